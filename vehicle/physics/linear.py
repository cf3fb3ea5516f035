"""The vehicle linearised at its static equilibrium: modes and road-to-hull / road-to-tyre-load responses.

`linearise(params)` charges the struts, finds the standing equilibrium (EquilibriumSolver) at the
given strut temperatures, and differentiates the model's explicit ODE (`VehicleModel.ode_function`,
valves eliminated) and outputs there with CasADi: dx/dt = A dx + B du, y = C dx + D du. The
mechanical states are kept (hull heave, pitch, roll; wheels; every strut internal state such as
the gas temperature, whose heat exchange makes the gas spring stiffer at high frequency); the
slow thermal, levelling and bookkeeping states are frozen.

What the linearisation means: small motions about the standing equilibrium. The smooth laws of
the model are differentiated as they are: the valve is its laminar bleed (check and blow-off
valves closed), and seal friction, smoothed over `friction.smoothing_velocity` (0.5 mm/s for the
apc strut), is a very stiff damper at zero velocity: for amplitudes that small the struts stick and
the vehicle rides on its tyres. `friction_velocity_m_s` gives the *equivalent linear* vehicle
instead. The Coulomb friction is replaced by its first-harmonic (describing-function) damping at
that strut velocity amplitude V, c_eq = 2 (F_C,comp + F_C,reb) / (pi V) (4 F_C / (pi V) when
symmetric; Gelb & Vander Velde 1968). This is done by widening the friction's smoothing to pi V / 4
(the smooth sign's slope at zero is then exactly c_eq), with the Stribeck peak and the seed-001
hysteresis band off.

Modes come from the eigenvalues of A: natural frequency |lambda| / 2 pi, damping ratio
-Re(lambda) / |lambda|, named by where their kinetic energy is (hull heave = bounce, pitch, roll;
wheels = hop, left/right in phase, or tramp, in anti-phase).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from struts.params import load_strut

from vehicle.physics.equilibrium import EquilibriumSolver, NumericFunction, charge_gas_masses
from vehicle.physics.model import VehicleModel
from vehicle.physics.params import VehicleParams
from vehicle.physics.ride import seat_vertical_acceleration

HULL = ("z", "theta", "phi")
HULL_RATES = ("dz", "dtheta", "dphi")


@dataclass
class Mode:
    name: str
    frequency_hz: float          # undamped natural frequency |lambda| / (2 pi)
    damping_ratio: float         # -Re(lambda) / |lambda|
    eigenvalue: complex
    energy_shares: dict          # kinetic energy share: heave, pitch, roll, wheels (per station)

    def as_dict(self) -> dict:
        return {"name": self.name, "frequency_hz": self.frequency_hz, "damping_ratio": self.damping_ratio,
                "eigenvalue": [self.eigenvalue.real, self.eigenvalue.imag],
                "energy_shares": {k: float(v) for k, v in self.energy_shares.items()}}


@dataclass
class LinearVehicle:
    """dx/dt = A x + B_road r + B_rate dr/dt (road height r and rate under each tyre), about equilibrium."""

    model: VehicleModel
    states: list[str]
    A: np.ndarray
    B_road: np.ndarray            # (n_states, n_stations)
    B_rate: np.ndarray
    C_tyre: np.ndarray            # tyre (wheel) load: (n_stations, n_states)
    D_tyre_road: np.ndarray       # (n_stations, n_stations)
    D_tyre_rate: np.ndarray
    temperatures_K: np.ndarray
    static_wheel_loads_N: np.ndarray
    friction_velocity_m_s: float | None
    notes: list[str] = field(default_factory=list)
    C_velocity: np.ndarray | None = None          # strut velocity (compression positive, as the model's output
    D_velocity_road: np.ndarray | None = None     # `strut_velocity`): (n_stations, n_states), (n_stations, n_stations)
    D_velocity_rate: np.ndarray | None = None

    def index(self, name: str) -> int:
        return self.states.index(name)

    @property
    def eigenvalues(self) -> np.ndarray:
        return np.linalg.eigvals(self.A)


# --- equivalent-linear friction --------------------------------------------------------------------
def equivalent_friction_params(params: VehicleParams, velocity_amplitude_m_s: float) -> VehicleParams:
    """The vehicle with every strut's seal friction replaced by its describing-function damping at
    strut velocity amplitude V [m/s] (see the module doc): smoothing pi V / 4, no Stribeck peak, no
    hysteresis band, the Stribeck (not LuGre) law. Viscous friction and the valves stay."""
    V = float(velocity_amplitude_m_s)
    if not (math.isfinite(V) and V > 0):
        raise ValueError(f"velocity amplitude must be > 0 m/s, got {velocity_amplitude_m_s!r}")
    data = params.model_dump()
    for axle in data["axles"]:
        ov = dict(axle.get("strut_overrides") or {})
        ov.update({"friction.model": "stribeck", "friction.smoothing_velocity": math.pi * V / 4.0,
                   "friction.breakaway_ratio": 1.0, "friction.hysteresis_velocity_compression": 0.0,
                   "friction.hysteresis_velocity_rebound": 0.0})
        if load_strut(axle["strut"], axle.get("strut_overrides") or None).internal_maps is not None:
            # seed 001 maps of the peak, Stribeck and band: off too (their constants above take over)
            ov.update({f"internal_maps.{k}": None for k in ("peak_compression", "peak_rebound",
                                                            "transition_velocity_compression",
                                                            "transition_velocity_rebound")})
        axle["strut_overrides"] = ov
    return VehicleParams.model_validate(data)


def mechanical_states(model: VehicleModel) -> list[str]:
    """Wheels, strut internal states and hull (the states a ride linearisation keeps)."""
    names = []
    for i in range(model.n):
        names += [f"w[{i}]", f"dw[{i}]"] + [f"{nm}[{i}]" for nm in model.struts[i].state_names]
    return names + list(HULL) + list(HULL_RATES)


# the outputs `linearise` keeps: the tyre loads and the strut velocities
LINEARISED_OUTPUTS = ("wheel_load", "strut_velocity")


def jacobian_graph(model: VehicleModel, outputs: tuple[str, ...] = LINEARISED_OUTPUTS) -> ca.Function:
    """(x, z, u, p) -> the Jacobians `_model_jacobians` reads (CasADi AD of the model's DAE form), named
    `jacobian_name(model, outputs)`: the same for every model of one structure (the parameter values are its input
    p), so a caller may keep it (the multiscale proxy keeps it in the compile cache, serialized)."""
    f, g, y = model.dae_functions
    x, z, u = ca.SX.sym("x", model.nx), ca.SX.sym("z", model.nz), ca.SX.sym("u", model.nu)
    p = ca.SX.sym("p", model.np)
    dx, res, out_all = f(x, z, u, p), g(x, z, u, p), y(x, z, u, p)[0]
    ys = []
    for name in outputs:
        j = list(model.OUTPUT_NAMES).index(name)
        ys.append(out_all[j * model.n:(j + 1) * model.n])
    yv = ca.vertcat(*ys)
    return ca.Function(jacobian_name(model, outputs), [x, z, u, p],
                       [ca.jacobian(dx, x), ca.jacobian(dx, z), ca.jacobian(dx, u),
                        ca.jacobian(yv, x), ca.jacobian(yv, z), ca.jacobian(yv, u),
                        ca.jacobian(res, x), ca.jacobian(res, z), ca.jacobian(res, u), res, dx])


def jacobian_name(model: VehicleModel, outputs: tuple[str, ...] = LINEARISED_OUTPUTS) -> str:
    return f"hpsim_linear_jacobians_{model.structure}_{len(outputs)}" + "".join(f"_{o}" for o in outputs)


def _jacobian_function(model: VehicleModel, outputs: tuple[str, ...]) -> ca.Function:
    """`jacobian_graph`, built once per model structure and outputs: models that differ in parameter values only
    (the equivalent-linear friction at several velocity amplitudes, as the multiscale proxy's matching asks for)
    share it."""
    key = (model.structure, tuple(outputs))
    J = _JACOBIANS.get(key)
    if J is None:
        J = jacobian_graph(model, outputs)
        if len(_JACOBIANS) >= 8:
            _JACOBIANS.pop(next(iter(_JACOBIANS)))
        _JACOBIANS[key] = J
    return J


# Jacobian functions of `_jacobian_function` by (model structure, outputs): a few, the oldest dropped first
_JACOBIANS: dict = {}


def _model_jacobians(model: VehicleModel, x0: np.ndarray, u0: np.ndarray, p: np.ndarray,
                     outputs: tuple[str, ...] = ("wheel_load",), J: ca.Function | None = None):
    """(df/dx, df/du, [(dy/dx, dy/du) per output], f) at (x0, u0) for run parameters p; y: the per-station
    outputs `outputs` (names in VehicleModel.OUTPUT_NAMES, default the tyre load).

    The one place that calls the model's CasADi functions: the DAE form `dae_functions`
    (f(x, z, u, p), g(x, z, u, p) = 0, y(x, z, u, p)), its algebraic valve pressure drops z
    eliminated by the implicit-function theorem, dz = -g_z^-1 (g_x dx + g_u du). (The explicit
    ODE form eliminates them by a warm-started, clamped Newton step whose derivative is
    ill-defined exactly at rest, where the clamp's bounds meet.)
    """
    J = _jacobian_function(model, outputs) if J is None else J
    jacobians = NumericFunction(J)          # evaluated into NumPy buffers: no element-by-element DM conversion
    z0 = np.zeros(model.nz)
    for _ in range(20):                     # the valve pressure drops at the equilibrium (0 at rest)
        values = jacobians(x0, z0, u0, p)
        *_, gx, gz, gu, r, _ = values
        if model.nz == 0 or np.max(np.abs(r)) < 1e-12:
            break                           # the Jacobians at this z0 are the ones wanted
        z0 = z0 - np.linalg.solve(gz, r.ravel())
    else:
        values = jacobians(x0, z0, u0, p)
    fx, fz, fu, yx, yz, yu, gx, gz, gu, _, rates = values
    if model.nz:
        zx, zu = -np.linalg.solve(gz, gx), -np.linalg.solve(gz, gu)
        fx, fu, yx, yu = fx + fz @ zx, fu + fz @ zu, yx + yz @ zx, yu + yz @ zu
    n = model.n
    return fx, fu, [(yx[k * n:(k + 1) * n], yu[k * n:(k + 1) * n]) for k in range(len(outputs))], rates.ravel()


def linearise(params: VehicleParams, temperatures_K=None, friction_velocity_m_s: float | None = None,
              speed_m_per_s: float = 0.0, gas_masses=None, equilibrium=None,
              jacobians: ca.Function | None = None) -> LinearVehicle:
    """The vehicle linearised at its standing equilibrium (struts at `temperatures_K`, default the
    charging temperature; charged as in a drive, or with the given `gas_masses`, a drive's own [kg]).
    See the module doc for the friction option. `equilibrium`: that standing equilibrium when the caller has
    solved it (an `EquilibriumSolver.solve` of this vehicle at these temperatures and gas masses: the seal
    friction does not enter the static balance, so one serves every friction velocity). `jacobians`: this
    vehicle's `jacobian_graph` when the caller keeps one (default: built here, once per model structure)."""
    model = None
    if gas_masses is None:
        model = VehicleModel(params)
        gas_masses = charge_gas_masses(model)      # the gas charge does not depend on friction
    if friction_velocity_m_s:
        model = VehicleModel(equivalent_friction_params(params, friction_velocity_m_s))
    elif model is None:
        model = VehicleModel(params)
    gas_masses = np.asarray(gas_masses, float)
    n = model.n
    T = np.full(n, params.charging.temperature) if temperatures_K is None else \
        np.broadcast_to(np.asarray(temperatures_K, float), (n,)).copy()
    eq = EquilibriumSolver(model).solve(T, gas_masses) if equilibrium is None else equilibrium
    return _linearised(model, model.run_parameters(gas_masses, False), T, gas_masses, eq, friction_velocity_m_s,
                       speed_m_per_s, jacobians)


def _linearised(model: VehicleModel, p: np.ndarray, T: np.ndarray, gas_masses: np.ndarray, eq,
                friction_velocity_m_s: float | None, speed_m_per_s: float, jacobians) -> LinearVehicle:
    """`linearise` of `model` at run parameters p (`VehicleModel.run_parameters`), strut temperatures T [K], gas
    masses [kg] and the standing equilibrium eq there."""
    x0 = model.state_at_rest(eq, gas_masses)
    # standing road, constant speed (no acceleration), ambient = strut temperature: no heat flow
    u0 = model.input_matrix(1, speed=speed_m_per_s, ambient=float(np.mean(T)))[:, 0]
    A, B, ((C, D), (Cv, Dv)), rates = _model_jacobians(model, x0, u0, p, LINEARISED_OUTPUTS, jacobians)
    names = mechanical_states(model)
    keep = [model.idx(nm) for nm in names]
    residual = np.max(np.abs(rates[keep]))
    notes = [f"linearised at the standing equilibrium, strut temperatures {np.min(T) - 273.15:.1f}-"
             f"{np.max(T) - 273.15:.1f} degC: small motions about it",
             "valves: the laminar bleed (check and blow-off valves closed at small amplitude)"]
    if friction_velocity_m_s:
        notes.append(f"seal friction: equivalent linear at a strut velocity amplitude of "
                     f"{friction_velocity_m_s * 1e3:.4g} mm/s (describing function 4 F_C / (pi V))")
    else:
        notes.append("seal friction: its smooth law differentiated at rest (a very stiff damper: the struts stick, "
                     "the vehicle rides on its tyres); use a friction velocity amplitude for the equivalent linear "
                     "vehicle")
    if residual > 1e-6:
        notes.append(f"warning: the equilibrium is not at rest in the dynamic model (max |dx/dt| = {residual:.3g})")
    road, rate = model.input_index["road"], model.input_index["road_rate"]
    return LinearVehicle(model=model, states=names, A=A[np.ix_(keep, keep)], B_road=B[keep, road],
                         B_rate=B[keep, rate], C_tyre=C[:, keep], D_tyre_road=D[:, road], D_tyre_rate=D[:, rate],
                         temperatures_K=T, static_wheel_loads_N=np.asarray(eq.wheel_loads_N, float),
                         friction_velocity_m_s=friction_velocity_m_s, notes=notes, C_velocity=Cv[:, keep],
                         D_velocity_road=Dv[:, road], D_velocity_rate=Dv[:, rate])


class EquivalentLinearVehicles:
    """`linearise(params, T, friction_velocity_m_s=V, gas_masses=..., equilibrium=..., jacobians=...)` at several
    friction velocity amplitudes V from one model: V enters the equivalent-friction vehicle
    (`equivalent_friction_params`) only as the struts' friction smoothing pi V / 4, a parameter value of the one
    Jacobian function, so each V sets those values in the run parameters instead of building the vehicle's
    parameters and model again. Equal bit for bit to `linearise` at each V (tests/unit/physics/test_linear_family.py);
    each LinearVehicle's `model` is the one given (its own smoothing value aside, the same vehicle).

    model: `VehicleModel(equivalent_friction_params(params, V0))` for some V0; temperatures_K, gas_masses, equilibrium:
    as `linearise` takes them; jacobians: `jacobian_graph(model)` or a kept copy of it (default: built here)."""

    SMOOTHING = ".friction.smoothing_velocity"       # the parameter V sets, per strut model (`symbolic_copy` names)

    def __init__(self, model: VehicleModel, temperatures_K, gas_masses, equilibrium, jacobians=None):
        self.model = model
        self.T = np.broadcast_to(np.asarray(temperatures_K, float), (model.n,)).copy()
        self.gas_masses = np.asarray(gas_masses, float)
        self.equilibrium = equilibrium
        self.jacobians = _jacobian_function(model, LINEARISED_OUTPUTS) if jacobians is None else jacobians
        self.p = model.run_parameters(self.gas_masses, False)
        self.smoothing = model.n_run + np.array([k for k, nm in enumerate(model.parameters.names)
                                                 if nm.startswith("strut") and nm.endswith(self.SMOOTHING)], int)
        if self.smoothing.size == 0:
            raise ValueError("the model has no seal friction smoothing among its parameters")

    def at(self, V: float) -> LinearVehicle:
        """The equivalent linear vehicle at strut velocity amplitude V [m/s]."""
        V = float(V)
        if not (math.isfinite(V) and V > 0):
            raise ValueError(f"velocity amplitude must be > 0 m/s, got {V!r}")
        p = self.p.copy()
        p[self.smoothing] = math.pi * V / 4.0
        return _linearised(self.model, p, self.T, self.gas_masses, self.equilibrium, V, 0.0, self.jacobians)


# --- modes -----------------------------------------------------------------------------------------
def modes(lin: LinearVehicle) -> list[Mode]:
    """Oscillatory modes (complex eigenvalue pairs), lowest frequency first, named by kinetic energy."""
    m = lin.model
    P = m.params
    lam, vec = np.linalg.eig(lin.A)
    inertia = {"heave": m.M, "pitch": P.hull.pitch_inertia, "roll": P.hull.roll_inertia}
    rate_index = {"heave": lin.index("dz"), "pitch": lin.index("dtheta"), "roll": lin.index("dphi")}
    wheel_index = [lin.index(f"dw[{i}]") for i in range(m.n)]
    out = []
    for k in np.flatnonzero(lam.imag > 1e-9):
        v = vec[:, k]
        energy = {key: inertia[key] * abs(v[j]) ** 2 for key, j in rate_index.items()}
        wheels = np.array([m.m_u[i] * abs(v[j]) ** 2 for i, j in enumerate(wheel_index)])
        total = sum(energy.values()) + wheels.sum()
        shares = {key: e / total for key, e in energy.items()}
        shares.update({m.station_names[i]: wheels[i] / total for i in range(m.n)})
        hull_name = max(energy, key=energy.get)
        if sum(energy.values()) >= wheels.sum():
            name = {"heave": "bounce", "pitch": "pitch", "roll": "roll"}[hull_name]
        else:
            name = _wheel_mode_name(m, v[wheel_index], wheels)
        w = abs(lam[k])
        out.append(Mode(name, w / (2 * math.pi), -lam[k].real / w, complex(lam[k]), shares))
    out = sorted(out, key=lambda md: md.frequency_hz)
    seen: dict[str, int] = {}
    for md in out:           # a name still shared (a near-degenerate pair): numbered from the lowest frequency
        seen[md.name] = seen.get(md.name, 0) + 1
        if seen[md.name] > 1:
            md.name = f"{md.name} #{seen[md.name]}"
    return out


def _wheel_mode_name(model: VehicleModel, wheel_velocities, wheel_energy) -> str:
    """'wheel hop' (left and right in phase) or 'wheel tramp' (anti-phase), with the axles that
    carry at least a quarter of the wheels' energy (near-equal axles mix in one mode)."""
    per_axle = wheel_energy[0::2] + wheel_energy[1::2]
    axle = int(np.argmax(per_axle))
    left, right = wheel_velocities[2 * axle], wheel_velocities[2 * axle + 1]
    kind = "hop" if (left * np.conj(right)).real >= 0 else "tramp"
    involved = np.flatnonzero(per_axle >= 0.25 * per_axle.sum())
    axles = [str(k + 1) for k in involved]
    # several axles: which move against the strongest one (the same axles make an in-phase and an opposed mode)
    against = [str(k + 1) for k in involved
               if (wheel_velocities[2 * k] * np.conj(left)).real < 0]
    phase = "" if len(axles) == 1 else (", in phase" if not against else f", {', '.join(against)} against {axle + 1}")
    return f"wheel {kind} (axle{'s' if len(axles) > 1 else ''} {', '.join(axles)}{phase})"


def mode_summary(mode_list: list[Mode]) -> dict:
    """The modes an engineer quotes: bounce, pitch, roll (lowest of each), wheel hop/tramp range."""
    out = {}
    for name in ("bounce", "pitch", "roll"):
        found = [md for md in mode_list if md.name == name]
        if found:
            out[name] = found[0]
    wheel = [md for md in mode_list if md.name.startswith("wheel")]
    if wheel:
        out["wheel_hop_range_hz"] = (min(md.frequency_hz for md in wheel), max(md.frequency_hz for md in wheel))
    return out


# --- frequency responses -----------------------------------------------------------------------------
def frequency_response(lin: LinearVehicle, road_weights, f_hz) -> dict:
    """Responses to a road input r_i = road_weights[i] R e^(j w t) under each tyre, per unit R [m].

    Returns complex arrays over f_hz: hull heave acceleration [m/s^2 / m], pitch and roll
    accelerations [rad/s^2 / m], per-seat vertical acceleration (vehicle seats) and tyre loads
    (n_stations, n_f) [N / m].
    """
    f = np.atleast_1d(np.asarray(f_hz, float))
    wts = np.asarray(road_weights, float)
    n_x = lin.A.shape[0]
    I = np.eye(n_x)
    iz, it, ip = (lin.index(nm) for nm in HULL_RATES)
    heave, pitch, roll = (np.empty(len(f), complex) for _ in range(3))
    tyre = np.empty((lin.model.n, len(f)), complex)
    for k, fk in enumerate(f):
        s = 2j * math.pi * fk
        b = (lin.B_road + s * lin.B_rate) @ wts
        X = np.linalg.solve(s * I - lin.A, b)
        heave[k], pitch[k], roll[k] = s * X[iz], s * X[it], s * X[ip]
        tyre[:, k] = lin.C_tyre @ X + (lin.D_tyre_road + s * lin.D_tyre_rate) @ wts
    seats = {st.name: seat_vertical_acceleration(heave, pitch, roll, st.x_from_cg, st.y_from_cg)
             for st in lin.model.params.seats}
    return {"f_hz": f, "heave_acc": heave, "pitch_acc": pitch, "roll_acc": roll, "seat_acc": seats,
            "tyre_load": tyre}


def strut_velocity_response(lin: LinearVehicle, f_hz) -> np.ndarray:
    """H (n_f, n_stations, n_stations): strut velocity at station i per unit road height [m/s / m] under station
    j alone (its height and its rate j w times it), H(s) = C_v (s I - A)^-1 (B_road + s B_rate) + D_road + s D_rate.
    The stations' own road inputs carry the wheelbase delays and the two tracks (a drive's road under each
    tyre); by the eigen-decomposition of A (one solve per mode, not per frequency)."""
    f = np.atleast_1d(np.asarray(f_hz, float))
    s = 2j * math.pi * f
    lam, V = np.linalg.eig(lin.A)
    CV = lin.C_velocity @ V                                     # (n, m)
    Vi = np.linalg.inv(V)
    Br, Bd = Vi @ lin.B_road, Vi @ lin.B_rate                   # (m, n)
    g = 1.0 / (s[:, None] - lam[None, :])                       # (n_f, m)
    # sum over the modes m of CV_im g_fm Br_mj as one matrix product per frequency (BLAS; einsum's loop over
    # f, i, j, m was the proxy set-up's largest item)
    H = (CV[None] * g[:, None, :]) @ Br + (CV[None] * (g * s[:, None])[:, None, :]) @ Bd
    return H + lin.D_velocity_road[None] + s[:, None, None] * lin.D_velocity_rate[None]


def axle_road_weights(lin: LinearVehicle, axle: int) -> np.ndarray:
    """Road input at axle `axle` (0-based), both tracks in phase, none elsewhere."""
    w = np.zeros(lin.model.n)
    w[2 * axle: 2 * axle + 2] = 1.0
    return w
