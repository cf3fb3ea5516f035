"""The weighing as a measurement: bands of standing wheel loads and heights under seal friction.

A standing strut is held by its seals anywhere inside a band around its frictionless force:

    F_i = F_gas,i(x_i) + f_i,    -F_reb,i(p_i) <= f_i <= F_comp,i(p_i)

with the breakaway (static) levels of the strut file's friction law, F = K_brk (F0 + f_p p).
`static_friction_limits` gives them: `struts.friction.coulomb_level` times the breakaway ratio K_brk, the
zero-velocity limit of the Stribeck law of seed 001 eq. 2 / REFERENCE §7. For `model: lugre` it is the
static level F_s = K_brk F_C of the mean F0, as `StrutBase.friction_force` uses it. p_i is the gas
pressure at the strut's own deflection, so each band moves with the pose. Positive f resists
compression (the sign convention of docs/CONTRIBUTING.md).

Every friction vector inside the eight bands gives one standing pose: the 3 hull and n wheel
balances (`vehicle.physics.equilibrium.static_balance`) fix q = (z, theta, phi, w_i) for given
f. The measured quantities (wheel loads, hull heights) are therefore bounded by their extremes over
the box of friction *utilisations* u_i in [-1, 1] (f_i = u_i F_comp,i(p_i) for u_i >= 0, u_i F_reb,i(p_i)
for u_i < 0): this parametrisation makes the feasible set an exact box although the bands depend
on the pose.

Method (`band_extremes`), per output and direction:
  1. linearise at the frictionless equilibrium: dy/du = Y_u - Y_q R_q^-1 R_u (implicit function
     theorem), the linear programme over the box is solved in closed form by the vertex
     u_i = sign(dy/du_i) (the LP of a linear objective over a box needs no simplex);
  2. solve the full nonlinear equilibrium at that vertex (Newton, residual < 1e-10);
  3. recompute the gradient there and flip any u_i whose sign disagrees (a vertex-optimality / KKT
     check over the box); repeat until none flips (a nearly linear problem needs none or one).
Accuracy: the extremes are the exact nonlinear values at KKT vertices (Newton tolerance ~1e-6 N,
~1e-10 m); for the 8x8 they equal the extremes over all 2^8 vertices (tests/test_weighing.py), and
the linear predictions of step 1 differ from them by ~1 % of the band width (reported as
`linearisation_error`).

Assumptions (documented in docs/scenarios.md, "Weighing bands"): valves carry nothing at rest
(the bleed equalises the oil pressures); the tyres are elastic without hysteresis and the scale
measures the vertical wheel load; the two weighings (before and after the drive) carry independent
friction states, because the struts stroke tens of millimetres in between. The approach (slow roll
onto the scale, stop) leaves each strut anywhere in its band: that is the default. If the struts
cool while standing before the weighing (`temperatures_at_stop_K`), the gas force falls at a held
deflection by dF_i and the seal takes it up. The band of strut i narrows to
[-F_reb + dF_i, F_comp] (all of it at the compression edge once dF_i >= F_comp + F_reb); this bound
neglects the redistribution of dF through the statically indeterminate hull.
"""
from __future__ import annotations

import copy
import threading
from collections import OrderedDict
from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from hpsim.errors import UserInputError
from struts import friction as fr

from vehicle.physics import hull as hull_eq
from vehicle.physics.equilibrium import (NumericFunction, equilibrium_solver, lockstep_newton, mapped_function,
                                         shared_statics, static_balance, statics_inputs)
from vehicle.physics.model import VehicleModel
from vehicle.physics.params import GRAVITY
from vehicle.physics.tyre import tyre_force

RESIDUAL_TOL = 1e-10        # scaled residual (1e-4 N units) of the Newton solves: ~1e-6 N
MAX_NEWTON = 100
# weighings a WeighingSolver remembers: drives of one vehicle from one standing state (a study's cases that share
# its model, vehicle.engines.shared_builds) weigh the same vehicle before they start
REMEMBERED_WEIGHINGS = 4
MAX_VERTEX_CORRECTIONS = 8
EXHAUSTED = ("weighing band: the struts cannot carry the vehicle with the seal friction at its band edge (gas volume "
             "exhausted)")
NOT_CONVERGED = "weighing band: the static equilibrium with friction did not converge"
# an output that moves less than this per unit utilisation does not depend on that strut (N, m)
RESOLUTION = {"N": 1e-6, "m": 1e-11}


# --- the band of one strut ------------------------------------------------------------------------
def static_friction_limits(friction, p_Pa):
    """(F_rebound [N], F_compression [N]): breakaway levels of a standing seal at pressure p [Pa].

    The seal holds any force in [-F_rebound, +F_compression] (> 0 resists compression). Stribeck law
    (REFERENCE §7, seed 001 eq. 2): the zero-velocity limit K_brk F_C with F_C = F0 + f_p p
    (`struts.friction.coulomb_level`) per direction. LuGre: the static level F_s = K_brk F_C of the
    mean F0 (as `StrutBase.friction_force`), both directions. `friction` is a strut file's
    `friction` block (struts.params.Friction).
    """
    f = friction
    if f.model == "lugre":
        F0_comp = F0_reb = 0.5 * (f.F0_compression + f.F0_rebound)
    else:
        F0_comp, F0_reb = f.F0_compression, f.F0_rebound
    return (f.breakaway_ratio * fr.coulomb_level(p_Pa, F0_reb, f.pressure_coefficient),
            f.breakaway_ratio * fr.coulomb_level(p_Pa, F0_comp, f.pressure_coefficient))


def held_friction(u, F_rebound_N, F_compression_N):
    """Friction force [N] at utilisation u in [-1, 1]: u F_comp for u >= 0, u F_reb for u < 0."""
    return ca.if_else(u >= 0, u * F_compression_N, u * F_rebound_N) if isinstance(u, (ca.SX, ca.MX)) \
        else np.where(np.asarray(u) >= 0, u * F_compression_N, u * F_rebound_N)


# --- a statics problem with friction utilisations ---------------------------------------------------
@dataclass
class StaticsProblem:
    """Balances R(q, u, c) = 0 and outputs y(q, u, c) of a standing structure (c: numeric inputs).

    outputs: ordered names -> (start, stop) rows of y; units: name -> "N" or "m" (resolution);
    deflections(q, u, c) -> strut deflections [m], strokes [m] (for the end-stop warning).
    """

    residual: ca.Function
    jac_q: ca.Function
    outputs: ca.Function
    sens: ca.Function              # (q, u, c) -> (R_q, R_u, Y_q, Y_u)
    limits: ca.Function            # (q, u, c) -> (F_reb, F_comp, p_gas) per strut
    deflections: ca.Function
    strokes: np.ndarray
    groups: dict                   # name -> (start, stop)
    units: dict                    # name -> "N" | "m"
    n_q: int
    n_u: int
    numeric: dict = field(init=False, repr=False)     # the functions above on NumPy arrays (NumericFunction)
    numeric_maps: dict = field(init=False, repr=False)  # functions mapped over columns (`mapped_function`)

    def __post_init__(self):
        self.numeric = {name: NumericFunction(getattr(self, name))
                        for name in ("residual", "jac_q", "outputs", "sens", "limits", "deflections")}
        self.numeric_maps = {}

    def values(self, name: str, q, u, c) -> tuple:
        """The outputs of function `name` (a field above) at (q, u, c) as dense 2-D NumPy arrays."""
        return self.numeric[name](q, u, c)

    def vectors(self, name: str, q, u, c) -> tuple:
        """The outputs of function `name` at (q, u, c), each raveled to a vector."""
        return self.numeric[name].vectors(q, u, c)

    @classmethod
    def build(cls, q, u, c, residual, groups: dict, units: dict, F_reb, F_comp, p_gas, deflections, strokes):
        res = ca.vertcat(*residual)
        y = ca.vertcat(*[ca.vertcat(*groups[k]) for k in groups])
        spans, k0 = {}, 0
        for k, v in groups.items():
            spans[k] = (k0, k0 + len(v))
            k0 += len(v)
        args = [q, u, c]
        return cls(residual=ca.Function("R", args, [res]),
                   jac_q=ca.Function("R_q", args, [ca.jacobian(res, q)]),
                   outputs=ca.Function("y", args, [y]),
                   sens=ca.Function("sens", args, [ca.jacobian(res, q), ca.jacobian(res, u), ca.jacobian(y, q),
                                                   ca.jacobian(y, u)]),
                   limits=ca.Function("lim", args, [ca.vertcat(*F_reb), ca.vertcat(*F_comp), ca.vertcat(*p_gas)]),
                   deflections=ca.Function("xs", args, [ca.vertcat(*deflections)]),
                   strokes=np.asarray(strokes, float), groups=spans, units=dict(units),
                   n_q=q.numel(), n_u=u.numel())

    # --- numerics --------------------------------------------------------------------------------
    def solve(self, u, c, q0) -> np.ndarray:
        """q with R(q, u, c) = 0 by damped Newton from q0."""
        q = np.asarray(q0, float).copy()
        for _ in range(MAX_NEWTON):
            r, = self.vectors("residual", q, u, c)
            if not np.all(np.isfinite(r)):
                raise UserInputError(EXHAUSTED)
            if np.max(np.abs(r)) < RESIDUAL_TOL:
                return q
            dq = np.linalg.solve(self.values("jac_q", q, u, c)[0], -r)
            q = q + min(1.0, 0.02 / max(np.max(np.abs(dq)), 1e-30)) * dq
        raise UserInputError(NOT_CONVERGED)

    def solve_many(self, U, c, q0) -> np.ndarray:
        """Row k: q with R(q, U[k], c) = 0 by `solve`'s damped Newton from q0. The rows iterate together (one mapped
        evaluation per step, `lockstep_newton`) and each stops where it would alone: row k is `solve(U[k], c, q0)`
        bit for bit."""
        U = np.atleast_2d(np.asarray(U, float))
        C = np.repeat(np.asarray(c, float)[:, None], len(U), axis=1)
        Q = np.tile(np.asarray(q0, float), (len(U), 1))

        def residual(rows):
            return mapped_function(self.numeric_maps, self.residual, rows.size)(Q[rows].T, U[rows].T, C[:, rows])[0].T

        def jacobian(rows):
            J = mapped_function(self.numeric_maps, self.jac_q, rows.size)(Q[rows].T, U[rows].T, C[:, rows])[0]
            return J.reshape(self.n_q, rows.size, self.n_q).transpose(1, 0, 2)

        return lockstep_newton(residual, jacobian, Q, RESIDUAL_TOL, MAX_NEWTON, EXHAUSTED, NOT_CONVERGED)

    def gradient(self, q, u, c) -> np.ndarray:
        """dy/du [units per utilisation] along the equilibrium manifold (implicit function theorem)."""
        R_q, R_u, Y_q, Y_u = self.values("sens", q, u, c)
        return Y_u - Y_q @ np.linalg.solve(R_q, R_u)

    def resolution(self) -> np.ndarray:
        out = np.empty(sum(b - a for a, b in self.groups.values()))
        for k, (a, b) in self.groups.items():
            out[a:b] = RESOLUTION[self.units[k]]
        return out


@dataclass
class Extremes:
    """Per output row: frictionless value, low and high bound, the utilisation vectors that reach them."""

    nominal: np.ndarray
    low: np.ndarray
    high: np.ndarray
    u_low: np.ndarray
    u_high: np.ndarray
    linear_low: np.ndarray
    linear_high: np.ndarray
    std_uniform: np.ndarray          # linear: friction forces independent, uniform over their bands
    corrections: int = 0
    warnings: list = field(default_factory=list)


def band_extremes(problem: StaticsProblem, c, q0, u_lower=None, u_upper=None) -> Extremes:
    """Low and high value of every output over the box u in [u_lower, u_upper] (default [-1, 1]).

    q0: the frictionless solution (u = 0), the starting point of every Newton solve. See the module
    docstring for the method and its accuracy.
    """
    n_u = problem.n_u
    lo = -np.ones(n_u) if u_lower is None else np.asarray(u_lower, float)
    hi = np.ones(n_u) if u_upper is None else np.asarray(u_upper, float)
    if np.any(lo > hi) or np.any(lo < -1) or np.any(hi > 1):
        raise ValueError("utilisation bounds must satisfy -1 <= lower <= upper <= 1")
    c = np.asarray(c, float)
    u0 = np.zeros(n_u)
    q0 = problem.solve(u0, c, q0)
    y0, = problem.vectors("outputs", q0, u0, c)
    res = problem.resolution()
    # one-sided gradients at u = 0 (the band levels differ in compression and rebound)
    G_plus = problem.gradient(q0, u0, c)
    G_minus = problem.gradient(q0, -1e-300 * np.ones(n_u), c)
    n_y = y0.size
    std = _uniform_std(problem, q0, u0, c, G_plus, lo, hi)
    out = Extremes(nominal=y0, low=np.empty(n_y), high=np.empty(n_y), u_low=np.empty((n_y, n_u)),
                   u_high=np.empty((n_y, n_u)), linear_low=np.empty(n_y), linear_high=np.empty(n_y),
                   std_uniform=std)
    cache: dict[bytes, list] = {}        # vertex -> [q, outputs, gradient (once asked for)]

    def evaluate(u):
        key = u.tobytes()
        if key not in cache:
            q = problem.solve(u, c, q0)
            cache[key] = [q, problem.vectors("outputs", q, u, c)[0], None]
        return cache[key]

    cache.update(_first_vertices(problem, c, q0, G_plus, G_minus, lo, hi, res))
    for j in range(n_y):
        for sense in (+1.0, -1.0):
            # 1. the vertex of the linear programme
            u = _linear_vertex(G_plus[j], G_minus[j], sense, lo, hi, res[j])
            linear = y0[j] + np.sum(np.where(u >= 0, G_plus[j], G_minus[j]) * u)
            # 2.-3. nonlinear solve, vertex correction until the gradient agrees with the vertex
            u, q, y = _settled_vertex(problem, c, j, sense, u, lo, hi, res[j], evaluate, out)
            if sense > 0:
                out.high[j], out.u_high[j], out.linear_high[j] = y[j], u, linear
            else:
                out.low[j], out.u_low[j], out.linear_low[j] = y[j], u, linear
            xs, = problem.vectors("deflections", q, u, c)
            if np.any(xs < 0) or np.any(xs > problem.strokes):
                out.warnings.append(f"output {j}: a strut is on its end stop at the band edge")
    if np.all(lo <= 0) and np.all(hi >= 0):
        # the frictionless value is inside by construction; guard against round-off
        out.low = np.minimum(out.low, y0)
        out.high = np.maximum(out.high, y0)
    return out


def _first_vertices(problem: StaticsProblem, c, q0, G_plus, G_minus, lo, hi, res) -> dict:
    """{vertex bytes: [q, outputs, None]} at the first vertex (step 1) of every output's extremes, all solved together
    (`solve_many`: each as its own solve)."""
    firsts = {}
    for j in range(len(G_plus)):
        for sense in (+1.0, -1.0):
            u = _linear_vertex(G_plus[j], G_minus[j], sense, lo, hi, res[j])
            firsts.setdefault(u.tobytes(), u)
    U = np.array(list(firsts.values()))
    return {u.tobytes(): [q.copy(), problem.vectors("outputs", q, u, c)[0], None]
            for u, q in zip(U, problem.solve_many(U, c, q0))}


def _linear_vertex(G_plus_j, G_minus_j, sense: float, lo, hi, res_j: float) -> np.ndarray:
    """Step 1 of `band_extremes` for one output: the vertex of the box where the linearised output is extreme in
    direction `sense` (utilisations it does not depend on, at resolution res_j, left at 0)."""
    g = sense * np.where(G_plus_j >= 0, G_plus_j, G_minus_j)
    u = np.where(g > 0, hi, lo)
    u = np.where(np.abs(g) * np.maximum(np.abs(lo), np.abs(hi)) <= res_j, 0.0, u)
    return np.clip(u, lo, hi)


def _uniform_std(problem: StaticsProblem, q0, u0, c, G_plus, lo, hi) -> np.ndarray:
    """Per output, the linear standard deviation with every friction force uniform over [lo F_reb, hi F_comp]: in
    utilisation units of the + side its variance is (width)^2 / 12 (the rebound side scaled by F_reb/F_comp)."""
    F_reb, F_comp, _ = problem.vectors("limits", q0, u0, c)
    ratio = np.where(F_comp > 0, F_reb / np.maximum(F_comp, 1e-300), 1.0)
    width = hi * (hi >= 0) + hi * ratio * (hi < 0) - (lo * (lo >= 0) + lo * ratio * (lo < 0))
    return np.sqrt(np.sum(G_plus ** 2 * width ** 2 / 12.0, axis=1))


def _settled_vertex(problem: StaticsProblem, c, j: int, sense: float, u, lo, hi, res_j: float, evaluate,
                    out: Extremes) -> tuple:
    """(u, q, outputs) at the vertex of output j's extreme in direction `sense`, from the vertex `u`: solved,
    moved to the vertex the gradient there points to, until they agree (corrections and a failure counted in
    `out`)."""
    for _ in range(MAX_VERTEX_CORRECTIONS):
        found = evaluate(u)
        q, y = found[0], found[1]
        if found[2] is None:
            found[2] = problem.gradient(q, u, c)
        gj = sense * found[2][j]
        want = np.where(np.abs(gj) * np.maximum(np.abs(lo), np.abs(hi)) <= res_j, u, np.where(gj > 0, hi, lo))
        if np.array_equal(want, u):
            break
        u = want
        out.corrections += 1
    else:
        out.warnings.append(f"output {j}: vertex not settled after {MAX_VERTEX_CORRECTIONS} corrections")
    return u, q, y


# --- the vehicle ----------------------------------------------------------------------------------
def _weighing_graph(model) -> dict:
    """The statics of `model` (a VehicleModel or its symbolic twin) with seal friction utilisations u: the
    arguments of `StaticsProblem.build`."""
    n, P = model.n, model.params
    q = ca.SX.sym("q", 3 + n)
    u = ca.SX.sym("u", n)
    c = ca.SX.sym("c", 3 * n)            # T [K], m [kg], dV [m^3] per strut
    T, m, dV = c[:n], c[n:2 * n], c[2 * n:]
    F_reb, F_comp = [None] * n, [None] * n

    def offset(i, p_gas):
        F_reb[i], F_comp[i] = static_friction_limits(model.struts[i].p.friction, p_gas)
        return held_friction(u[i], F_reb[i], F_comp[i])

    b = static_balance(model, q, T, m, dV, strut_force_offset=offset)
    axle_loads = [0.5 * (b["wheel_loads"][2 * k] + b["wheel_loads"][2 * k + 1]) for k in range(P.n_axles)]
    groups = {"wheel_loads": b["wheel_loads"], "axle_loads": axle_loads,
              "station_heights": b["station_heights"], "axle_heights": b["axle_heights"]}
    units = {"wheel_loads": "N", "axle_loads": "N", "station_heights": "m", "axle_heights": "m"}
    return {"q": q, "u": u, "c": c, "residual": b["residual"], "groups": groups, "units": units, "F_reb": F_reb,
            "F_comp": F_comp, "p_gas": b["gas_pressures"], "deflections": b["deflections"],
            "strokes": [s.p.geometry.stroke for s in model.struts]}


def _weighing_expressions(model) -> list:
    """Every expression and number of `_weighing_graph` (what the weighing's functions read)."""
    g = _weighing_graph(model)
    return [*g["residual"], *(e for v in g["groups"].values() for e in v), *g["F_reb"], *g["F_comp"], *g["p_gas"],
            *g["deflections"], *(ca.SX(v) for v in g["strokes"])]


def weighing_problem(model: VehicleModel) -> StaticsProblem:
    g = _weighing_graph(model)
    return StaticsProblem.build(g["q"], g["u"], g["c"], g["residual"], g["groups"], g["units"], g["F_reb"],
                                g["F_comp"], g["p_gas"], g["deflections"], g["strokes"])


class WeighingSolver:
    """Bands of the standing 8x8 (or any VehicleModel) for given temperatures, gas masses and oil volumes."""

    def __init__(self, model: VehicleModel):
        self.model = model
        self.frictionless = equilibrium_solver(model)
        self.problem = shared_statics(model, "weighing", _weighing_expressions, weighing_problem)
        self.remembered: OrderedDict = OrderedDict()
        self.remembered_lock = threading.Lock()

    def bands(self, temperatures_K, gas_masses_kg, oil_volumes_m3=None, temperatures_at_stop_K=None) -> dict:
        """`weighing_bands` of this model; a weighing with the same inputs as a recent one returns a copy of its
        result (the computation is deterministic: the same numbers bit for bit)."""
        n = self.model.n
        T, m, dV = statics_inputs(n, temperatures_K, gas_masses_kg, oil_volumes_m3)
        T_stop = None if temperatures_at_stop_K is None else \
            np.broadcast_to(np.asarray(temperatures_at_stop_K, float), (n,)).copy()
        key = (T.tobytes(), m.tobytes(), dV.tobytes(), None if T_stop is None else T_stop.tobytes())
        with self.remembered_lock:
            found = self.remembered.get(key)
            if found is not None:
                self.remembered.move_to_end(key)
        if found is None:
            found = self._bands(T, m, dV, T_stop)
            with self.remembered_lock:          # a shared model may weigh on several threads of a worker
                self.remembered[key] = found
                while len(self.remembered) > REMEMBERED_WEIGHINGS:
                    self.remembered.popitem(last=False)
        return copy.deepcopy(found)

    def _bands(self, T, m, dV, temperatures_at_stop_K) -> dict:
        model = self.model
        n = model.n
        eq = self.frictionless.solve(T, m, dV)
        q0 = np.concatenate([[eq.heave_m, eq.pitch_rad, eq.roll_rad], eq.wheel_displacement_m])
        c = np.concatenate([T, m, dV])
        u0 = np.zeros(n)
        F_reb, F_comp, p_gas = self.problem.vectors("limits", q0, u0, c)
        lower = None
        settle = np.zeros(n)
        if temperatures_at_stop_K is not None:
            T_stop = np.broadcast_to(np.asarray(temperatures_at_stop_K, float), (n,))
            x0 = eq.strut_deflections_m
            settle = np.array([float(model.struts[i].static_gas_force(x0[i], T_stop[i], m[i], dV[i]))
                               - float(model.struts[i].static_gas_force(x0[i], T[i], m[i], dV[i])) for i in range(n)])
            # cooling at a held deflection: the gas force falls by settle_i, the seal takes it up
            settle = np.maximum(settle, 0.0)
            f_low = settle - F_reb                                  # the lowest friction left after cooling
            lower = np.where(f_low < 0, f_low / np.maximum(F_reb, 1e-300), np.minimum(f_low / np.maximum(F_comp, 1e-300), 1.0))
        ex = band_extremes(self.problem, c, q0, u_lower=lower)
        out = {"method": "vertex of the linearised band problem, corrected by the nonlinear equilibrium "
                         "(vehicle.physics.weighing)",
               "stations": list(model.station_names),
               "static_friction_N": {"rebound": F_reb, "compression": F_comp},
               "gas_pressure_Pa": p_gas,
               "settling_force_N": settle,
               "corrections": ex.corrections, "warnings": ex.warnings}
        for name, (a, b) in self.problem.groups.items():
            out[name] = {"nominal": ex.nominal[a:b].copy(), "low": ex.low[a:b].copy(), "high": ex.high[a:b].copy(),
                         "std_uniform": ex.std_uniform[a:b].copy(),
                         "linearisation_error": np.maximum(np.abs(ex.linear_low[a:b] - ex.low[a:b]),
                                                           np.abs(ex.linear_high[a:b] - ex.high[a:b]))}
        # every strut at the compression edge of its band: the pose after the struts crept down
        # while cooling (the lower end of the heights)
        u_edge = np.ones(n)
        q_edge = self.problem.solve(u_edge, c, q0)
        y_edge, = self.problem.vectors("outputs", q_edge, u_edge, c)
        out["compression_edge"] = {name: y_edge[a:b].copy() for name, (a, b) in self.problem.groups.items()}
        return out


def weighing_bands(model: VehicleModel, temperatures_K, gas_masses_kg, oil_volumes_m3=None, *,
                   temperatures_at_stop_K=None, solver: WeighingSolver | None = None) -> dict:
    """Bands of the standing vehicle's wheel loads and hull heights under seal friction.

    Returns a dict (NumPy arrays, SI):
      wheel_loads, station_heights  per station; axle_loads (mean of left and right), axle_heights
          (hull at the axle's centre line, vs the charged pose): each {nominal, low, high, std_uniform,
          linearisation_error}; nominal is the frictionless equilibrium (`EquilibriumSolver`),
          [low, high] the worst case over all friction states, std_uniform the (linearised) standard
          deviation if the seal forces were independent and uniform over their bands
      static_friction_N {rebound, compression}, gas_pressure_Pa: at the frictionless pose
      compression_edge: the outputs with every seal at its compression edge
      settling_force_N, corrections, warnings, method, stations
    temperatures_at_stop_K (optional): strut temperatures when the vehicle stopped; the struts then
    cooled at rest to temperatures_K before the weighing (see the module docstring).
    """
    return (solver or weighing_solver(model)).bands(temperatures_K, gas_masses_kg, oil_volumes_m3,
                                                    temperatures_at_stop_K)


def weighing_solver(model: VehicleModel) -> WeighingSolver:
    """The model's WeighingSolver, built once per model object (a run weighs before and after its drive)."""
    solver = model.__dict__.get("_weighing_solver")
    if solver is None:
        solver = model.__dict__["_weighing_solver"] = WeighingSolver(model)
    return solver


# --- what the report prints -----------------------------------------------------------------------
BAND_DATASETS = {"wheel_loads": "wheel_loads", "axle_loads": "axle_loads", "station_heights": "station_height_change",
                 "axle_heights": "axle_height_change"}


# the edges written to files; "std_uniform" is also in every band (add it here and to the results
# variables table, vehicle.physics.outputs, to store it: difference_bands then adds dN_std_pct, dh_std_mm)
BAND_EDGES = ("nominal", "low", "high")


def band_datasets(bands: dict) -> dict:
    """Flat {dataset name: array} for an HDF5 group such as /equilibrium/before_band (SI units in names)."""
    out = {}
    for key, stem in BAND_DATASETS.items():
        unit = "N" if "load" in key else "m"
        for edge in BAND_EDGES:
            out[f"{stem}_{edge}_{unit}"] = np.asarray(bands[key][edge], float)
    out["static_friction_rebound_N"] = np.asarray(bands["static_friction_N"]["rebound"], float)
    out["static_friction_compression_N"] = np.asarray(bands["static_friction_N"]["compression"], float)
    return out


def difference_bands(before: dict, after: dict) -> dict:
    """Per axle, bands of the change after - before of two independent weighings.

    Both weighings carry their own friction state, so the difference can range from the lowest after
    value minus the highest before value to the highest after minus the lowest before:
        dN in [N_after_low - N_before_high, N_after_high - N_before_low]
    (NOT after_low - before_low). Same for dh. `before`/`after`: `band_datasets` dicts (or HDF5 groups
    with those names). dN_band_pct is relative to the frictionless before-load N_before_nominal, as
    dN_pct of the report; dh_band_mm in mm.
    """
    Nb_lo, Nb_hi, Nb0 = (np.asarray(before[f"axle_loads_{e}_N"], float) for e in ("low", "high", "nominal"))
    Na_lo, Na_hi = (np.asarray(after[f"axle_loads_{e}_N"], float) for e in ("low", "high"))
    hb_lo, hb_hi = (np.asarray(before[f"axle_height_change_{e}_m"], float) for e in ("low", "high"))
    ha_lo, ha_hi = (np.asarray(after[f"axle_height_change_{e}_m"], float) for e in ("low", "high"))
    dN_pct = 100.0 * np.stack([Na_lo - Nb_hi, Na_hi - Nb_lo], axis=1) / Nb0[:, None]
    dh_mm = 1e3 * np.stack([ha_lo - hb_hi, ha_hi - hb_lo], axis=1)
    out = {"dN_band_pct": dN_pct, "dh_band_mm": dh_mm}
    if "axle_loads_std_uniform_N" in before and "axle_loads_std_uniform_N" in after:
        # independent weighings: the variances add
        sN = np.hypot(np.asarray(before["axle_loads_std_uniform_N"], float), np.asarray(after["axle_loads_std_uniform_N"], float))
        sh = np.hypot(np.asarray(before["axle_height_change_std_uniform_m"], float),
                      np.asarray(after["axle_height_change_std_uniform_m"], float))
        out["dN_std_pct"] = 100.0 * sN / Nb0
        out["dh_std_mm"] = 1e3 * sh
    return out


# --- one station: the hand-checkable case --------------------------------------------------------
def station_problem(strut, sprung_mass_kg: float, unsprung_mass_kg: float, motion_ratio: float,
                    tyre_stiffness_N_per_m: float, x_reference_m: float):
    """A single station (quarter car) standing: q = (hull z, wheel w) vs a reference pose where the
    strut is at x_reference_m and the tyre carries the whole weight. Statically determinate: the
    wheel load is (M + m_u) g whatever the friction; the hull height moves by the held friction.
    Returns a StaticsProblem with c = (T [K], m_gas [kg], dV [m^3]); outputs wheel_loads, hull_height.
    """
    q = ca.SX.sym("q", 2)
    u = ca.SX.sym("u", 1)
    c = ca.SX.sym("c", 3)
    W = (sprung_mass_kg + unsprung_mass_kg) * GRAVITY
    x = hull_eq.strut_deflection(x_reference_m, motion_ratio, q[1], q[0])
    F_gas = strut.static_gas_force(x, c[0], c[1], c[2])
    p_gas = F_gas / strut.p.geometry.gas_area
    F_reb, F_comp = static_friction_limits(strut.p.friction, p_gas)
    Fs = F_gas + strut.end_stop_force(x, 0.0)[0] + held_friction(u[0], F_reb, F_comp)
    Ft = tyre_force(W / tyre_stiffness_N_per_m - q[1], 0.0, tyre_stiffness_N_per_m, 0.0, 1e-6)
    residual = [(motion_ratio * Fs - sprung_mass_kg * GRAVITY) / 1e4,
                (Ft - motion_ratio * Fs - unsprung_mass_kg * GRAVITY) / 1e4]
    return StaticsProblem.build(q, u, c, residual, {"wheel_loads": [Ft], "hull_height": [q[0]]},
                                {"wheel_loads": "N", "hull_height": "m"}, [F_reb], [F_comp], [p_gas], [x],
                                [strut.p.geometry.stroke])
