"""The multiscale drive's linear-model road proxy (`solver.multiscale.proxy: linear_model`): each station's squared
strut velocity of the linearised vehicle driven by the whole road, its time integral cumulated on a time grid, so
that the proxy's mean over a stretch is (C(t1) - C(t0)) / (t1 - t0). Why this proxy, and what it was measured to
give: docs/engines.md, "Control variate"."""
from __future__ import annotations

import time

import numpy as np

from vehicle.physics import linear
from vehicle.physics.model import VehicleModel
from vehicle.numerics.codegen import Library, serialized_function
from vehicle.engines.control_variate import strut_velocity_from_spectrum
from vehicle.engines.proxy_roads import PROXY_ROADS, ComputedOnce, proxy_road


# the linearisation's Jacobian function by its name (the model's structure: `linear.jacobian_name`), read from the
# compile cache once per process
JACOBIANS = ComputedOnce(4)


class LinearProxy:
    """The proxy set up in three parts, so that each runs where a core would otherwise idle (`MultiscaleDrive`:
    before and beside the first window, beside its slaving matrix, beside the windows that run alone at the end).
    They are `prepare` (what does not depend on the seal friction's velocity amplitude V: the road under each tyre on the
    proxy's time grid and its spectrum, the linearisation's Jacobians), `match` (V matched to the first window)
    and `finish` (the velocities over the whole road, their cumulative). They read the model, the road and the
    drive's time grid only, so they can run on a thread beside the windows.

    drive: the MultiscaleDrive (its model, station roads, time grid, gas masses and multiscale settings);
    inputs: its `_linear_proxy_inputs()` (the initial strut temperatures and the vehicle standing at them),
    computed on the drive's thread: they use its equilibrium solver; kept: where the road part is kept for the
    process's other drives on the same road (`proxy_roads.PROXY_ROADS`; ComputedOnce(0): computed for this one)."""

    PAD_S = 30.0                  # s of road before and after the drive: the linear vehicle's memory

    def __init__(self, drive, inputs: tuple, kept: ComputedOnce = PROXY_ROADS):
        self.drive = drive
        self.kept = kept
        self.T0, self.standing = inputs
        self.ms = drive.ms
        self.rate_hz = self.ms.LINEAR_PROXY_RATE_HZ
        self.setup_s = 0.0
        self.V = self.ms.LINEAR_PROXY_FRICTION_VELOCITY_M_S     # until `match`
        self._linearised: dict = {}          # V -> the linear vehicle (the first guess is linearised in `prepare`)

    def prepare(self) -> None:
        """The road under each tyre on the proxy's time grid and its spectrum (`proxy_roads.proxy_road`: computed
        once per process for every drive on the same road), and the linear vehicle at the first guess of V (its
        Jacobians read from the compile cache or built: `_jacobians`)."""
        t0 = time.perf_counter()
        self.road = proxy_road(self.drive, self.rate_hz, self.PAD_S, self.kept)
        self.t, self.roads, self.spectrum = self.road.t, self.road.roads, self.road.spectrum
        self.vehicles = self._equivalent_vehicles()
        self._linear(self.ms.LINEAR_PROXY_FRICTION_VELOCITY_M_S)
        self.setup_s += time.perf_counter() - t0

    def _equivalent_vehicles(self) -> linear.EquivalentLinearVehicles:
        """The linear vehicle at every V from one equivalent-friction model (`linear.EquivalentLinearVehicles`). Its
        Jacobians (`linear.jacobian_graph`: one function for every V, the friction enters as a parameter value) are
        kept in the compile cache (`serialized_function`) rather than built from the model's equations in every
        run, and read once per process and model structure (`JACOBIANS`)."""
        d = self.drive
        model = VehicleModel(linear.equivalent_friction_params(d.model.params,
                                                               self.ms.LINEAR_PROXY_FRICTION_VELOCITY_M_S))
        name = linear.jacobian_name(model)
        jacobians = JACOBIANS.get(name, lambda: serialized_function(Library(
            name, ("linear_jacobians", model.structure, linear.LINEARISED_OUTPUTS),
            lambda: linear.jacobian_graph(model))))
        return linear.EquivalentLinearVehicles(model, self.T0, d.gas_masses, self.standing, jacobians)

    def _linear(self, V: float):
        lin = self._linearised.get(V)
        if lin is None:
            lin = self._linearised[V] = self.vehicles.at(V)
        return lin

    def _velocities(self, V: float, spectrum: tuple) -> np.ndarray:
        lin = self._linear(V)
        return strut_velocity_from_spectrum(lambda f: linear.strut_velocity_response(lin, f), spectrum, self.rate_hz,
                                            self.ms.LINEAR_PROXY_FREQUENCIES)

    def matched_velocity(self, match) -> float:
        """V such that the linear vehicle's RMS strut velocity (mean square over the stations) over [t_a, t_b]
        equals `rms`, match = (t_a, t_b, rms), the full model's over the same stretch (the first window): the
        equivalent linearisation that reproduces the response's variance (Roberts & Spanos, Random Vibration and
        Statistical Linearization, 1990, ch. 5). The linear vehicle's damping stands for the seal friction and the
        valves' non-linear (orifice, blow-off) damping together, which the laminar-bleed linearisation alone does
        not give. Two secant steps in log V from LINEAR_PROXY_FRICTION_VELOCITY_M_S (RMS ~ V^alpha); V kept within
        LINEAR_PROXY_V_RANGE_M_S. match=None: V = LINEAR_PROXY_FRICTION_VELOCITY_M_S."""
        ms, rate, pad = self.ms, self.rate_hz, self.PAD_S
        V = ms.LINEAR_PROXY_FRICTION_VELOCITY_M_S
        if match is None:
            return V
        t_a, t_b, target = match
        sl = slice(max(int((t_a + pad) * rate) - int(pad * rate), 0), int((t_b + pad) * rate) + int(pad * rate))
        inside = (self.t[sl] >= t_a) & (self.t[sl] <= t_b)
        stretch = self.road.stretch_spectrum(sl.start, sl.stop)

        def rms(Vx):
            return float(np.sqrt(np.mean(self._velocities(Vx, stretch)[:, inside] ** 2)))
        lo, hi = ms.LINEAR_PROXY_V_RANGE_M_S
        alpha = 0.5                           # first guess: RMS ~ V^0.5 (friction-dominated damping ~ 1/V)
        r = rms(V)
        for _ in range(2):
            V_new = float(np.clip(V * (target / r) ** (1.0 / alpha), lo, hi))
            if abs(np.log(V_new / V)) < 1e-3:
                break
            r_new = rms(V_new)
            if r_new != r:
                alpha = float(np.clip(np.log(r_new / r) / np.log(V_new / V), 0.05, 2.0))
            V, r = V_new, r_new
        return float(np.clip(V * (target / r) ** (1.0 / alpha), lo, hi))

    def match(self, match=None) -> float:
        """Set V to `matched_velocity(match)`; returns it."""
        t0 = time.perf_counter()
        self.V = self.matched_velocity(match)
        self.setup_s += time.perf_counter() - t0
        return self.V

    def finish(self) -> tuple:
        """(t, C, V): the time grid [s], each station's cumulative squared strut velocity C (n, len(t)) [m^2/s] of
        the linear vehicle at the friction velocity amplitude V [m/s] that `match` set, driven by the whole road
        (trapezoid rule)."""
        t0 = time.perf_counter()
        v2 = np.square(self._velocities(self.V, self.spectrum))
        c = np.empty(v2.shape)                # in place from here: these arrays are the size of the whole road
        c[:, 0] = 0.0
        np.add(v2[:, 1:], v2[:, :-1], out=c[:, 1:])
        c[:, 1:] *= 0.5
        np.cumsum(c[:, 1:], axis=1, out=c[:, 1:])
        c[:, 1:] /= self.rate_hz
        self.setup_s += time.perf_counter() - t0
        return self.t, c, self.V
