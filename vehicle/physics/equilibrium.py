"""Static equilibrium of the hull on its struts and tyres, and charging of the gas springs.

Standing still, each strut carries its gas force at the body temperature: the gas has had time
to reach it. The law is isothermal at the oil temperature (the heat network's oil node, which the gas
follows at rest), or the seed-000 polytropic law if the strut file says so. The valves carry nothing and seal friction is taken at the middle of its band (zero). The hull
(3 DOF) on 8 supports is statically indeterminate: the strut and tyre compliances decide the
load split, so the unknowns are heave, pitch, roll and the 8 wheel displacements, solved by
Newton on the 11 force/moment balances.

Charging (seed 000 §3, REFERENCE §3): the gas mass of each strut is set so that the requested
wheel loads are carried at the requested heights at the charging temperature. By construction
the charged pose is the reference of all displacements (z = theta = phi = 0, w = 0).
"""
from __future__ import annotations

import threading
from collections import OrderedDict
from dataclasses import dataclass
from types import SimpleNamespace

import casadi as ca
import numpy as np

from hpsim.errors import UserInputError
from struts import gas as gaslaw

from vehicle.physics import hull as hull_eq
from vehicle.physics.model import VehicleModel
from vehicle.physics.params import GRAVITY
from vehicle.physics.tyre import tyre_force


@dataclass
class Equilibrium:
    heave_m: float
    pitch_rad: float
    roll_rad: float
    wheel_displacement_m: np.ndarray
    wheel_loads_N: np.ndarray
    strut_forces_N: np.ndarray
    strut_deflections_m: np.ndarray
    gas_pressures_Pa: np.ndarray
    axle_height_change_m: np.ndarray
    temperatures_K: np.ndarray

    def as_dict(self) -> dict:
        return {k: (v.tolist() if isinstance(v, np.ndarray) else v) for k, v in self.__dict__.items()}


class NumericFunction:
    """A CasADi Function evaluated on NumPy arrays through evaluation buffers of its own, one set per thread.

    Called with NumPy arguments a Function converts every argument and result to a DM: for the small statics
    functions here that costs ~10x their evaluation. The buffers hand the arrays' memory to the same evaluation
    (the same instructions on the same numbers: the results are the same bit for bit). Inputs must be dense;
    returns a tuple of dense 2-D arrays (as `np.asarray` of the DM results).
    """

    def __init__(self, function: ca.Function):
        self.function = function
        for k in range(function.n_in()):
            if not function.sparsity_in(k).is_dense():
                raise ValueError(f"{function.name()}: input {k} is not dense")
        # where each result's nonzeros (column-major) go in the dense row-major array; None: dense already
        self.out_shapes, self.out_places = [], []
        for k in range(function.n_out()):
            sp = function.sparsity_out(k)
            rows, cols = sp.get_triplet()
            self.out_shapes.append((sp.size1(), sp.size2()))
            self.out_places.append(None if sp.is_dense() else
                                   np.asarray(rows, np.intp) * sp.size2() + np.asarray(cols, np.intp))
        self.local = threading.local()

    def __reduce__(self):
        return (NumericFunction, (self.function,))

    def _buffers(self) -> tuple:
        held = getattr(self.local, "held", None)
        if held is None:
            f = self.function
            buffer, evaluate = f.buffer()
            args = [np.zeros(f.nnz_in(k)) for k in range(f.n_in())]
            results = [np.zeros(f.nnz_out(k)) for k in range(f.n_out())]
            for k, a in enumerate(args):
                buffer.set_arg(k, memoryview(a))
            for k, r in enumerate(results):
                buffer.set_res(k, memoryview(r))
            held = self.local.held = (buffer, evaluate, args, results)   # the buffer reads and writes these arrays
        return held

    def __call__(self, *args) -> tuple:
        _, evaluate, inputs, results = self._buffers()
        if len(args) != len(inputs):
            raise TypeError(f"{self.function.name()} takes {len(inputs)} arguments, got {len(args)}")
        for held, given in zip(inputs, args):
            given = np.asarray(given, float)
            held[:] = given.ravel(order="F") if given.ndim > 1 else given
        evaluate()
        out = []
        for (n1, n2), places, r in zip(self.out_shapes, self.out_places, results):
            if places is None:
                dense = r.reshape(n2, n1).T.copy() if n2 > 1 else r.reshape(n1, 1).copy()
            else:
                dense = np.zeros(n1 * n2)
                dense[places] = r
                dense = dense.reshape(n1, n2)
            out.append(dense)
        return tuple(out)

    def vectors(self, *args) -> tuple:
        """The results at args raveled (for functions whose outputs are column vectors)."""
        return tuple(v.ravel() for v in self(*args))


# statics builds a process keeps (each a few functions of the static balance): the vehicles of a study's designs
# that share their statics and a few that do not
MAX_SHARED_STATICS = 8
_shared_statics: OrderedDict = OrderedDict()
_statics_reads: dict = {}          # (model structure, kind) -> indices of theta the kind's statics read (None: unknown)
_first_statics: dict = {}          # (model structure, kind) -> (theta, kinematics, built) of its first model
_shared_statics_lock = threading.Lock()


def lockstep_newton(residual, jacobian, Q: np.ndarray, tol: float, steps: int, exhausted: str, failed: str):
    """Damped Newton on every row of Q at once, in place: residual(rows) -> R (len(rows), n) and jacobian(rows) ->
    J (len(rows), n, n) at Q[rows]. Each row stops when its own largest residual is below tol and moves at most
    0.02 per step (as `EquilibriumSolver.solve`): a row ends where its Newton alone ends, bit for bit. Raises
    UserInputError(exhausted) at a non-finite residual, UserInputError(failed) after `steps` steps."""
    active = np.arange(len(Q))
    for _ in range(steps):
        R = residual(active)
        if not np.all(np.isfinite(R)):
            raise UserInputError(exhausted)
        going = np.max(np.abs(R), axis=1) >= tol
        active, R = active[going], R[going]
        if active.size == 0:
            return Q
        dQ = np.linalg.solve(jacobian(active), -R[:, :, None])[:, :, 0]
        scale = np.minimum(1.0, 0.02 / np.maximum(np.max(np.abs(dQ), axis=1), 1e-30))
        Q[active] = Q[active] + scale[:, None] * dQ
    raise UserInputError(failed)


def mapped_function(maps: dict, function: ca.Function, columns: int) -> NumericFunction:
    """`function` evaluated on `columns` columns at once (each column the instructions of one call), kept in `maps`."""
    found = maps.get((function.name(), columns))
    if found is None:
        found = maps[(function.name(), columns)] = NumericFunction(function.map(columns, "serial"))
    return found


def _symbolic_view(model: VehicleModel) -> SimpleNamespace:
    """The model's symbolic twin (`VehicleModel.sym`: its parameters as the symbols theta) where `static_balance`
    reads a model."""
    return SimpleNamespace(**vars(model.sym), n=model.n)


def _theta_read(model: VehicleModel, kind: str, graph) -> np.ndarray | None:
    """Indices of the model's parameter vector theta that `graph(view)` (SX expressions of a statics problem
    built on a model or its symbolic twin) depends on, found once per model structure; None where the graph cannot
    be built on the symbolic twin (the statics are then built per model)."""
    key = (model.structure, kind)
    with _shared_statics_lock:
        if key in _statics_reads:
            return _statics_reads[key]
    try:
        expressions = ca.vertcat(*graph(_symbolic_view(model)))
        theta = model.parameters.symbols
        others = [v for v in ca.symvar(expressions) if not ca.depends_on(theta, v)]
        reads = ca.Function("reads", [theta, *others], [expressions]).which_depends("i0", ["o0"], 1, False)
        found = np.flatnonzero(np.asarray(reads, bool))
    except (RuntimeError, TypeError, ValueError, AttributeError, NotImplementedError):
        found = None
    with _shared_statics_lock:
        _statics_reads[key] = found
    return found


def _statics_key(kind: str, structure: str, reads: np.ndarray, theta: np.ndarray, kinematics: tuple) -> tuple:
    return (kind, structure, reads.tobytes(), theta[reads].tobytes(), *kinematics)


def _remember_statics(key: tuple, built) -> None:
    with _shared_statics_lock:
        _shared_statics[key] = built
        while len(_shared_statics) > MAX_SHARED_STATICS:
            _shared_statics.popitem(last=False)


def shared_statics(model: VehicleModel, kind: str, graph, build):
    """`build(model)`, or what it returned for an earlier model of this process whose statics read the same numbers.

    graph(view) -> list of SX expressions: everything `build` evaluates, built on `view` (the model or its symbolic
    twin). The key is the model's structure (`VehicleModel.structure`: strut types, gas laws, mechanisms, every
    zero) with the values of the parameters the graph depends on, and the numbers of the model's kinematics: all
    that a numeric build reads, so the shared functions are the ones the model's own build would make, instruction
    for instruction. A design study's vehicles that differ in what the standing vehicle does not feel (a valve's
    bleed, the fill pressure, which only sets the gas masses fed to the functions) build their statics once. The
    first model of a structure builds its own and is only remembered: a single drive builds no symbolic graph.
    """
    if not isinstance(model, VehicleModel):
        return build(model)
    group = (model.structure, kind)
    theta = model.parameters.numeric()
    kinematics = tuple(np.asarray(v, float).tobytes() for v in (
        model.a, model.y, model.r, model.m_u, model.tyre_static_deflection, model.link_drive, model.link_brake,
        [model.a_cg, model.y_cg, model.M, model.x_charged, model.pitch_per_acceleration]))
    with _shared_statics_lock:
        first = _first_statics.get(group) if group not in _statics_reads else None
        if first is None and group not in _statics_reads:
            _first_statics[group] = None          # claimed: this model builds the structure's first statics
    if first is None and group not in _statics_reads:
        built = build(model)
        with _shared_statics_lock:
            _first_statics[group] = (theta, kinematics, built)
        return built
    reads = _theta_read(model, kind, graph)
    if reads is None:
        return build(model)
    with _shared_statics_lock:
        first = _first_statics.pop(group, None)
    if first is not None:
        _remember_statics(_statics_key(kind, group[0], reads, first[0], first[1]), first[2])
    key = _statics_key(kind, group[0], reads, theta, kinematics)
    with _shared_statics_lock:
        found = _shared_statics.get(key)
        if found is not None:
            _shared_statics.move_to_end(key)
            return found
    found = build(model)
    _remember_statics(key, found)
    return found


def charge_gas_masses(model: VehicleModel) -> np.ndarray:
    """Gas mass [kg] per strut by the vehicle's `charging.method` (REFERENCE §1, §3).

    load_and_height: the charging loads are carried at the charging deflection at the charging
        temperature with the standing gas law of the strut file (isothermal for `gas.process:
        energy`, seed 000 eq. 5 for `polytropic`): exact loads and heights, standing.
    gas_pressure: each strut's `charge.pressure` at full extension at its `charge.temperature`
        (`strut.charge_gas_mass`); strut overrides of charge.pressure take effect.
    polytropic_convention: the charging loads at the charging deflection and temperature by seed
        000's polytropic law from full extension (eq. 5, the strut file's exponent), the convention
        that gives 41.8 kN at 112 mm for 4.8 MPa at 20 degC.
    `charging.fill_pressure_offset` then adds to the fill pressure at full extension (at the
    temperature that defines the method's charge) for sensitivity studies.
    """
    P = model.params
    method = P.charging.method
    if method == "gas_pressure":
        masses = np.array([float(s.charge_gas_mass) for s in model.struts])
        T_fill = np.array([float(s.p.charge.temperature) for s in model.struts])
    else:
        masses = _masses_for_charging_loads(model, "polytropic" if method == "polytropic_convention" else None)
        T_fill = np.full(model.n, P.charging.temperature)
    dp_fill = P.charging.fill_pressure_offset
    if dp_fill != 0.0:
        for i in range(model.n):
            strut = model.struts[i]
            V_ext = float(strut.extended_gas_volume(T_fill[i]))
            p_fill = float(gaslaw.pressure(T_fill[i], V_ext / masses[i], strut.gas, strut.p.gas.eos))
            if p_fill + dp_fill <= 0.1e6:
                raise UserInputError(f"{P.name}: charging.fill_pressure_offset {dp_fill / 1e6:.3g} MPa leaves "
                                     f"{(p_fill + dp_fill) / 1e6:.3g} MPa at {model.station_names[i]} (> 0.1 MPa needed)")
            masses[i] = strut.gas_mass_for(p_fill + dp_fill, T_fill[i])
        return masses
    if method == "gas_pressure":
        return masses
    # the hull must be in equilibrium at the charged pose with these loads
    Fs = (model.charged_wheel_loads - model.m_u * GRAVITY) / model.r
    Qz, Qt, Qp = hull_eq.generalised_forces(model.r * Fs, model.a, model.y, model.a_cg, model.y_cg)
    W = model.M * GRAVITY
    if abs(Qz - W) > 5e-3 * W or abs(Qt) > 5e-3 * W * 1.0 or abs(Qp) > 5e-3 * W * 1.0:
        raise UserInputError(
            f"{P.name}: charging.wheel_loads are not in equilibrium with the hull (sprung weight {W:.6g} N, "
            f"loads carry {Qz:.6g} N, pitch moment {Qt:.4g} N m, roll moment {Qp:.4g} N m); "
            "omit hull.mass / hull.cg_x to derive them from the loads")
    return masses


def _masses_for_charging_loads(model: VehicleModel, process: str | None) -> np.ndarray:
    """Gas mass [kg] per strut that carries the charging load at the charging deflection and temperature.

    process: None = the strut file's standing law (`static_gas_force`), "polytropic" = seed 000 eq. 5.
    """
    P = model.params
    T = P.charging.temperature
    masses = np.zeros(model.n)
    for i in range(model.n):
        strut = model.struts[i]
        name = model.station_names[i]
        stroke = strut.p.geometry.stroke
        if not 0.0 < model.x_charged < stroke:
            raise UserInputError(
                f"{P.name}: charging.strut_deflection = {model.x_charged * 1e3:.4g} mm is outside the stroke "
                f"(0, {stroke * 1e3:.4g}) mm of strut {strut.p.name} at {name}")
        F_needed = (model.charged_wheel_loads[i] - model.m_u[i] * GRAVITY) / model.r[i]
        if F_needed <= 0:
            raise UserInputError(
                f"{P.name}: charging.wheel_loads: {model.charged_wheel_loads[i]:.6g} N at {name} does not even carry "
                f"the unsprung weight {model.m_u[i] * GRAVITY:.6g} N")
        try:
            masses[i] = strut.gas_mass_carrying(F_needed, model.x_charged, T, process=process)
        except UserInputError:
            raise UserInputError(
                f"{P.name}: strut {strut.p.name} at {name} cannot carry {F_needed / 1e3:.4g} kN at "
                f"{model.x_charged * 1e3:.4g} mm deflection (gas pressure would exceed the gas law's range)") from None
        p_gas = F_needed / strut.p.geometry.gas_area
        if p_gas > 60e6:
            raise UserInputError(
                f"{P.name}: strut {strut.p.name} at {name} would need {p_gas / 1e6:.4g} MPa to carry its load "
                "(allowed up to 60 MPa)")
    return masses


def static_balance(model: VehicleModel, q, T, m, dV, strut_force_offset=None, acceleration_m_s2=0.0) -> dict:
    """The 3 + n static balances of the hull on its stations and their by-products (symbolic or numeric).

    acceleration_m_s2: a steady longitudinal acceleration a_x (+ forward; braking < 0): the settled
    vehicle under the pitch moment and linkage forces of vehicle.physics.hull (as in the model's
    equations with dx/dt = 0); 0: standing.
    q = (z, theta, phi, w_1..w_n) [m, rad, rad, m]; T [K], m [kg], dV [m^3] per strut. Each strut
    carries its static gas force (`static_gas_force`) plus its end-stop force; valves carry nothing.
    strut_force_offset(i, p_gas_Pa) -> extra strut force [N] at station i (seal friction held at
    rest, vehicle.physics.weighing); None: frictionless. Residuals are scaled by 1e-4 (N -> ~1).
    Returns residual (list), wheel_loads, strut_forces, gas_forces, gas_pressures, deflections,
    station_heights [m, hull above each station vs the charged pose], axle_heights [m].
    """
    P = model.params
    n = model.n
    res, Fs_list, Fg_list, Ft_list, xs_list, p_list, zs_list = [], [], [], [], [], [], []
    V_link = hull_eq.linkage_forces(acceleration_m_s2, model.pitch_per_acceleration, model.link_drive,
                                    model.link_brake)
    for i in range(n):
        zs = hull_eq.station_displacement(q[0], q[1], q[2], model.a[i], model.y[i], model.a_cg, model.y_cg)
        xs = hull_eq.strut_deflection(model.x_charged, model.r[i], q[3 + i], zs)
        strut = model.struts[i]
        F_gas = strut.static_gas_force(xs, T[i], m[i], dV[i])
        p_gas = F_gas / strut.p.geometry.gas_area
        Fs = F_gas + strut.end_stop_force(xs, 0.0)[0]
        if strut_force_offset is not None:
            Fs = Fs + strut_force_offset(i, p_gas)
        tyre = model.tyre[i]
        Ft = tyre_force(model.tyre_static_deflection[i] - q[3 + i], 0.0, tyre.stiffness, tyre.damping,
                        tyre.lift_off_smoothing)
        res.append((Ft - model.r[i] * Fs - V_link[i] - model.m_u[i] * GRAVITY) / 1e4)
        Fs_list.append(Fs)
        Fg_list.append(F_gas)
        Ft_list.append(Ft)
        xs_list.append(xs)
        p_list.append(p_gas)
        zs_list.append(zs)
    Qz, Qt, Qp = hull_eq.generalised_forces([model.r[i] * Fs_list[i] + V_link[i] for i in range(n)], model.a,
                                            model.y, model.a_cg, model.y_cg)
    Qt = Qt + model.pitch_per_acceleration * acceleration_m_s2
    res = [(Qz - model.M * GRAVITY) / 1e4, Qt / 1e4, Qp / 1e4] + res
    axle_heights = [hull_eq.axle_height_change(q[0], q[1], ax.position, model.a_cg) for ax in P.axles]
    return {"residual": res, "wheel_loads": Ft_list, "strut_forces": Fs_list, "gas_forces": Fg_list,
            "gas_pressures": p_list, "deflections": xs_list, "station_heights": zs_list,
            "axle_heights": axle_heights}


def statics_inputs(n: int, temperatures_K, gas_masses_kg, oil_volumes_m3=None):
    """(T [K], m [kg], dV [m^3]) per strut as arrays of n: one temperature may serve all, no oil volumes = 0."""
    T = np.broadcast_to(np.asarray(temperatures_K, float), (n,)).copy()
    dV = np.zeros(n) if oil_volumes_m3 is None else np.asarray(oil_volumes_m3, float)
    return T, np.asarray(gas_masses_kg, float), dV


def _equilibrium_graph(model) -> tuple:
    """(inputs q, T, m, dV, acc; residual; outputs wheel loads, strut forces, deflections) of the static balance of
    `model` (a VehicleModel or its symbolic twin) in q = (z, theta, phi, w_i)."""
    n = model.n
    q = ca.SX.sym("q", 3 + n)           # z, theta, phi, w_i
    T = ca.SX.sym("T", n)
    m = ca.SX.sym("m", n)
    dV = ca.SX.sym("dV", n)
    acc = ca.SX.sym("acc")
    b = static_balance(model, q, T, m, dV, acceleration_m_s2=acc)
    outputs = [ca.vertcat(*b["wheel_loads"]), ca.vertcat(*b["strut_forces"]), ca.vertcat(*b["deflections"])]
    return [q, T, m, dV, acc], ca.vertcat(*b["residual"]), outputs


def _equilibrium_expressions(model) -> list:
    """Everything the equilibrium's functions evaluate (`_equilibrium_graph`'s residual and outputs)."""
    _, res, outputs = _equilibrium_graph(model)
    return [res, *outputs]


def equilibrium_functions(model: VehicleModel) -> dict:
    """F (residual), Jf (its Jacobian in q), out (outputs) of `_equilibrium_graph` and their NumericFunctions."""
    args, res, outputs = _equilibrium_graph(model)
    F = ca.Function("eq_res", args, [res])
    Jf = ca.Function("eq_jac", args, [ca.jacobian(res, args[0])])
    out = ca.Function("eq_out", args, outputs)
    return {"F": F, "Jf": Jf, "out": out, "numeric_residual": NumericFunction(F),
            "numeric_jacobian": NumericFunction(Jf), "numeric_out": NumericFunction(out), "maps": {}}


EXHAUSTED = ("static equilibrium: the struts cannot carry the vehicle at these temperatures and charges (gas volume "
             "exhausted)")
NOT_CONVERGED = "static equilibrium did not converge (check temperatures and charges)"


class EquilibriumSolver:
    """Newton solve of the static balances for given temperatures, gas masses and oil volumes (and a steady
    longitudinal acceleration: the settled state of a vehicle braking or accelerating at a constant rate)."""

    def __init__(self, model: VehicleModel):
        self.model = model
        built = shared_statics(model, "equilibrium", _equilibrium_expressions, equilibrium_functions)
        self.F, self.Jf, self.out = built["F"], built["Jf"], built["out"]
        self.numeric_residual, self.numeric_jacobian, self.numeric_out = \
            built["numeric_residual"], built["numeric_jacobian"], built["numeric_out"]
        self.maps = built["maps"]

    def solve(self, temperatures_K, gas_masses_kg, oil_volumes_m3=None, q0=None,
              acceleration_m_s2: float = 0.0) -> Equilibrium:
        """acceleration_m_s2: steady longitudinal acceleration (+ forward, braking < 0), default standing."""
        model = self.model
        n = model.n
        a = float(acceleration_m_s2)
        T, m, dV = statics_inputs(n, temperatures_K, gas_masses_kg, oil_volumes_m3)
        q = np.zeros(3 + n) if q0 is None else np.asarray(q0, float).copy()
        for it in range(100):
            r, = self.numeric_residual.vectors(q, T, m, dV, a)
            if not np.all(np.isfinite(r)):
                raise UserInputError(EXHAUSTED)
            if np.max(np.abs(r)) < 1e-10:
                break
            J, = self.numeric_jacobian(q, T, m, dV, a)
            dq = np.linalg.solve(J, -r)
            # damped Newton: limit wheel/hull moves to 20 mm per iteration
            scale = min(1.0, 0.02 / max(np.max(np.abs(dq)), 1e-30))
            q = q + scale * dq
        else:
            raise UserInputError(NOT_CONVERGED)
        return self._standing(q, T, m, dV, a)

    def solve_many(self, temperatures_K, gas_masses_kg, oil_volumes_m3=None) -> list[Equilibrium]:
        """`solve` standing (from the charged pose) for each row of temperatures_K and oil_volumes_m3 (rows of n
        per strut), the rows' Newton steps taken together (`lockstep_newton`): each the same as its `solve`."""
        n = self.model.n
        T = np.atleast_2d(np.asarray(temperatures_K, float))
        dV = np.zeros_like(T) if oil_volumes_m3 is None else np.atleast_2d(np.asarray(oil_volumes_m3, float))
        m = np.asarray(gas_masses_kg, float)
        M = np.repeat(m[:, None], len(T), axis=1)
        Q = np.zeros((len(T), 3 + n))

        def inputs(rows):
            return Q[rows].T, T[rows].T, M[:, rows], dV[rows].T, np.zeros((1, rows.size))

        def residual(rows):
            return mapped_function(self.maps, self.F, rows.size)(*inputs(rows))[0].T

        def jacobian(rows):
            J = mapped_function(self.maps, self.Jf, rows.size)(*inputs(rows))[0]
            return J.reshape(3 + n, rows.size, 3 + n).transpose(1, 0, 2)

        lockstep_newton(residual, jacobian, Q, 1e-10, 100, EXHAUSTED, NOT_CONVERGED)
        return [self._standing(Q[k].copy(), T[k].copy(), m, dV[k].copy(), 0.0) for k in range(len(T))]

    def _standing(self, q, T, m, dV, a) -> Equilibrium:
        """The Equilibrium at the solution q (strut on an end stop: UserInputError)."""
        model = self.model
        n = model.n
        Ft, Fs, xs = self.numeric_out.vectors(q, T, m, dV, a)
        for i in range(n):
            stroke = model.struts[i].p.geometry.stroke
            if not -1e-3 <= xs[i] <= stroke + 1e-3:
                where = "full extension" if xs[i] < 0 else "the bump stop"
                raise UserInputError(
                    f"static equilibrium: strut at {model.station_names[i]} sits on {where} "
                    f"(deflection {xs[i] * 1e3:.4g} mm, stroke 0-{stroke * 1e3:.4g} mm): it cannot carry its load "
                    "at these temperatures and charges")
        dh = np.array([hull_eq.axle_height_change(q[0], q[1], ax.position, model.a_cg) for ax in model.params.axles])
        p_gas = Fs / np.array([s.p.geometry.gas_area for s in model.struts])
        return Equilibrium(heave_m=float(q[0]), pitch_rad=float(q[1]), roll_rad=float(q[2]),
                           wheel_displacement_m=q[3:].copy(), wheel_loads_N=Ft, strut_forces_N=Fs,
                           strut_deflections_m=xs, gas_pressures_Pa=p_gas, axle_height_change_m=dh,
                           temperatures_K=T)


def equilibrium_table(model: VehicleModel, eq: Equilibrium) -> dict:
    """The per-axle table of `hpsim vehicle equilibrium` (changes against the charged state)."""
    axles = []
    N0 = model.charged_wheel_loads
    for k in range(model.params.n_axles):
        l, r = 2 * k, 2 * k + 1
        mean = 0.5 * (eq.wheel_loads_N[l] + eq.wheel_loads_N[r])
        mean0 = 0.5 * (N0[l] + N0[r])
        axles.append({"axle": k + 1, "dh_mm": eq.axle_height_change_m[k] * 1e3,
                      "N_left_daN": eq.wheel_loads_N[l] / 10.0, "N_right_daN": eq.wheel_loads_N[r] / 10.0,
                      "N_mean_daN": mean / 10.0, "dN_pct": 100.0 * (mean - mean0) / mean0})
    return {"axles": axles, "pitch_mrad": eq.pitch_rad * 1e3, "roll_mrad": eq.roll_rad * 1e3,
            "total_load_N": float(np.sum(eq.wheel_loads_N))}


def equilibrium_solver(model: VehicleModel) -> EquilibriumSolver:
    """The model's EquilibriumSolver, built once per model object: a run's vehicle check, its drive and its weighings
    stand the same vehicle (each build makes the static balance and its Jacobian: ~20 ms)."""
    solver = model.__dict__.get("_equilibrium_solver")
    if solver is None:
        solver = model.__dict__["_equilibrium_solver"] = EquilibriumSolver(model)
    return solver
