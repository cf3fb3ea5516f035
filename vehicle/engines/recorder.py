"""The block recorder: what an engine does with each block of samples it integrated, whatever integrated it.

It checks the samples against physics (non-finite states, struts beyond their end stops, temperatures outside
any physical range: a SimulationError naming the strut and what to change). It evaluates the output table's time
series at them, cuts the statistics intervals they end (closing the last at the drive's distance when the block
ends the drive), makes the statistics rows, and hands all of it to the observer, the sink (samples, rows,
checkpoints) and the progress callback. Used by the full drive's blocks and its end, the multiscale windows, the
time-parallel segments and the ensemble's lanes (docs/CONTRIBUTING.md).
"""
from __future__ import annotations

from dataclasses import fields
from functools import cached_property

import numpy as np

from hpsim.errors import SimulationError

from vehicle.physics import ride, thermal
from vehicle.physics.model import DISSIPATION_TERMS, ENERGY_TERMS, HULL_ACCELERATIONS
from vehicle.engines.contract import DriveState
from vehicle.engines.state_index import StateIndex
from vehicle.engines.vehicle_on_road import VehicleOnRoad


class BlockRecorder:
    """Records blocks of the drive of `vehicle` (a `VehicleOnRoad`) ending at `end_m` [m].

    samples_per_call  the samples of a full block (M): the compiled block outputs' width
    compiled_outputs  the compiled block outputs (vehicle.numerics.solvers.compiled_outputs), or None: CasADi's
                      virtual machine (`outputs`)
    The state indices of `StateIndex` are attributes of the recorder (quad_index, T_index, ...).
    """

    def __init__(self, vehicle: VehicleOnRoad, end_m: float, samples_per_call: int, compiled_outputs=None):
        self.vehicle = vehicle
        self.model, self.settings, self.p = vehicle.model, vehicle.settings, vehicle.p
        self.end_m = float(end_m)
        self.M = int(samples_per_call)
        self.compiled_outputs = compiled_outputs
        for f in fields(StateIndex):
            setattr(self, f.name, getattr(vehicle.index, f.name))
        self.travel_bin_edges_m = self.model.travel_bin_edges()

    @cached_property
    def outputs(self):
        """The model's outputs y(x, memory, u, p) in CasADi's virtual machine (`VehicleModel.output_function_ode`):
        for blocks the compiled block outputs do not serve. Built on first use: a drive whose libraries are in the
        compile cache builds no graph it does not evaluate."""
        return self.model.output_function_ode()

    @cached_property
    def _strokes_m(self) -> np.ndarray:
        """Each station's strut stroke [m] as a column (n, 1) (`check`)."""
        return np.array([st.p.geometry.stroke for st in self.model.struts])[:, None]

    def record(self, st: DriveState, X, U, t, s, memory, sink, observer, progress, *, ends: bool,
               checkpoint: bool) -> DriveState:
        """One block's samples checked elsewhere, recorded here: its outputs and the statistics intervals it ends
        (the last closed at the drive's distance when the block `ends` the drive) to the observer and the sink,
        a checkpoint (every few blocks and at the end), progress. Returns the drive state after the block."""
        block = self.block_outputs(X, U, t, s, memory)
        intervals = self.stats_intervals(st, X, t, s, ends=ends)
        if observer is not None:
            observer.block(X, U, memory, block)
            observer.intervals(intervals)
        st = DriveState(t_s=float(t[-1]), s_m=float(s[-1]), x=X[:, -1].copy(), next_stats_m=st.next_stats_m,
                        last_stats=st.last_stats, sample_index=st.sample_index + X.shape[1],
                        solver_memory=memory[:, -1].copy())
        if sink is not None:
            sink.samples(block)
            rows = [self.stats_row(*interval) for interval in intervals]
            if rows:
                sink.stats(rows)
            if checkpoint:
                sink.checkpoint(st.as_dict())
        if progress is not None:
            progress(st.s_m, float(self.settings.speed.speed(st.s_m)), st.t_s)
        return st

    # a state this far outside physics means the integration has failed, whatever the solver says
    PHYSICAL_TEMPERATURE_K = (150.0, 273.15 + 400.0)
    STROKE_MARGIN_M = 0.02

    def _advice(self) -> str:
        S = self.settings
        v_max = float(np.max(S.speed.speeds_m_per_s)) * 3.6
        return (f"scenario extremes: speed up to {v_max:.4g} km/h, solver.dt {S.dt_s * 1e3:.4g} ms; "
                f"try a smaller solver.dt (e.g. {S.dt_s * 500:.3g} ms) or a lower speed / smoother road")

    def check(self, X, t, s, x_before=None):
        """Stop with a SimulationError naming the strut, the state and what to change when the solution
        is non-finite or outside physical bounds (deflection beyond the end stops, temperatures)."""
        m = self.model
        finite = np.isfinite(X)
        if not np.all(finite):
            col = int(np.argmax(~np.all(finite, axis=0)))
            bad = [m.layout.names[k] for k in np.flatnonzero(~finite[:, col])]
            first = bad[0]
            station = None
            if "[" in first:
                k = int(first[first.index("[") + 1:-1])
                station = m.station_names[k] if k < m.n else None
            where = f"strut {station}, state {first.split('[')[0]}" if station else f"state {first}"
            last = ""
            if station is not None:
                prev = X[:, col - 1] if col > 0 else x_before
                if prev is not None and np.all(np.isfinite(prev)):
                    k = m.station_names.index(station)
                    x_def = float(m.strut_deflections(prev[:, None])[k, 0])
                    last = (f"; last finite sample: deflection {x_def * 1e3:.1f} mm, strut temperature "
                            f"{prev[m.idx(f'T_surface[{k}]')] - 273.15:.1f} degC (surface), "
                            f"{prev[m.idx(f'T_oil[{k}]')] - 273.15:.1f} degC (oil)")
            raise SimulationError(
                f"the solution became non-finite at {s[col] / 1e3:.3f} km (t = {t[col]:.1f} s), first in {where} "
                f"({len(bad)} states non-finite){last}; {self._advice()}")
        deflections = m.strut_deflections(X)
        strokes = self._strokes_m
        outside = (deflections < -self.STROKE_MARGIN_M) | (deflections > strokes + self.STROKE_MARGIN_M)
        if np.any(outside):                  # the first station out of its stroke, at its first such sample
            i = int(np.argmax(np.any(outside, axis=1)))
            stroke, xs, col = float(strokes[i, 0]), deflections[i], int(np.argmax(outside[i]))
            where = "bottomed out (beyond the bump stop)" if xs[col] > stroke else "over-extended (beyond the rebound stop)"
            raise SimulationError(
                f"strut {m.station_names[i]} {where} at {s[col] / 1e3:.3f} km (t = {t[col]:.1f} s): deflection "
                f"{xs[col] * 1e3:.1f} mm, stroke 0-{stroke * 1e3:.0f} mm, strut temperature "
                f"{X[m.idx(f'T_oil[{i}]'), col] - 273.15:.1f} degC (oil); {self._advice()}")
        T = X[self.heat_nodes_index]
        lo, hi = self.PHYSICAL_TEMPERATURE_K
        bad = (T < lo) | (T > hi)
        if np.any(bad):
            k, col = (int(v[0]) for v in np.nonzero(bad))
            i, node = k % m.n, thermal.NODES[k // m.n]
            raise SimulationError(
                f"strut {m.station_names[i]} {node} temperature {T[i, col] - 273.15:.1f} degC at {s[col] / 1e3:.3f} km "
                f"(t = {t[col]:.1f} s) is outside any physical range ({lo - 273.15:.0f} to {hi - 273.15:.0f} degC): "
                f"the heat balance has failed; {self._advice()}")

    def block_outputs(self, X, U, t, s, memory) -> dict:
        """Every time series of the output table (vehicle.physics.outputs) at a block's samples."""
        m = self.model
        n = X.shape[1]
        if self.compiled_outputs is not None and n <= self.M:
            # fewer samples than a block (the first, a window's or the drive's last): the compiled block outputs on
            # the samples padded with copies of the last (each column is evaluated on its own), the padding dropped
            pad = np.full(self.M, n - 1)
            pad[:n] = np.arange(n)
            Y, acc, heights = (np.asarray(v)[:, :n] for v in self.compiled_outputs(
                X[:, pad], np.broadcast_to(memory, (m.n_memory, n))[:, pad], U[:, pad], self.p))
        else:
            Y, acc, heights = self.outputs.map(n)(X, np.broadcast_to(memory, (m.n_memory, n)), U,
                                                  np.repeat(self.p[:, None], n, axis=1))
        outs = m.split_outputs(np.asarray(Y))
        block = {}
        for key, f in self.series.items():
            rows = self.series_rows.get(key)
            if rows is not None:
                block[key] = X[rows]
            elif f.kind == "time":
                block[key] = t
            elif f.kind == "distance":
                block[key] = s
            elif f.kind == "input":
                block[key] = U[m.input_index[f.name]]
            elif f.kind == "output":
                block[key] = outs[f.name]
            elif f.kind == "axle_heights":
                block[key] = np.asarray(heights)
            elif f.kind == "hull_accelerations":
                block[key] = np.asarray(acc)
            else:
                raise ValueError(f"output table: {key!r} has an unknown series kind {f.kind!r}")
        return block

    def stats_intervals(self, st: DriveState, X, t, s, ends: bool = False) -> list[tuple]:
        """Every statistics interval ended in this block, as the arguments of `stats_row` (distance at the end,
        duration, quadrature differences, state at the end, interval mean gas temperature). A block that `ends`
        the drive closes its last interval at the drive's distance: interpolated to it
        when the end sample passes a boundary there, else at the end sample (within half a step of it). No
        boundary beyond the drive's distance is cut. Advances st.next_stats_m and st.last_stats."""
        rows = []
        q = X[self.quad_index]
        T = X
        end_m = self.end_m
        t_last, q_last = st.last_stats["t_s"], st.last_stats["q"]
        s0, t0, q0, T0 = st.s_m, st.t_s, st.x[self.quad_index], st.x
        # the gas temperature swings by kelvins with every bump: its interval mean over the output samples
        Tg = X[self.T_gas_index]
        g_sum = np.broadcast_to(np.asarray(st.last_stats.get("gas_sum", 0.0), float), (self.model.n,)).copy()
        g_n = int(st.last_stats.get("gas_n", 0))
        closed_at_end = False
        for j in range(len(t)):
            g_sum += Tg[:, j]
            g_n += 1
            while s[j] >= st.next_stats_m - 1e-9 and st.next_stats_m <= end_m:
                # the quadratures are smooth and monotone: interpolate them to the boundary
                a = (st.next_stats_m - s0) / (s[j] - s0) if s[j] > s0 else 1.0
                tb, qb, Tb = t0 + a * (t[j] - t0), q0 + a * (q[:, j] - q0), T0 + a * (T[:, j] - T0)
                rows.append((st.next_stats_m, tb - t_last, qb - q_last, Tb, g_sum / g_n if g_n else Tg[:, j]))
                closed_at_end = st.next_stats_m == end_m
                t_last, q_last = tb, qb
                g_sum, g_n = np.zeros(self.model.n), 0
                st.next_stats_m += self.settings.stats_interval_m
            s0, t0, q0, T0 = s[j], t[j], q[:, j], T[:, j]
        if ends and not closed_at_end and t[-1] > t_last:
            rows.append((end_m, t[-1] - t_last, q[:, -1] - q_last, T[:, -1], g_sum / g_n if g_n else Tg[:, -1]))
            t_last, q_last = t[-1], q[:, -1]
            g_sum, g_n = np.zeros(self.model.n), 0
        st.last_stats = {"t_s": t_last, "q": q_last, "gas_sum": g_sum, "gas_n": g_n}
        return rows

    def stats_row(self, s_end, duration, dq, x_end, gas_mean=None) -> dict:
        """One statistics row; x_end: the state at the interval's end (its temperatures are reported);
        gas_mean: the interval mean of the gas temperature (default its value at the end)."""
        n = self.model.n
        nE = len(ENERGY_TERMS)
        E = dq[: nE * n].reshape(nE, n)
        row = {"distance_end_m": float(s_end), "duration_s": float(duration),
               "strut_temperature_K": x_end[self.T_index].copy(),
               "wall_temperature_K": x_end[self.T_wall_index].copy(),
               "oil_temperature_K": x_end[self.T_oil_index].copy(),
               "mean_gas_temperature_K": np.array(x_end[self.T_gas_index] if gas_mean is None else gas_mean,
                                                  float)}
        for k, e in enumerate(ENERGY_TERMS):
            if e in DISSIPATION_TERMS:
                row[f"power_{e}_W"] = E[k] / max(duration, 1e-12)
        row["rms_strut_velocity_m_per_s"] = np.sqrt(np.maximum(dq[nE * n: nE * n + n], 0) / max(duration, 1e-12))
        row["rms_hull_acceleration"] = np.sqrt(np.maximum(dq[nE * n + n: nE * n + n + len(HULL_ACCELERATIONS)], 0)
                                               / max(duration, 1e-12))
        row["pump_oil_volume_interval_m3"] = np.asarray(dq[self.pump_slots], float).copy()
        if self.ride_slots:
            row.update(self._ride_row(duration, dq, E[ENERGY_TERMS.index("end_stop")]))
        return row

    def _ride_row(self, duration, dq, end_stop_energy_J) -> dict:
        """Ride and road-holding statistics of an interval from the differences of the ride quadratures
        (vehicle.physics.ride; the keys vehicle.analysis.ride_metrics reads)."""
        Q = {q: dq[k] for q, k in self.ride_slots.items()}
        T = max(duration, 1e-12)
        row = {}
        if len(self.model.seat_names):
            row["weighted_rms_acceleration_m_s2"] = ride.weighted_rms(Q["aw2"], T)
            row["weighted_rms_lateral_acceleration_m_s2"] = ride.weighted_rms(Q["awl2"], T)
            row["vdv_m_s175"] = ride.vibration_dose_value(Q["aw4"])
            row["absorbed_power_W"] = np.maximum(Q["pabs"], 0.0) / T
        row["dynamic_load_coefficient"] = ride.dynamic_load_coefficient(Q["F"], Q["F2"], T)
        row["lift_off_share"] = np.clip(Q["lift"] / T, 0.0, 1.0)
        row["end_stop_time_s"] = np.maximum(Q["stop"], 0.0)
        row["end_stop_energy_J"] = np.asarray(end_stop_energy_J, float).copy()
        hist = ride.travel_histogram(Q["above"], duration)
        row["strut_travel_min_m"], row["strut_travel_max_m"] = ride.travel_range(hist, self.travel_bin_edges_m)
        row["strut_travel_histogram_s"] = hist
        return row

    def final_values(self, state: DriveState) -> dict:
        """The drive's end as stored in /summary: energies since the start, the heat network's temperatures and
        (with ride metrics) the whole drive's ride numbers from the quadratures since the start."""
        m = self.model
        x = state.x
        values = {f"energy_{e}_J": np.asarray(x[idx], float) for e, idx in m.energy_index.items()}
        values["strut_temperature_K"] = np.asarray(x[self.T_index], float)          # the surface (pyrometer)
        values["wall_temperature_K"] = np.asarray(x[self.T_wall_index], float)
        values["oil_temperature_K"] = np.asarray(x[self.T_oil_index], float)
        values["pump_oil_volume_m3"] = np.asarray(x[self.pump_index], float)
        values["oil_added_m3"] = np.asarray(x[self.series_rows["oil_added_m3"]], float)
        if m.ride_metrics:
            values.update(self._ride_row(float(state.t_s), x[self.quad_index], x[m.energy_index["end_stop"]]))
            values["strut_travel_bin_edges_m"] = np.asarray(self.travel_bin_edges_m, float)
        return values
