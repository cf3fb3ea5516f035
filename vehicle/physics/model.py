"""The vehicle DAE: hull (bounce, pitch, roll) + wheel stations + struts + heat + levelling.

`VehicleModel` is equations only (PyBaMM-style): it names its states, algebraic variables,
inputs and run parameters, and builds CasADi expressions for
    dx/dt = f(x, z, u, p),   0 = g(x, z, u, p),   outputs y(x, z, u, p).
Solvers (`vehicle.numerics.solvers`) decide how to integrate it; `vehicle.runs.drive` ties it to a road and a
speed profile.

States (per station i, stations axle-major, left first):
  hull:     z, theta, phi [m, rad], and their rates
  station:  w_i (wheel vertical displacement from the charged pose, + up), dw_i,
            T_strut_i (strut body temperature), strut internal states (e.g. T_gas_i),
            xf_i (filtered deflection, compensation), V_oil_i (oil added by compensation)
  energy quadratures per station [J]: valve, friction, gas heat, end stop, strut work,
            tyre work, road work.
Algebraic: dp_valve_i [Pa] (valve flow balance, incompressible oil: seed 000 eq. 2).
Inputs u (time-varying): road height r_i [m] and rate dr_i [m/s] under each tyre (enveloped
  road at the wheel's own distance), vehicle speed V [m/s], ambient temperature [K].
Run parameters p (constant during a run, so one compiled model serves every case): gas mass
  per strut [kg], compensation on/off (0/1).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import casadi as ca
import numpy as np

from struts.model import StrutInputs, make_strut
from struts.params import load_strut

from vehicle.physics import compensation as comp
from vehicle.physics import hull as hull_eq
from vehicle.physics import thermal
from vehicle.physics.params import GRAVITY, VehicleParams
from vehicle.physics.tyre import tyre_force

ENERGY_TERMS = ("valve", "friction", "gas", "end_stop", "strut_work", "tyre_work", "road_work")
DISSIPATION_TERMS = ("valve", "friction", "gas", "end_stop")
HULL_ACCELERATIONS = ("heave_acc", "pitch_acc", "roll_acc")


@dataclass
class Layout:
    """Names and index ranges of the state vector."""

    names: list[str] = field(default_factory=list)

    def add(self, name: str) -> int:
        self.names.append(name)
        return len(self.names) - 1

    def index(self, name: str) -> int:
        return self.names.index(name)

    def __len__(self):
        return len(self.names)


class VehicleModel:
    def __init__(self, params: VehicleParams):
        self.params = params
        self.n = params.n_stations
        self.station_names = params.station_names()
        # one strut model per distinct (file, overrides)
        self.struts = []
        cache = {}
        for i in range(self.n):
            axle = params.axles[params.station_axle(i)]
            key = (axle.strut, repr(sorted(axle.strut_overrides.items())))
            if key not in cache:
                cache[key] = make_strut(load_strut(axle.strut, axle.strut_overrides or None))
            self.struts.append(cache[key])
        self.a = np.array([params.axles[params.station_axle(i)].position for i in range(self.n)])
        self.y = np.array([params.station_y(i) for i in range(self.n)])
        self.r = np.array([params.axles[params.station_axle(i)].motion_ratio for i in range(self.n)])
        self.m_u = np.array([params.axles[params.station_axle(i)].unsprung_mass for i in range(self.n)])
        self.a_cg = params.sprung_cg_x()
        self.y_cg = params.hull.cg_y
        self.M = params.sprung_mass()
        self.x_charged = params.charging.strut_deflection
        loads = np.repeat(np.asarray(params.charging.wheel_loads, float), 2)
        self.charged_wheel_loads = loads
        # tyre deflection at the charged state carries the charged wheel load
        self.tyre_static_deflection = loads / params.tyre.stiffness
        self._build_layout()

    # --- layout ----------------------------------------------------------------------------------
    def _build_layout(self):
        L = Layout()
        # stiff block first (treated implicitly by the Rosenbrock solver): each station's
        # mechanics and strut internal states, then the hull, which couples to every station.
        # Stations before hull keeps the block's sparse factorisation free of fill-in (arrowhead).
        for i, s in enumerate(self.station_names):
            L.add(f"w[{i}]")
            L.add(f"dw[{i}]")
            for nm in self.struts[i].stiff_state_names:
                L.add(f"{nm}[{i}]")
        for nm in ("z", "theta", "phi", "dz", "dtheta", "dphi"):
            L.add(nm)
        self.n_stiff = len(L)
        for i in range(self.n):
            for nm in self.struts[i].state_names:
                if nm not in self.struts[i].stiff_state_names:
                    L.add(f"{nm}[{i}]")
        for i in range(self.n):
            L.add(f"T_strut[{i}]")
            L.add(f"xf[{i}]")
            L.add(f"V_oil[{i}]")
        # last valve pressure drop of each incompressible strut: not a state of the physics but the
        # warm start of the Newton elimination in the fixed-step solver (rate 0; the solver
        # overwrites it after every step)
        for i in range(self.n):
            if not self.struts[i].compressible:
                L.add(f"dp_memory[{i}]")
        self.n_dynamic = len(L)
        for i in range(self.n):
            for e in ENERGY_TERMS:
                L.add(f"E_{e}[{i}]")
        # integrals of squares for RMS statistics: strut velocity per station, hull accelerations
        for i in range(self.n):
            L.add(f"I_v2[{i}]")
        for nm in HULL_ACCELERATIONS:
            L.add(f"I_{nm}2")
        self.layout = L
        self.nx = len(L)
        self.nz = sum(len(st.algebraic_names) for st in self.struts)
        self.nu = 2 * self.n + 2
        self.np = 2 * self.n + 1

    def station_motion(self, X, i: int):
        """(strut deflection [m], strut velocity [m/s]) of station i from named states X.

        The wheel's motion relative to the hull point above it, through the motion ratio
        (hull.py); symbolic or numeric.
        """
        zs = hull_eq.station_displacement(X["z"], X["theta"], X["phi"], self.a[i], self.y[i], self.a_cg, self.y_cg)
        dzs = hull_eq.station_displacement(X["dz"], X["dtheta"], X["dphi"], self.a[i], self.y[i],
                                           self.a_cg, self.y_cg)
        return (hull_eq.strut_deflection(self.x_charged, self.r[i], X[f"w[{i}]"], zs),
                self.r[i] * (X[f"dw[{i}]"] - dzs))

    def strut_deflections(self, X) -> np.ndarray:
        """Strut deflections [m] from state vectors X (nx, ...) -> (n_stations, ...)."""
        X = np.asarray(X)
        named = {nm: X[k] for k, nm in enumerate(self.layout.names)}
        return np.array([self.station_motion(named, i)[0] for i in range(self.n)])

    @cached_property
    def _z_index(self) -> dict:
        out, k = {}, 0
        for i, st in enumerate(self.struts):
            if not st.compressible:
                out[i] = k
                k += 1
        return out

    def idx(self, name: str) -> int:
        return self.layout.index(name)

    @cached_property
    def energy_index(self) -> dict:
        return {e: np.array([self.idx(f"E_{e}[{i}]") for i in range(self.n)]) for e in ENERGY_TERMS}

    # --- parameters of a run -------------------------------------------------------------------
    def run_parameters(self, gas_mass_kg, compensation_enabled: bool, nominal_deflection_m=None) -> np.ndarray:
        xn = np.full(self.n, self.x_charged) if nominal_deflection_m is None else np.asarray(nominal_deflection_m, float)
        return np.concatenate([np.asarray(gas_mass_kg, float), xn, [1.0 if compensation_enabled else 0.0]])

    # --- equations -------------------------------------------------------------------------------
    def equations(self, x, z, u, p, dp_override=None):
        """Symbolic (or numeric) rates, residuals and outputs.

        dp_override: if given (list per station), the valve pressure drops are taken from it
        instead of the algebraic variables z (used when a solver eliminates z by Newton).
        """
        P = self.params
        n = self.n
        X = {nm: x[k] for k, nm in enumerate(self.layout.names)}
        road = [u[i] for i in range(n)]
        droad = [u[n + i] for i in range(n)]
        speed = u[2 * n]
        T_amb = u[2 * n + 1]
        m_gas = [p[i] for i in range(n)]
        x_nom = [p[n + i] for i in range(n)]
        comp_on = p[2 * n]

        zc, th = X["z"], X["theta"]
        dzc, dth, dph = X["dz"], X["dtheta"], X["dphi"]
        h_conv = thermal.convection_coefficient(P.heat, speed)

        rates = {}
        residuals = []
        out = {k: [] for k in ("strut_force", "strut_deflection", "strut_velocity", "gas_pressure", "gas_temperature",
                               "tyre_force", "wheel_load", "power_valve", "power_friction", "heat_gas",
                               "power_end_stop", "oil_flow")}
        hull_forces = []
        for i in range(n):
            strut = self.struts[i]
            w, dw = X[f"w[{i}]"], X[f"dw[{i}]"]
            Ts = X[f"T_strut[{i}]"]
            xs, vs = self.station_motion(X, i)
            # levelling
            xf = X[f"xf[{i}]"]
            V_oil = X[f"V_oil[{i}]"]
            q_oil = comp_on * comp.oil_flow(xf, x_nom[i], strut.p.geometry.gas_area, P.compensation.time_constant,
                                            P.compensation.dead_band, P.compensation.flow_limit,
                                            P.compensation.smoothing)
            # strut
            internal = {nm: X[f"{nm}[{i}]"] for nm in strut.state_names}
            if self.struts[i].compressible:
                dp = None
            else:
                dp = dp_override[i] if dp_override is not None else z[self._z_index[i]]
            # The oil's thermal expansion enters through the gas volume (a function of T_strut);
            # its *rate* in the gas energy equation is left out (dT_wall_rate = 0): beta V_oil dT/dt
            # ~ 1e-8 m^3/s against A v ~ 1e-4 m^3/s while driving, and the gas follows the wall
            # within tau anyway. Keeping it would need the body-temperature rate, which depends on
            # the gas heat flow: no loop, but a second evaluation of the whole strut.
            sin = StrutInputs(x=xs, v=vs, T_wall=Ts, m_gas=m_gas[i], dV_oil=V_oil, dV_oil_rate=q_oil,
                              dT_wall_rate=0.0, x_mid=x_nom[i])
            eq = strut.equations(sin, internal, dp)
            P_diss = eq["power_valve"] + eq["power_friction"] + eq["heat_gas"] + eq["power_end_stop"]
            dTs = thermal.temperature_rate(Ts, P_diss, T_amb, h_conv, P.heat.surface_area, P.heat.emissivity,
                                           P.heat.capacity)
            Fs = eq["force"]
            # tyre on the enveloped road
            defl = self.tyre_static_deflection[i] + road[i] - w
            ddefl = droad[i] - dw
            Ft = tyre_force(defl, ddefl, P.tyre.stiffness, P.tyre.damping, P.tyre.lift_off_smoothing)
            # wheel station
            rates[f"w[{i}]"] = dw
            rates[f"dw[{i}]"] = (Ft - self.r[i] * Fs) / self.m_u[i] - GRAVITY
            for nm in strut.state_names:
                rates[f"{nm}[{i}]"] = eq["rates"][nm]
            rates[f"T_strut[{i}]"] = dTs
            if not strut.compressible:
                rates[f"dp_memory[{i}]"] = 0.0 * dTs
            rates[f"xf[{i}]"] = comp.filtered_deflection_rate(xf, xs, P.compensation.filter_time_constant)
            rates[f"V_oil[{i}]"] = q_oil
            rates[f"E_valve[{i}]"] = eq["power_valve"]
            rates[f"E_friction[{i}]"] = eq["power_friction"]
            rates[f"E_gas[{i}]"] = eq["heat_gas"]
            rates[f"E_end_stop[{i}]"] = eq["power_end_stop"]
            rates[f"E_strut_work[{i}]"] = Fs * vs
            rates[f"E_tyre_work[{i}]"] = Ft * ddefl
            rates[f"E_road_work[{i}]"] = Ft * droad[i]
            rates[f"I_v2[{i}]"] = vs * vs
            if eq["residual"] is not None:
                residuals.append(eq["residual"])
            hull_forces.append(self.r[i] * Fs)
            out["strut_force"].append(Fs)
            out["strut_deflection"].append(xs)
            out["strut_velocity"].append(vs)
            out["gas_pressure"].append(eq["gas_pressure"])
            out["gas_temperature"].append(eq["gas_temperature"])
            out["tyre_force"].append(Ft)
            out["wheel_load"].append(Ft)
            out["power_valve"].append(eq["power_valve"])
            out["power_friction"].append(eq["power_friction"])
            out["heat_gas"].append(eq["heat_gas"])
            out["power_end_stop"].append(eq["power_end_stop"])
            out["oil_flow"].append(q_oil)
        Qz, Qt, Qp = hull_eq.generalised_forces(hull_forces, self.a, self.y, self.a_cg, self.y_cg)
        ddz, ddt, ddp = hull_eq.hull_accelerations(Qz, Qt, Qp, self.M, P.hull.pitch_inertia, P.hull.roll_inertia,
                                                   GRAVITY)
        rates.update({"z": dzc, "theta": dth, "phi": dph, "dz": ddz, "dtheta": ddt, "dphi": ddp})
        # hull accelerations about equilibrium: gravity is balanced by the static strut forces
        for nm, acc in zip(HULL_ACCELERATIONS, (ddz, ddt, ddp)):
            rates[f"I_{nm}2"] = acc * acc
        out["hull_acc"] = [ddz, ddt, ddp]
        out["axle_height"] = [hull_eq.axle_height_change(zc, th, ax.position, self.a_cg) for ax in P.axles]
        ode = [rates[nm] for nm in self.layout.names]
        return ode, residuals, out

    # --- CasADi functions ------------------------------------------------------------------------
    @cached_property
    def symbols(self):
        return (ca.SX.sym("x", self.nx), ca.SX.sym("z", self.nz), ca.SX.sym("u", self.nu), ca.SX.sym("p", self.np))

    OUTPUT_NAMES = ("strut_force", "strut_deflection", "strut_velocity", "gas_pressure", "gas_temperature",
                    "wheel_load", "power_valve", "power_friction", "heat_gas", "power_end_stop", "oil_flow")

    @cached_property
    def dae_functions(self):
        """(f(x,z,u,p) -> ode, g(x,z,u,p) -> alg, y(x,z,u,p) -> outputs) as CasADi Functions."""
        x, z, u, p = self.symbols
        ode, alg, out = self.equations(x, z, u, p)
        f = ca.Function("f", [x, z, u, p], [ca.vertcat(*ode)])
        g = ca.Function("g", [x, z, u, p], [ca.vertcat(*alg)])
        y = ca.Function("y", [x, z, u, p], [ca.vertcat(*[ca.vertcat(*out[k]) for k in self.OUTPUT_NAMES]),
                                           ca.vertcat(*out["hull_acc"]), ca.vertcat(*out["axle_height"])])
        return f, g, y

    def eliminate_valves(self, x, iterations: int = 1):
        """Valve pressure drops of incompressible struts by warm-started Newton (explicit-ODE form)."""
        X = {nm: x[k] for k, nm in enumerate(self.layout.names)}
        dps = []
        for i in range(self.n):
            strut = self.struts[i]
            if strut.compressible:
                dps.append(None)
                continue
            _, vs = self.station_motion(X, i)
            dps.append(strut.valve_pressure_drop(vs, X[f"T_strut[{i}]"], dp_guess=X[f"dp_memory[{i}]"],
                                                 newton_iterations=iterations, warm=True))
        return dps

    @cached_property
    def memory_index(self) -> np.ndarray:
        return np.array([self.idx(f"dp_memory[{i}]") for i in range(self.n) if not self.struts[i].compressible],
                        dtype=int)

    @cached_property
    def ode_function(self):
        """f(x, u, p) -> (dx/dt, valve dp of the incompressible struts): the explicit-ODE form."""
        x, _, u, p = self.symbols
        dps = self.eliminate_valves(x)
        ode, _, out = self.equations(x, None, u, p, dp_override=dps)
        mem = ca.vertcat(*[d for d in dps if d is not None]) if len(self.memory_index) else ca.SX(0, 1)
        return ca.Function("f_ode", [x, u, p], [ca.vertcat(*ode), mem]), dps

    @cached_property
    def _strut_derivative_functions(self) -> list:
        """Per distinct strut: (x, v, T_wall, m_gas, dV_oil, internal..., dp) -> (dF/dx, dF/dv [N/m, N s/m]).

        The valve part of dF/dv goes through the implicit-function theorem of the flow balance,
        A_v^2 / (d q_valve / d dp), instead of differentiating the Newton iterations.
        """
        out = {}
        for strut in self.struts:
            if id(strut) in out:
                continue
            xs, vs, T, m, dV, dp = (ca.SX.sym(n) for n in ("x", "v", "T", "m", "dV", "dp"))
            internal = {nm: ca.SX.sym(nm) for nm in strut.state_names}
            eq = strut.equations(StrutInputs(x=xs, v=vs, T_wall=T, m_gas=m, dV_oil=dV), internal,
                                 None if strut.compressible else dp)
            F = eq["force"]
            k = ca.jacobian(F, xs)
            c = ca.jacobian(F, vs)
            if not strut.compressible:
                from struts import valves

                q = valves.valve_flow(dp, **strut.valve_arguments(T))
                Av = strut.p.geometry.valve_area
                c = c + ca.jacobian(F, dp) * Av / ca.jacobian(q, dp)
            args = [xs, vs, T, m, dV, dp] + [internal[nm] for nm in strut.state_names]
            out[id(strut)] = ca.Function("strut_kc", args, [k, c])
        return [out[id(s)] for s in self.struts]

    def stiff_jacobian(self, x, p, dps):
        """Approximate Jacobian of the stiff block (stations' w, dw, stiff strut states; hull).

        Built from each station's local strut stiffness/damping and the tyre's, through the
        constant kinematics (hull.py): the structural-dynamics form of d f / d x. Exact for the
        mechanics with frozen slow states, which is all a W-method needs.
        """
        P = self.params
        n = self.n
        X = {nm: x[k] for k, nm in enumerate(self.layout.names)}
        ns = self.n_stiff
        J = ca.SX(ns, ns)
        hull = [self.idx(nm) for nm in ("z", "theta", "phi")]
        dhull = [self.idx(nm) for nm in ("dz", "dtheta", "dphi")]
        for a, b in zip(hull, dhull):
            J[a, b] = 1.0
        inertia = [self.M, P.hull.pitch_inertia, P.hull.roll_inertia]
        kt, ct = P.tyre.stiffness, P.tyre.damping
        KK = [[0.0] * 3 for _ in range(3)]
        CC = [[0.0] * 3 for _ in range(3)]
        fns = self._strut_derivative_functions
        for i in range(n):
            strut = self.struts[i]
            w, dw = self.idx(f"w[{i}]"), self.idx(f"dw[{i}]")
            B = [1.0, -(self.a[i] - self.a_cg), self.y[i] - self.y_cg]   # d z_station / d (z, theta, phi)
            xs, vs = self.station_motion(X, i)
            dp = 0.0 if dps[i] is None else dps[i]
            args = [xs, vs, X[f"T_strut[{i}]"], p[i], X[f"V_oil[{i}]"], dp] + \
                [X[f"{nm}[{i}]"] for nm in strut.state_names]
            ks, cs = fns[i](*args)
            r2 = self.r[i] ** 2
            mu = self.m_u[i]
            J[w, dw] = 1.0
            J[dw, w] = (-kt - r2 * ks) / mu
            J[dw, dw] = (-ct - r2 * cs) / mu
            for j in range(3):
                J[dw, hull[j]] = r2 * ks * B[j] / mu
                J[dw, dhull[j]] = r2 * cs * B[j] / mu
                J[dhull[j], w] = r2 * ks * B[j] / inertia[j]
                J[dhull[j], dw] = r2 * cs * B[j] / inertia[j]
                for l in range(3):
                    KK[j][l] = KK[j][l] + r2 * ks * B[j] * B[l]
                    CC[j][l] = CC[j][l] + r2 * cs * B[j] * B[l]
        for j in range(3):
            for l in range(3):
                J[dhull[j], hull[l]] = -KK[j][l] / inertia[j]
                J[dhull[j], dhull[l]] = -CC[j][l] / inertia[j]
        return J

    @cached_property
    def jacobian_function(self):
        """J(x, u, p): the stiff-block Jacobian for the Rosenbrock-W solver."""
        x, _, u, p = self.symbols
        dps = self.eliminate_valves(x)
        return ca.Function("J_stiff", [x, u, p], [self.stiff_jacobian(x, p, dps)])

    def output_function_ode(self):
        x, _, u, p = self.symbols
        dps = self.eliminate_valves(x, iterations=4)
        _, _, out = self.equations(x, None, u, p, dp_override=dps)
        return ca.Function("y_ode", [x, u, p], [ca.vertcat(*[ca.vertcat(*out[k]) for k in self.OUTPUT_NAMES]),
                                                ca.vertcat(*out["hull_acc"]), ca.vertcat(*out["axle_height"])])

    def split_outputs(self, Y: np.ndarray) -> dict:
        """Rows of the first output of y() -> dict name -> (n_stations, ...) arrays."""
        Y = np.asarray(Y)
        return {k: Y[j * self.n:(j + 1) * self.n] for j, k in enumerate(self.OUTPUT_NAMES)}
