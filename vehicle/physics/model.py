"""The vehicle DAE: hull (bounce, pitch, roll) + wheel stations + struts + heat + levelling.

`VehicleModel` is equations only (PyBaMM-style): it names its states, algebraic variables,
inputs and run parameters, and builds CasADi expressions for
    dx/dt = f(x, z, u, p),   0 = g(x, z, u, p),   outputs y(x, z, u, p).
Solvers (`vehicle.numerics.solvers`) decide how to integrate it; `vehicle.engines.full` ties it to a road and a
speed profile.

States (per station i, stations axle-major, left first):
  hull:     z, theta, phi [m, rad], and their rates
  station:  w_i (wheel vertical displacement from the charged pose, + up), dw_i,
            T_oil_i, T_wall_i, T_surface_i (the strut's heat network, vehicle.physics.thermal),
            strut internal states (e.g. T_gas_i, the gas node),
            xf_i (filtered deflection, compensation), V_oil_i (oil added by compensation)
  energy quadratures per station [J]: valve, friction, gas heat, end stop, strut work,
            tyre work, road work; the ride quadratures; last V_pump_i (oil the levelling moved, m^3)
Algebraic: dp_valve_i [Pa] (valve flow balance, incompressible oil: seed 000 eq. 2).
Inputs u (time-varying), in this order (`INPUTS`; `input_index` gives the positions and
  `input_matrix` builds U from named rows: nothing else hard-codes them):
  road           road height r_i [m] under each tyre (n; the enveloped road at the wheel's own
                 distance, pass surface of its axle)
  road_rate      its rate dr_i [m/s] (n)
  speed          vehicle speed V [m/s] (1)
  ambient        ambient temperature [K] (1)
  acceleration   longitudinal acceleration a_x [m/s^2] of the speed profile, + forward (1): drive and
                 brake forces at the tyres, the hull's pitch moment (load transfer), the linkage's
                 anti-pitch forces (vehicle.physics.hull)
Parameters p (constant during a run): the run parameters (gas mass per strut [kg], nominal
  deflection per strut [m], compensation on/off) followed by the parameter vector theta: every
  non-zero number of the vehicle and strut files (`hpsim.parameters`), so a sweep, a calibration
  or a notebook that changes a number reuses one compiled model; only a change of structure
  (number of axles, strut type, gas model, a mechanism switched on or off) builds a new one.
  `model.parameters.names` lists theta; `model.structure` fingerprints the structure.

The equations are built on a symbolic copy of the parameters (`self.sym`); the numeric
parameters and kinematics (`self.params`, `self.a`, `self.struts`, ...) serve statics, checks
and everything else evaluated in Python.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from types import SimpleNamespace
from functools import cached_property

import casadi as ca
import numpy as np

from hpsim.parameters import ParameterVector, symbolic_copy
from struts.model import StrutInputs, make_strut
from struts.params import load_strut

from vehicle.physics import compensation as comp
from vehicle.physics import hull as hull_eq
from vehicle.physics import ride
from vehicle.physics import strut_kernel
from vehicle.physics import thermal
from vehicle.physics.params import GRAVITY, VehicleParams
from vehicle.physics.tyre import tyre_force

# longitudinal_work: the work of the longitudinal acceleration's loads on the hull and wheels, i.e. the
# pitch moment m h a_x (hull.longitudinal_pitch_moment) times the pitch rate, shared equally by the
# stations, plus the anti-pitch linkage forces V_i times the hull-wheel velocity at station i; with it
# the mechanical balance reads road_work + longitudinal_work = d(kinetic + potential) + tyre_work +
# strut_work (0 at constant speed; tests/test_vehicle_drive.py)
ENERGY_TERMS = ("valve", "friction", "gas", "end_stop", "strut_work", "tyre_work", "road_work", "longitudinal_work")
DISSIPATION_TERMS = ("valve", "friction", "gas", "end_stop")
HULL_ACCELERATIONS = ("heave_acc", "pitch_acc", "roll_acc")
# time-varying inputs in the order of u: (name, per station?) (see the module doc)
INPUTS = (("road", True), ("road_rate", True), ("speed", False), ("ambient", False), ("acceleration", False))
# ride and road-holding quadratures per station (vehicle.physics.ride): int F dt, int F^2 dt of the tyre
# load, time with the tyre lifted off, time on an end stop; then the time above each inner travel-bin
# edge (TRAVEL_BINS bins of equal width over the stroke, the outer ones open: `travel_histogram`)
STATION_QUADRATURES = ("F", "F2", "lift", "stop")
TRAVEL_BINS = 20


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
    def __init__(self, params: VehicleParams, ride_metrics: bool = True):
        self.params = params
        # ride metrics: ISO 2631-1 filters at the seats and road-holding quadratures (a structural switch)
        self.ride_metrics = bool(ride_metrics)
        self.seat_filters = ride.SeatFilters.default()
        self.seat_names = [st.name for st in params.seats] if self.ride_metrics else []
        self.n = params.n_stations
        self.station_names = params.station_names()
        # one strut model per distinct (file, overrides): (index, parameters, model)
        axles = [params.axles[params.station_axle(i)] for i in range(self.n)]
        keys = [(axle.strut, repr(sorted(axle.strut_overrides.items()))) for axle in axles]
        distinct: dict = {}
        for key, axle in zip(keys, axles):
            if key not in distinct:
                sp = load_strut(axle.strut, axle.strut_overrides or None)
                distinct[key] = (len(distinct), sp, make_strut(sp))
        station_struts = [distinct[key] for key in keys]
        self.struts = [model for _, _, model in station_struts]
        K = self._kinematics(params)
        self.a, self.y, self.r, self.m_u = (np.asarray(v, float) for v in (K.a, K.y, K.r, K.m_u))
        self.a_cg, self.y_cg, self.M, self.x_charged = K.a_cg, K.y_cg, K.M, K.x_charged
        self.charged_wheel_loads = np.asarray(K.charged_wheel_loads, float)
        # tyre deflection at the charged state carries the charged wheel load
        self.tyre_static_deflection = np.asarray(K.tyre_static_deflection, float)
        # per-station tyres (the axle's override of the vehicle tyre) and the longitudinal load transfer
        self.tyre = K.tyre
        self.pitch_per_acceleration = float(K.pitch_per_acceleration)
        self.link_drive, self.link_brake = (np.asarray(v, float) for v in (K.link_drive, K.link_brake))
        # the symbolic twin: the same parameters as CasADi symbols (theta), for the compiled equations
        self.parameters = ParameterVector()
        sym_params = symbolic_copy(params, self.parameters, "vehicle")
        sym_struts = {k: make_strut(symbolic_copy(sp, self.parameters, f"strut{k}"), check=False)
                      for k, sp, _ in distinct.values()}
        self.sym = self._kinematics(sym_params)
        self.sym.struts = [sym_struts[k] for k, _, _ in station_struts]
        self._build_layout()

    def state_at_rest(self, eq, gas_masses_kg) -> np.ndarray:
        """Full state vector of the vehicle standing in equilibrium `eq` (vehicle.physics.equilibrium.Equilibrium):
        hull and wheels, strut temperatures, filtered deflections and the struts' internal states at rest."""
        x = np.zeros(self.nx)
        x[self.idx("z")], x[self.idx("theta")], x[self.idx("phi")] = eq.heave_m, eq.pitch_rad, eq.roll_rad
        for i in range(self.n):
            x[self.idx(f"w[{i}]")] = eq.wheel_displacement_m[i]
            for node in thermal.NODES:
                x[self.idx(f"T_{node}[{i}]")] = eq.temperatures_K[i]
            x[self.idx(f"xf[{i}]")] = eq.strut_deflections_m[i]
            for nm, v in self.struts[i].initial_states(eq.temperatures_K[i], x=eq.strut_deflections_m[i],
                                                       m_gas=gas_masses_kg[i]).items():
                x[self.idx(f"{nm}[{i}]")] = v
        return x

    @staticmethod
    def _kinematics(P) -> SimpleNamespace:
        """Station positions, motion ratios, masses and the charged state from parameters P (numeric or symbolic)."""
        n = P.n_stations
        axle = [P.axles[P.station_axle(i)] for i in range(n)]
        loads = [w for w in P.charging.wheel_loads for _ in (0, 1)]
        tyre = [P.axle_tyre(P.station_axle(i)) for i in range(n)]       # per-axle tyres (axles[k].tyre)
        a = [ax.position for ax in axle]
        m_u = [ax.unsprung_mass for ax in axle]
        static_defl = [w / t.stiffness for w, t in zip(loads, tyre)]
        # longitudinal acceleration (hull.py): pitch moment per unit acceleration m_total h_total [kg m],
        # the wheel centres at radius - static deflection, and the anti-pitch linkage per station
        M = P.sprung_mass()
        pitch_per_acc = hull_eq.longitudinal_pitch_moment(1.0, M, P.hull.cg_height, m_u,
                                                          [t.radius - d for t, d in zip(tyre, static_defl)])
        shares = {w: [s * 0.5 for s in P.axle_shares(w) for _ in (0, 1)] for w in ("drive", "brake")}
        L = P.longitudinal
        return SimpleNamespace(
            params=P, a=a, y=[P.station_y(i) for i in range(n)],
            r=[ax.motion_ratio for ax in axle], m_u=m_u,
            a_cg=P.sprung_cg_x(), y_cg=P.hull.cg_y, M=M, x_charged=P.charging.strut_deflection,
            charged_wheel_loads=loads, tyre_static_deflection=static_defl, tyre=tyre,
            pitch_per_acceleration=pitch_per_acc,
            link_drive=hull_eq.linkage_coefficients(shares["drive"], a, L.anti_squat),
            link_brake=hull_eq.linkage_coefficients(shares["brake"], a, L.anti_dive))

    @property
    def structure(self) -> str:
        """Fingerprint of the model's structure (a compiled model serves every model with the same one)."""
        return f"s{self.n}_{self.parameters.structure}" + ("" if self.ride_metrics else "_noride")

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
            for node in thermal.NODES:        # the heat network: slow (tau >= seconds, thermal.py)
                L.add(f"T_{node}[{i}]")
            L.add(f"xf[{i}]")
            L.add(f"V_oil[{i}]")
        self.n_dynamic = len(L)
        for i in range(self.n):
            for e in ENERGY_TERMS:
                L.add(f"E_{e}[{i}]")
        # integrals of squares for RMS statistics: strut velocity per station, hull accelerations
        for i in range(self.n):
            L.add(f"I_v2[{i}]")
        for nm in HULL_ACCELERATIONS:
            L.add(f"I_{nm}2")
        if self.ride_metrics:
            # explicit (slow) block: the seat filters' poles are at |lambda h| <= 0.32 for h = 4 ms without
            # the 100 Hz band limit (ride.SeatFilters), inside the explicit trapezoid's stability region
            for seat in self.seat_names:
                for nm in self.seat_filters.velocity_state_names(seat):
                    L.add(nm)
                for q in ride.SeatFilters.QUADRATURES:
                    L.add(f"I_{q}_{seat}")
            for i in range(self.n):
                for q in STATION_QUADRATURES:
                    L.add(f"I_{q}[{i}]")
                for k in range(1, TRAVEL_BINS):
                    L.add(f"I_above{k}[{i}]")
        for i in range(self.n):     # last, so the others keep their places: the oil the levelling moved, int |q| dt
            L.add(f"V_pump[{i}]")
        self.layout = L
        self.nx = len(L)
        self.nz = sum(len(st.algebraic_names) for st in self.struts)
        self.nu = sum(self.n if per_station else 1 for _, per_station in INPUTS)
        self.n_run = 2 * self.n + 1          # run parameters ahead of theta in p
        self.np = self.n_run + len(self.parameters)

    @cached_property
    def input_index(self) -> dict:
        """Positions of the inputs in u: name -> slice (per-station inputs) or int (see INPUTS)."""
        out, k = {}, 0
        for name, per_station in INPUTS:
            if per_station:
                out[name] = slice(k, k + self.n)
                k += self.n
            else:
                out[name] = k
                k += 1
        return out

    def input_matrix(self, n_columns: int, **rows) -> np.ndarray:
        """U (nu, n_columns) from named input rows (INPUTS; an omitted input is 0): scalars, (n_columns,)
        rows, or (n, n_columns) blocks for the per-station inputs."""
        unknown = set(rows) - set(self.input_index)
        if unknown:
            raise KeyError(f"unknown model inputs {sorted(unknown)}; the model's inputs: {list(self.input_index)}")
        U = np.zeros((self.nu, n_columns))
        for name, value in rows.items():
            U[self.input_index[name]] = value
        return U

    def station_motion(self, X, i: int, K=None):
        """(strut deflection [m], strut velocity [m/s]) of station i from named states X.

        The wheel's motion relative to the hull point above it, through the motion ratio
        (hull.py). K: kinematics (default the numeric ones; `self.sym` in the equations).
        """
        K = K or self
        zs = hull_eq.station_displacement(X["z"], X["theta"], X["phi"], K.a[i], K.y[i], K.a_cg, K.y_cg)
        dzs = hull_eq.station_displacement(X["dz"], X["dtheta"], X["dphi"], K.a[i], K.y[i], K.a_cg, K.y_cg)
        return (hull_eq.strut_deflection(K.x_charged, K.r[i], X[f"w[{i}]"], zs),
                K.r[i] * (X[f"dw[{i}]"] - dzs))

    def strut_deflections(self, X) -> np.ndarray:
        """Strut deflections [m] from state vectors X (nx, ...) -> (n_stations, ...): `station_motion`'s deflection
        of every station in one array operation (the same operations per element, the same values)."""
        X = np.asarray(X)
        iz, it, ip, iw = self._deflection_rows
        column = (self.n,) + (1,) * (X.ndim - 1)
        zs = hull_eq.station_displacement(X[iz], X[it], X[ip], self.a.reshape(column), self.y.reshape(column),
                                          self.a_cg, self.y_cg)
        return hull_eq.strut_deflection(self.x_charged, self.r.reshape(column), X[iw], zs)

    @cached_property
    def _deflection_rows(self) -> tuple:
        """State rows of the hull's heave, pitch and roll and of every wheel's travel (`strut_deflections`)."""
        idx = self.layout.index
        return idx("z"), idx("theta"), idx("phi"), np.array([idx(f"w[{i}]") for i in range(self.n)])

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
        """p: gas masses, nominal deflections, compensation on/off, then the parameter vector theta."""
        xn = np.full(self.n, self.x_charged) if nominal_deflection_m is None else np.asarray(nominal_deflection_m, float)
        return np.concatenate([np.asarray(gas_mass_kg, float), xn, [1.0 if compensation_enabled else 0.0],
                               self.parameters.numeric()])

    # --- equations -------------------------------------------------------------------------------
    def equations(self, x, z, u, p, dp_override=None, strut_parts=None):
        """Symbolic rates, residuals and outputs.

        p must be the model's parameter symbol (`self.symbols[3]`, or a vector whose tail is
        theta's symbols): the parameters enter through the symbolic twin `self.sym`.
        dp_override: if given (list per station), the valve pressure drops are taken from it
        instead of the algebraic variables z (used when a solver eliminates z by Newton).
        strut_parts: if given (list per station of (strut equations, node rates), `strut_kernel.parts_from_outputs`),
        the stations' strut parts are taken from it instead of computed (the split step's rest).
        """
        K = self.sym
        P = K.params
        n = self.n
        X = {nm: x[k] for k, nm in enumerate(self.layout.names)}
        iu = self.input_index
        road = [u[k] for k in range(iu["road"].start, iu["road"].stop)]
        droad = [u[k] for k in range(iu["road_rate"].start, iu["road_rate"].stop)]
        speed = u[iu["speed"]]
        T_amb = u[iu["ambient"]]
        acc = u[iu["acceleration"]]
        # anti-pitch linkage forces on the hull at each station (hull.py; the wheel gets -V_i)
        V_link = hull_eq.linkage_forces(acc, K.pitch_per_acceleration, K.link_drive, K.link_brake)
        # p: gas masses, nominal deflections, compensation on/off (`strut_inputs`), then theta

        zc, th = X["z"], X["theta"]
        dzc, dth, dph = X["dz"], X["dtheta"], X["dphi"]

        rates = {}
        residuals = []
        out = {k: [] for k in ("strut_force", "strut_deflection", "strut_velocity", "gas_pressure", "gas_temperature",
                               "tyre_force", "wheel_load", "power_valve", "power_friction", "heat_gas",
                               "power_end_stop", "oil_flow")}
        hull_forces = []
        for i in range(n):
            strut = K.struts[i]
            w, dw = X[f"w[{i}]"], X[f"dw[{i}]"]
            T_oil, T_wall, T_surf = (X[f"T_{node}[{i}]"] for node in thermal.NODES)
            xs, vs = self.station_motion(X, i, K)
            # levelling and the strut's inputs (`strut_inputs`)
            xf = X[f"xf[{i}]"]
            sin, internal = self.strut_inputs(X, i, p, K, (xs, vs))
            q_oil = sin.dV_oil_rate
            if strut.compressible:
                dp = None
            else:
                dp = dp_override[i] if dp_override is not None else z[self._z_index[i]]
            if strut_parts is not None:
                eq, dT_nodes = strut_parts[i]
            else:
                eq, dT_nodes = strut_kernel.strut_part(K, i, sin, internal, dp, T_oil, T_wall, T_surf, T_amb, speed)
            Fs = eq["force"]
            # tyre on the enveloped road
            defl = K.tyre_static_deflection[i] + road[i] - w
            ddefl = droad[i] - dw
            Ft = tyre_force(defl, ddefl, K.tyre[i].stiffness, K.tyre[i].damping, K.tyre[i].lift_off_smoothing)
            # wheel station
            rates[f"w[{i}]"] = dw
            rates[f"dw[{i}]"] = (Ft - K.r[i] * Fs - V_link[i]) / K.m_u[i] - GRAVITY
            for nm in strut.state_names:
                rates[f"{nm}[{i}]"] = eq["rates"][nm]
            for node, dT in zip(thermal.NODES, dT_nodes):
                rates[f"T_{node}[{i}]"] = dT
            rates[f"xf[{i}]"] = comp.filtered_deflection_rate(xf, xs, P.compensation.filter_time_constant)
            rates[f"V_oil[{i}]"] = q_oil
            rates[f"V_pump[{i}]"] = comp.pumped_volume_rate(q_oil)
            rates[f"E_valve[{i}]"] = eq["power_valve"]
            rates[f"E_friction[{i}]"] = eq["power_friction"]
            rates[f"E_gas[{i}]"] = eq["heat_gas"]
            rates[f"E_end_stop[{i}]"] = eq["power_end_stop"]
            rates[f"E_strut_work[{i}]"] = Fs * vs
            rates[f"E_tyre_work[{i}]"] = Ft * ddefl
            rates[f"E_road_work[{i}]"] = Ft * droad[i]
            zs_rate = hull_eq.station_displacement(dzc, dth, dph, K.a[i], K.y[i], K.a_cg, K.y_cg)
            rates[f"E_longitudinal_work[{i}]"] = V_link[i] * (zs_rate - dw) \
                + K.pitch_per_acceleration * acc * dth / n
            rates[f"I_v2[{i}]"] = vs * vs
            if eq["residual"] is not None:
                residuals.append(eq["residual"])
            hull_forces.append(K.r[i] * Fs + V_link[i])
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
        Qz, Qt, Qp = hull_eq.generalised_forces(hull_forces, K.a, K.y, K.a_cg, K.y_cg)
        Qt = Qt + K.pitch_per_acceleration * acc          # the longitudinal pitch moment (hull.py)
        ddz, ddt, ddp = hull_eq.hull_accelerations(Qz, Qt, Qp, K.M, P.hull.pitch_inertia, P.hull.roll_inertia,
                                                   GRAVITY)
        rates.update({"z": dzc, "theta": dth, "phi": dph, "dz": ddz, "dtheta": ddt, "dphi": ddp})
        # hull accelerations about equilibrium: gravity is balanced by the static strut forces
        for nm, acc in zip(HULL_ACCELERATIONS, (ddz, ddt, ddp)):
            rates[f"I_{nm}2"] = acc * acc
        out["hull_acc"] = [ddz, ddt, ddp]
        out["axle_height"] = [hull_eq.axle_height_change(zc, th, ax.position, K.a_cg) for ax in P.axles]
        if self.ride_metrics:
            rates.update(self._ride_rates(X, (ddz, ddt, ddp), out))
        ode = [rates[nm] for nm in self.layout.names]
        return ode, residuals, out

    def _ride_rates(self, X, hull_acc, out) -> dict:
        """Rates of the ride states (vehicle.physics.ride).

        Per seat: the ISO 2631-1 Wk (vertical) and Wd (lateral) filters and the absorbed-power filter
        driven by the hull accelerations at the seat, and the quadratures of a_w^2, a_w^4, a_wl^2 and P_abs.
        Per station: int F and int F^2 of the tyre load, the time lifted off (F = 0: the tyre law is exactly
        zero there), the time on an end stop and the time above each inner travel-bin edge."""
        K = self.sym
        ddz, ddt, ddp = hull_acc
        rates = {}
        for seat, st in zip(self.seat_names, K.params.seats):
            # driven by the seat's velocities (states; ride.SeatFilters.rates_from_velocity): the same
            # kinematics as the accelerations (seat_vertical_acceleration, seat_lateral_acceleration)
            v_v = ride.seat_vertical_acceleration(X["dz"], X["dtheta"], X["dphi"], st.x_from_cg, st.y_from_cg)
            v_l = -st.z_from_cg * X["dphi"]
            names = self.seat_filters.velocity_state_names(seat)
            r, quad = self.seat_filters.rates_from_velocity([X[nm] for nm in names], v_v, v_l, GRAVITY * X["phi"])
            rates.update(zip(names, r))
            rates.update({f"I_{q}_{seat}": v for q, v in quad.items()})
        for i in range(self.n):
            F, F2, lift = ride.tyre_integrands(out["tyre_force"][i])
            xs = out["strut_deflection"][i]
            stroke = K.struts[i].p.geometry.stroke
            rates.update({f"I_F[{i}]": F, f"I_F2[{i}]": F2, f"I_lift[{i}]": lift,
                          f"I_stop[{i}]": ride.end_stop_indicator(xs, stroke)})
            above = ride.travel_exceedance_indicators(xs, [stroke * k / TRAVEL_BINS for k in range(1, TRAVEL_BINS)])
            rates.update({f"I_above{k + 1}[{i}]": v for k, v in enumerate(above)})
        return rates

    def travel_bin_edges(self) -> np.ndarray:
        """(n_stations, TRAVEL_BINS + 1) strut-travel bin edges [m]: equal bins over each strut's stroke
        (the first and last bins also take the travel beyond the end stops)."""
        return np.array([st.p.geometry.stroke * np.arange(TRAVEL_BINS + 1) / TRAVEL_BINS for st in self.struts])

    @cached_property
    def ride_index(self) -> dict:
        """Indices of the ride quadratures: per seat quadrature (n_seats,), per station quadrature (n,),
        'above' (TRAVEL_BINS - 1, n); {} without ride metrics."""
        if not self.ride_metrics:
            return {}
        out = {q: np.array([self.idx(f"I_{q}_{s}") for s in self.seat_names], dtype=int)
               for q in ride.SeatFilters.QUADRATURES}
        out.update({q: np.array([self.idx(f"I_{q}[{i}]") for i in range(self.n)]) for q in STATION_QUADRATURES})
        out["above"] = np.array([[self.idx(f"I_above{k}[{i}]") for i in range(self.n)]
                                 for k in range(1, TRAVEL_BINS)])
        return out

    # --- CasADi functions ------------------------------------------------------------------------
    @cached_property
    def symbols(self):
        p = ca.vertcat(ca.SX.sym("p_run", self.n_run), self.parameters.symbols)
        return ca.SX.sym("x", self.nx), ca.SX.sym("z", self.nz), ca.SX.sym("u", self.nu), p

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

    def station_run_parameters(self, i: int, p) -> tuple:
        """(gas mass [kg], nominal deflection [m]) of station i's strut from the run parameters p."""
        return p[i], p[self.n + i]

    def strut_inputs(self, X, i: int, p, K=None, motion=None):
        """(StrutInputs, internal states) of station i's strut from named states X and run parameters p.

        The strut sees the oil node as its T_wall: oil expansion, viscosity and the gas's
        heat-exchange partner (the floating piston, oil side). The oil's thermal expansion
        enters through the gas volume (a function of T_oil); its *rate* in the gas energy
        equation is left out (dT_wall_rate = 0): beta V_oil dT/dt ~ 1e-8 m^3/s against
        A v ~ 1e-4 m^3/s while driving, and the gas follows the oil within tau anyway.
        """
        K = K or self.sym
        P = K.params
        n = self.n
        strut = K.struts[i]
        xs, vs = motion if motion is not None else self.station_motion(X, i, K)
        q_oil = p[2 * n] * comp.oil_flow(X[f"xf[{i}]"], p[n + i], strut.p.geometry.gas_area,
                                         P.compensation.time_constant, P.compensation.dead_band,
                                         P.compensation.flow_limit, P.compensation.smoothing)
        m_gas, x_mid = self.station_run_parameters(i, p)
        sin = StrutInputs(x=xs, v=vs, T_wall=X[f"T_oil[{i}]"], m_gas=m_gas, dV_oil=X[f"V_oil[{i}]"],
                          dV_oil_rate=q_oil, dT_wall_rate=0.0, x_mid=x_mid)
        return sin, {nm: X[f"{nm}[{i}]"] for nm in strut.state_names}

    def eliminate_valves(self, x, memory, p, iterations: int = 1):
        """Valve pressure drops of struts with an algebraic one by warm-started Newton (explicit-ODE form).

        memory: the previous step's pressure drops (one per such strut, in station order), held by the
        solver between steps (`n_memory`, `initial_memory`). The flow balance is the strut's
        (`valve_demand`: the deflection rate's flow, or the integrated strut's quasi-steady balance).
        """
        X = {nm: x[k] for k, nm in enumerate(self.layout.names)}
        dps, k = [], 0
        for i in range(self.n):
            strut = self.sym.struts[i]
            if strut.compressible:
                dps.append(None)
                continue
            sin, internal = self.strut_inputs(X, i, p)
            dps.append(strut_kernel.valve_drop(strut, sin, internal, memory[k], iterations))
            k += 1
        return dps

    # base names of the slow states (minutes to hours): what the multiscale mode (vehicle.engines.multiscale)
    # advances between its windows of road; everything else in x[:n_dynamic] is fast. A model that adds
    # slow states (e.g. thermal nodes) lists their base names here.
    SLOW_STATES = tuple(f"T_{node}" for node in thermal.NODES) + ("xf", "V_oil")

    def indicator_quadrature_indices(self) -> list[int]:
        """Indices in x of the quadratures of indicator functions (time with the tyre lifted off, on an end stop,
        above each travel-bin edge: `ride.tyre_integrands`, `ride.end_stop_indicator`,
        `ride.travel_exceedance_indicators`). Their integrands jump where the motion crosses a threshold, so a
        higher-order quadrature rule gains nothing over the rectangle rule (a fixed-step solver may integrate
        them with one evaluation per step)."""
        names = ("I_lift", "I_stop", "I_above")
        return [k for k, nm in enumerate(self.layout.names) if nm.split("[")[0].rstrip("0123456789") in names]

    def slow_state_indices(self) -> list[int]:
        """Indices in x of the slow states (`SLOW_STATES`, any station)."""
        return [k for k, nm in enumerate(self.layout.names[:self.n_dynamic]) if nm.split("[")[0] in self.SLOW_STATES]

    @property
    def n_memory(self) -> int:
        """Warm-start values a fixed-step solver carries between steps (valve pressure drops)."""
        return sum(1 for st in self.struts if not st.compressible)

    def initial_memory(self) -> np.ndarray:
        return np.zeros(self.n_memory)

    @cached_property
    def memory_symbol(self):
        return ca.SX.sym("memory", self.n_memory)

    @cached_property
    def ode_function(self):
        """f(x, memory, u, p) -> (dx/dt, new memory): the explicit-ODE form (valves eliminated)."""
        x, _, u, p = self.symbols
        mem = self.memory_symbol
        dps = self.eliminate_valves(x, mem, p)
        ode, _, out = self.equations(x, None, u, p, dp_override=dps)
        new_mem = ca.vertcat(*[d for d in dps if d is not None]) if self.n_memory else ca.SX(0, 1)
        return ca.Function("f_ode", [x, mem, u, p], [ca.vertcat(*ode), new_mem])

    # --- the strut kernel (vehicle.physics.strut_kernel): the interface of the step split around the struts ---
    @property
    def has_strut_kernel(self) -> bool:
        return strut_kernel.applies(self)

    def strut_kernel(self, i: int, jacobian: bool) -> ca.Function:
        return strut_kernel.kernel(self, i, jacobian)

    def strut_kernel_names(self, i: int, jacobian: bool) -> tuple:
        """(input names, output names) of station i's strut kernel."""
        strut = self.sym.struts[i]
        return strut_kernel.input_names(strut), strut_kernel.output_names(strut, jacobian)

    def strut_kernel_inputs(self, x, memory, u, p) -> list:
        return strut_kernel.kernel_inputs(self, x, memory, u, p)

    def rates_from_strut_kernels(self, x, u, p, outputs: list[dict]):
        """dx/dt (`ode_function`'s first output) with every station's strut part read from its kernel's outputs
        (name -> value, one dict per station)."""
        parts = strut_kernel.parts_from_outputs(self, outputs)
        ode, _, _ = self.equations(x, None, u, p, dp_override=[o["dp"] for o in outputs], strut_parts=parts)
        return ca.vertcat(*ode)

    @property
    def has_stiff_strut_states(self) -> bool:
        return any(st.stiff_state_names for st in self.struts)

    @cached_property
    def _strut_derivative_functions(self) -> dict:
        """Per distinct strut: (x, v, T_wall, m_gas, dV_oil, dp, internal states...) -> (dF/dx, dF/dv) from the
        strut protocol's `force_derivatives` (theta enters as free symbols)."""
        out = {}
        for strut in self.sym.struts:
            if id(strut) in out:
                continue
            xs, vs, T, m, dV, dp = (ca.SX.sym(n) for n in ("x", "v", "T", "m", "dV", "dp"))
            internal = {nm: ca.SX.sym(nm) for nm in strut.state_names}
            k, c = strut.force_derivatives(StrutInputs(x=xs, v=vs, T_wall=T, m_gas=m, dV_oil=dV), internal,
                                           None if strut.compressible else dp)
            args = [xs, vs, T, m, dV, dp] + [internal[nm] for nm in strut.state_names]
            out[id(strut)] = (ca.vertcat(*args), ca.vertcat(k, c))
        return out

    def _strut_stiffness_damping(self, i, xs, vs, T, m_gas, dV_oil, dp, internal):
        args, kc = self._strut_derivative_functions[id(self.sym.struts[i])]
        values = ca.vertcat(xs, vs, T, m_gas, dV_oil, 0.0 if dp is None else dp, *internal)
        kc = ca.substitute(kc, args, values)
        return kc[0], kc[1]

    def stiff_jacobian(self, x, p, dps, stiffness=None):
        """Approximate Jacobian of the stiff block (stations' w, dw, stiff strut states; hull).

        Built from each station's local strut stiffness/damping and the tyre's, through the
        constant kinematics (hull.py): the structural-dynamics form of d f / d x. Exact for the
        mechanics with frozen slow states, which is all a W-method needs. stiffness: if given (per station (ks, cs)),
        the struts' stiffness and damping are taken from it (the strut kernels' outputs) instead of computed.
        """
        K = self.sym
        P = K.params
        n = self.n
        X = {nm: x[k] for k, nm in enumerate(self.layout.names)}
        ns = self.n_stiff
        J = ca.SX(ns, ns)
        hull = [self.idx(nm) for nm in ("z", "theta", "phi")]
        dhull = [self.idx(nm) for nm in ("dz", "dtheta", "dphi")]
        for a, b in zip(hull, dhull):
            J[a, b] = 1.0
        inertia = [K.M, P.hull.pitch_inertia, P.hull.roll_inertia]
        KK = [[0.0] * 3 for _ in range(3)]
        CC = [[0.0] * 3 for _ in range(3)]
        for i in range(n):
            w, dw = self.idx(f"w[{i}]"), self.idx(f"dw[{i}]")
            B = [1.0, -(K.a[i] - K.a_cg), K.y[i] - K.y_cg]   # d z_station / d (z, theta, phi)
            xs, vs = self.station_motion(X, i, K)
            ks, cs = stiffness[i] if stiffness is not None else self._strut_stiffness_damping(
                i, xs, vs, X[f"T_oil[{i}]"], p[i], X[f"V_oil[{i}]"], dps[i],
                [X[f"{nm}[{i}]"] for nm in self.struts[i].state_names])
            r2 = K.r[i] ** 2
            mu = K.m_u[i]
            kt, ct = K.tyre[i].stiffness, K.tyre[i].damping
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
        """J(x, memory, u, p): the stiff-block Jacobian for the Rosenbrock-W solver.

        Structural (hand-written from the struts' stiffness and damping through the hull
        kinematics, `stiff_jacobian`) when the struts have no stiff internal states; the exact
        CasADi Jacobian of the stiff block otherwise (an integrated strut's chamber pressures and
        gas volume are stiff states whose rows the structural form does not have).
        tests/test_vehicle_jacobian.py checks the structural form against the exact one.
        """
        x, _, u, p = self.symbols
        mem = self.memory_symbol
        if self.has_stiff_strut_states:
            return self.exact_stiff_jacobian_function
        J = self.stiff_jacobian(x, p, self.eliminate_valves(x, mem, p))
        return ca.Function("J_stiff", [x, mem, u, p], [J])

    @cached_property
    def exact_stiff_jacobian_function(self):
        """J(x, memory, u, p) by CasADi AD through the eliminated (one Newton step) valves."""
        x, _, u, p = self.symbols
        mem = self.memory_symbol
        f, _ = self.ode_function(x, mem, u, p)
        return ca.Function("J_exact", [x, mem, u, p], [ca.jacobian(f[:self.n_stiff], x[:self.n_stiff])])

    def output_function_ode(self):
        """y(x, memory, u, p) -> (outputs, hull accelerations, axle heights)."""
        x, _, u, p = self.symbols
        mem = self.memory_symbol
        dps = self.eliminate_valves(x, mem, p, iterations=4)
        _, _, out = self.equations(x, None, u, p, dp_override=dps)
        return ca.Function("y_ode", [x, mem, u, p], [ca.vertcat(*[ca.vertcat(*out[k]) for k in self.OUTPUT_NAMES]),
                                                     ca.vertcat(*out["hull_acc"]), ca.vertcat(*out["axle_height"])])

    def split_outputs(self, Y: np.ndarray) -> dict:
        """Rows of the first output of y() -> dict name -> (n_stations, ...) arrays."""
        Y = np.asarray(Y)
        return {k: Y[j * self.n:(j + 1) * self.n] for j, k in enumerate(self.OUTPUT_NAMES)}
