"""The vehicle on its road: what every engine integrates, before any solver is chosen.

The road each tyre reads (enveloped by its contact length, one envelope per distinct length), the struts'
charge (gas masses) and the equilibrium solver of the standing vehicle, the run-time parameter vector, the
drive's distance <-> time map, where it ends (`DriveEnd`), and the input matrix u(t) the model reads at any
times. A part of every engine (docs/CONTRIBUTING.md): it holds no solver and no results.
"""
from __future__ import annotations

from functools import cached_property

import numpy as np

from vehicle.physics.equilibrium import charge_gas_masses, equilibrium_solver
from vehicle.physics.model import VehicleModel
from vehicle.scenario.settings import DriveSettings
from vehicle.engines.contract import DriveState
from vehicle.engines.drive_end import DriveEnd
from vehicle.engines.state_index import StateIndex


class VehicleOnRoad:
    """`model` charged (gas_masses, default: as the vehicle file charges it) on `road` driven with `settings`.

    Attributes a caller reads: model, settings, station_roads (the surface each station's tyre reads),
    gas_masses [kg], equilibrium_solver, p (the run-time parameters), s_grid/t_grid (distance [m] -> time [s]),
    total_time_s (when the distance map reaches the drive's distance), index (`StateIndex`).
    """

    def __init__(self, model: VehicleModel, road, settings: DriveSettings, gas_masses=None):
        self.model, self.settings = model, settings
        envelopes: dict = {}
        self.station_roads = []
        for i in range(model.n):
            L = float(model.tyre[i].contact_length)
            if L not in envelopes:
                envelopes[L] = road.enveloped(L) if L > 0 else road
            self.station_roads.append(envelopes[L])
        for surface in {id(r): r for r in self.station_roads}.values():    # the splines of what the tyres read
            surface.prepare(sorted({model.params.station_axle(i) for i in range(model.n)
                                    if self.station_roads[i] is surface}))
        self.gas_masses = charge_gas_masses(model) if gas_masses is None else np.asarray(gas_masses, float)
        self.equilibrium_solver = equilibrium_solver(model)
        self.p = model.run_parameters(self.gas_masses, settings.compensation)
        self.s_grid, self.t_grid = settings.speed.time_grid(settings.distance_m + 1.0)
        self.total_time_s = float(np.interp(settings.distance_m, self.s_grid, self.t_grid))
        self.index = StateIndex.of(model)

    def end(self, steps_per_sample: int) -> DriveEnd:
        """Where the drive ends on a solver of settings.dt_s with `steps_per_sample` steps per output sample."""
        return DriveEnd.of(self.settings.distance_m, self.total_time_s, self.settings.dt_s, steps_per_sample)

    def distance_at(self, t):
        """The drive's distance [m] at time(s) t [s]."""
        return np.interp(t, self.t_grid, self.s_grid)

    def time_at(self, s_m: float) -> float:
        """The drive's time [s] at distance s_m [m]."""
        return float(np.interp(s_m, self.s_grid, self.t_grid))

    def initial_equilibrium(self):
        """The standing vehicle at the drive's initial temperatures (vehicle.physics.equilibrium.Equilibrium)."""
        T0 = np.broadcast_to(np.asarray(self.settings.initial_temperatures_K, float), (self.model.n,))
        return self.equilibrium_solver.solve(T0, self.gas_masses)

    def initial_state(self, solver_memory: np.ndarray) -> DriveState:
        """The drive's start: the vehicle standing at its initial temperatures, the first statistics interval open,
        the solver's memory as given (zeros of its size)."""
        x = self.model.state_at_rest(self.initial_equilibrium(), self.gas_masses)
        return DriveState(t_s=0.0, s_m=0.0, x=x, next_stats_m=self.settings.stats_interval_m,
                          last_stats={"t_s": 0.0, "q": x[self.index.quad_index].copy(),
                                      "gas_sum": np.zeros(self.model.n), "gas_n": 0},
                          solver_memory=solver_memory)

    @cached_property
    def _input_groups(self) -> list[tuple]:
        """The stations grouped by the surface their tyre reads: (enveloped road, track, pass, station indices,
        their distances behind the first axle [m])."""
        m, P = self.model, self.model.params
        groups: dict = {}
        for i in range(m.n):
            track = "left" if i % 2 == 0 else "right"
            surface, k = self.station_roads[i], P.station_axle(i)
            key = (id(surface), track, id(surface.heights(track, k)))
            groups.setdefault(key, (surface, track, k, []))[3].append(i)
        return [(surface, track, k, np.array(st), np.array([float(m.a[i]) for i in st]))
                for surface, track, k, st in groups.values()]

    def inputs(self, t: np.ndarray) -> np.ndarray:
        """Input matrix (nu, len(t)) by name (`VehicleModel.input_matrix`): road height and rate under each
        tyre (axle k reads pass k of the ground, terrain.passes: the wheels ahead of it have rolled over it),
        speed, ambient, the speed profile's longitudinal acceleration a = v dv/ds (0 at constant speed)."""
        m = self.model
        s = self.distance_at(t)
        v = self.settings.speed.speed(s)
        road, rate = np.empty((m.n, len(t))), np.empty((m.n, len(t)))
        for surface, track, pass_index, stations, offsets in self._input_groups:
            # the stations on one surface in one call (elementwise: the same values as one call per station)
            road[stations], slope = surface.evaluate(s[None, :] - offsets[:, None], track, pass_index=pass_index)
            rate[stations] = slope * v
        return m.input_matrix(len(t), road=road, road_rate=rate, speed=v, ambient=self.settings.ambient_K,
                              acceleration=self.settings.speed.acceleration(s))
