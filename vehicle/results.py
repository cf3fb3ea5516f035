"""Results of a drive in HDF5 (layout: docs/hdf5.md), written as the drive goes, and resumable.

`run_scenario()` is what `hpsim run` and every sweep case do: validate the scenario, build the
drive, write /scenario and /equilibrium/before, then hand `H5Results` to `Drive.run` as its sink.
Every block of samples is appended to chunked, compressed, resizable datasets; every checkpoint
(the drive's resume state plus the number of samples and statistics rows it covers) is written
*after* the data it covers, then the file is flushed. A run that is killed, crashes or is
interrupted keeps a readable file; `--resume` truncates the datasets to the checkpoint's counts,
rebuilds the drive from the scenario text stored in the file and continues from the checkpoint,
ending with the same result as an uninterrupted run.
"""
from __future__ import annotations

import datetime as _dt
import functools
import json
import subprocess
import time
from pathlib import Path
from typing import Callable

import h5py
import numpy as np

from hpsim.errors import SimulationError, UserInputError

from .scenario import ScenarioSource, prepare, read_scenario, read_scenario_text

FORMAT = "hpsim-drive"
FORMAT_VERSION = 1
CHUNK_ROWS = 512            # samples per HDF5 chunk of the time series
DISSIPATION = ("valve", "friction", "gas", "end_stop")


@functools.lru_cache(maxsize=1)
def code_version() -> str:
    """hpsim version, plus the git commit when running from a checkout."""
    from hpsim import __version__

    here = Path(__file__).resolve().parent
    try:
        out = subprocess.run(["git", "describe", "--always", "--dirty"], cwd=here, capture_output=True,
                             text=True, timeout=5)
        if out.returncode == 0 and out.stdout.strip():
            return f"{__version__} ({out.stdout.strip()})"
    except (OSError, subprocess.SubprocessError):
        pass
    return __version__


def _now() -> str:
    return _dt.datetime.now().astimezone().isoformat(timespec="seconds")


# --- the drive adapter ---------------------------------------------------------------------------
def completing_drive_class():
    """`Drive` subclass that hands the drive's last (partial) block to the sink.

    vehicle.drive.Drive.run computes the final block (samples beyond the distance trimmed) but
    leaves the loop before giving it, its statistics rows and a final checkpoint to the sink.
    This adapter remembers the last block and rows and delivers them after run() when the sink
    has not seen them; it does nothing when the drive does it itself.
    """
    from .drive import Drive

    class CompletingDrive(Drive):
        def _block_outputs(self, X, U, t, s):
            self._last_block = super()._block_outputs(X, U, t, s)
            return self._last_block

        def _stats(self, st, X, t, s):
            self._last_rows = super()._stats(st, X, t, s)
            return self._last_rows

        def run(self, sink=None, state=None, progress=None, checkpoint_every_blocks: int = 1):
            tracker = _TrackingSink(sink, 0 if state is None else state.sample_index)
            res = super().run(tracker if sink is not None else None, state, progress,
                              checkpoint_every_blocks=checkpoint_every_blocks)
            if sink is not None:
                if tracker.n_samples < res.state.sample_index:
                    sink.samples(self._last_block)
                    if self._last_rows:
                        sink.stats(self._last_rows)
                if tracker.checkpointed != res.state.sample_index:
                    sink.checkpoint(res.state.as_dict())
                if progress is not None:
                    progress(res.state.s_m, float(self.settings.speed.speed(res.state.s_m)), res.state.t_s)
            return res

    return CompletingDrive


class _TrackingSink:
    def __init__(self, sink, n0: int):
        self.sink, self.n_samples, self.checkpointed = sink, n0, n0

    def start(self, info):
        if hasattr(self.sink, "start"):
            self.sink.start(info)

    def samples(self, block):
        self.n_samples += len(np.atleast_1d(block["t_s"]))
        self.sink.samples(block)

    def stats(self, rows):
        self.sink.stats(rows)

    def checkpoint(self, state):
        self.checkpointed = int(state["sample_index"])
        self.sink.checkpoint(state)


# --- the writer ------------------------------------------------------------------------------------
def _append(group: h5py.Group, name: str, rows: np.ndarray, compression: int, columns=None, chunk_rows=CHUNK_ROWS):
    """Append rows (first axis) to a resizable dataset, creating it on first use."""
    if name not in group:
        kw = {}
        if compression:
            kw = {"compression": "gzip", "compression_opts": int(compression), "shuffle": True}
        shape = rows.shape[1:]
        ds = group.create_dataset(name, shape=(0,) + shape, maxshape=(None,) + shape, dtype="f8",
                                  chunks=(chunk_rows,) + shape, **kw)
        if columns is not None:
            ds.attrs["columns"] = list(columns)
    ds = group[name]
    n = ds.shape[0]
    ds.resize(n + rows.shape[0], axis=0)
    ds[n:] = rows


UNITS = {"t_s": "s", "distance_m": "m", "speed_m_per_s": "m/s", "strut_temperature_K": "K",
         "axle_height_change_m": "m", "hull_acceleration": "m/s^2, rad/s^2, rad/s^2", "heave_m": "m",
         "pitch_rad": "rad", "roll_rad": "rad", "oil_added_m3": "m^3", "strut_force": "N", "strut_deflection": "m",
         "gas_pressure": "Pa", "gas_temperature": "K", "wheel_load": "N"}


class H5Results:
    """The drive's sink: appends samples and statistics, writes checkpoints, flushes."""

    def __init__(self, f: h5py.File, stored: set[str], compression: int, station_names, axle_names,
                 wall_before_s: float = 0.0):
        self.f = f
        self.stored = stored
        self.compression = compression
        self.station_names = list(station_names)
        self.axle_names = list(axle_names)
        self.wall_before_s = wall_before_s
        self.session_t0 = time.perf_counter()
        self.ts = f.require_group("timeseries")
        self.st = f.require_group("stats")
        self.n_samples = int(self.ts.attrs.get("n_samples", 0))
        self.n_stats = int(self.st.attrs.get("n_rows", 0))
        self.last_state: dict | None = None

    def _columns(self, width: int):
        if width == len(self.station_names):
            return self.station_names
        if width == len(self.axle_names):
            return self.axle_names
        if width == 3:
            return ["heave", "pitch", "roll"]
        return None

    # DriveSink protocol
    def start(self, info: dict) -> None:  # pragma: no cover - not called by the drive
        pass

    def samples(self, block: dict) -> None:
        n = len(np.atleast_1d(block["t_s"]))
        for key, value in block.items():
            if key not in self.stored:
                continue
            a = np.asarray(value, float)
            rows = a.T if a.ndim == 2 else a.reshape(n)
            new = key not in self.ts
            _append(self.ts, key, rows, self.compression, self._columns(rows.shape[1]) if rows.ndim == 2 else None)
            if new:
                unit = UNITS.get(key) or ("J" if key.endswith("_J") else "")
                self.ts[key].attrs["unit"] = unit
        self.n_samples += n
        self.ts.attrs["n_samples"] = self.n_samples

    def stats(self, rows: list[dict]) -> None:
        if not rows:
            return
        for key in rows[0]:
            a = np.array([np.asarray(r[key], float) for r in rows])
            new = key not in self.st
            _append(self.st, key, a, self.compression,
                    self._columns(a.shape[1]) if a.ndim == 2 else None, chunk_rows=64)
            if new:
                self.st[key].attrs["unit"] = (key.rsplit("_", 1)[-1] if "_" in key else "")
        self.n_stats += len(rows)
        self.st.attrs["n_rows"] = self.n_stats

    def checkpoint(self, state: dict) -> None:
        """Write the resume state after the data it covers, then flush."""
        g = self.f.require_group("checkpoint")
        for k, v in state.items():
            a = np.asarray(v)
            if a.ndim == 0:
                g.attrs[k] = a.item()
            elif k in g and g[k].shape == a.shape:
                g[k][...] = a
            else:
                if k in g:
                    del g[k]
                g.create_dataset(k, data=a)
        g.attrs["n_samples"] = self.n_samples
        g.attrs["n_stats"] = self.n_stats
        g.attrs["wall_s"] = self.wall_s()
        g.attrs["written_at"] = _now()
        self.last_state = state
        self.f.flush()

    # --- other groups ---
    def wall_s(self) -> float:
        return self.wall_before_s + (time.perf_counter() - self.session_t0)

    def equilibrium(self, name: str, eq) -> None:
        g = self.f.require_group("equilibrium")
        if name in g:
            del g[name]
        e = g.create_group(name)
        for k, v in eq.__dict__.items():
            if isinstance(v, np.ndarray):
                e.create_dataset(k, data=np.asarray(v, float))
            else:
                e.attrs[k] = float(v)
        e.attrs["stations"] = self.station_names
        self.f.flush()

    def status(self, status: str, **attrs) -> None:
        g = self.f.require_group("summary")
        g.attrs["status"] = status
        g.attrs["complete"] = status == "complete"
        for k, v in attrs.items():
            g.attrs[k] = v
        self.f.flush()


def _write_json_attr(obj, name: str, value) -> None:
    obj.attrs[name] = json.dumps(value, indent=1, default=float)


def truncate(f: h5py.File, n_samples: int, n_stats: int) -> None:
    """Cut the time series and statistics back to what the checkpoint covers."""
    for gname, n, attr in (("timeseries", n_samples, "n_samples"), ("stats", n_stats, "n_rows")):
        g = f.require_group(gname)
        for ds in g.values():
            if ds.shape[0] > n:
                ds.resize(n, axis=0)
            elif ds.shape[0] < n:
                raise UserInputError(f"{f.filename}: /{gname}/{ds.name.rsplit('/', 1)[-1]} has {ds.shape[0]} rows, "
                                     f"fewer than the checkpoint's {n}: the file is damaged, start again without --resume")
        g.attrs[attr] = n


# --- running a scenario --------------------------------------------------------------------------
class RunInterrupted(Exception):
    """Ctrl-C during a run: the file is closed and readable; message says how far it got."""

    def __init__(self, message: str, path: Path):
        super().__init__(message)
        self.path = path


def _stored_source(f: h5py.File, path: Path) -> ScenarioSource:
    g = f.get("scenario")
    if g is None or "yaml" not in g.attrs:
        raise UserInputError(f"{path}: not an hpsim results file (no /scenario)")
    name = str(g.attrs.get("source", path))
    base = str(g.attrs.get("base_dir", Path(path).resolve().parent))
    return read_scenario_text(str(g.attrs["yaml"]), name, base)


def results_status(path: str | Path) -> str | None:
    """'complete', 'running', 'interrupted', 'failed', or None if there is no readable results file."""
    path = Path(path)
    if not path.exists():
        return None
    try:
        with h5py.File(path, "r") as f:
            if f.attrs.get("format") != FORMAT:
                return None
            g = f.get("summary")
            if g is None:
                return "running"
            return str(g.attrs.get("status", "running"))
    except OSError:
        return None


def run_scenario(scenario: str | Path | ScenarioSource, out: str | Path, *, resume: bool = False,
                 overwrite: bool = False, progress: bool = True, log: Callable[[str], None] | None = None,
                 checkpoint_every_blocks: int = 1) -> dict:
    """Run a scenario into an HDF5 file; returns the summary attributes.

    Raises UserInputError (bad scenario, file exists, cannot resume), SimulationError (after
    writing status 'failed' and the message) or RunInterrupted (Ctrl-C, status 'interrupted').
    """
    log = log or (lambda msg: None)
    out = Path(out)
    src = scenario if isinstance(scenario, ScenarioSource) else (
        read_scenario(scenario) if scenario is not None else None)
    status = results_status(out) if out.exists() else None
    if out.exists() and status is None and not overwrite:
        raise UserInputError(f"{out}: exists and is not an hpsim results file (remove it or use --overwrite)")
    if resume and status is not None:
        return _resume(out, src, progress, log, checkpoint_every_blocks)
    if out.exists() and not overwrite:
        hint = "--resume to continue it or " if status != "complete" else ""
        raise UserInputError(f"{out}: exists (status {status}); use {hint}--overwrite to start again, or -o another file")
    if src is None:
        raise UserInputError(f"{out}: not found and no scenario given")
    if resume:
        log(f"{out}: nothing to resume, starting")
    prep = prepare(src)                            # every check before any work
    model, drive = prep.drive(completing_drive_class())
    resolved = prep.resolved()
    resolved["vehicle_derived"]["gas_masses_kg"] = drive.gas_masses.tolist()
    resolved["vehicle_derived"]["charged_wheel_loads_N"] = model.charged_wheel_loads.tolist()
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(out.name + ".partial")
    with h5py.File(tmp, "w") as f:
        f.attrs["format"] = FORMAT
        f.attrs["format_version"] = FORMAT_VERSION
        g = f.create_group("scenario")
        g.attrs["yaml"] = src.text
        g.attrs["source"] = src.name
        g.attrs["base_dir"] = str(src.base_dir)
        _write_json_attr(g, "resolved_json", resolved)
        g.attrs["hpsim_version"] = code_version()
        g.attrs["created"] = _now()
        g.attrs["stations"] = model.station_names
        g.attrs["axles"] = [f"axle{k + 1}" for k in range(model.params.n_axles)]
        g.attrs["distance_m"] = prep.scenario.distance
        g.attrs["total_time_s"] = drive.total_time_s
        c = f.create_group("equilibrium").create_group("charged")
        c.create_dataset("wheel_loads_N", data=model.charged_wheel_loads)
        c.create_dataset("axle_height_change_m", data=np.zeros(model.params.n_axles))
        c.attrs["temperature_K"] = model.params.charging.temperature
        f.create_group("timeseries").attrs["n_samples"] = 0
        f.create_group("stats").attrs["n_rows"] = 0
    tmp.replace(out)
    f = h5py.File(out, "r+")
    try:
        sink = H5Results(f, prep.scenario.output.stored(), prep.scenario.output.compression,
                         model.station_names, [f"axle{k + 1}" for k in range(model.params.n_axles)])
        sink.status("running", build_s=drive.build_s)
        before = drive.initial_equilibrium()
        sink.equilibrium("before", before)
        return _drive(drive, sink, None, prep, out, progress, log, checkpoint_every_blocks)
    finally:
        f.close()


def _resume(out: Path, src: ScenarioSource | None, progress, log, checkpoint_every_blocks) -> dict:
    from .drive import DriveState

    with h5py.File(out, "r") as f:
        stored = _stored_source(f, out)
        status = str(f["summary"].attrs.get("status", "running")) if "summary" in f else "running"
        if status == "complete":
            log(f"{out}: already complete, nothing to do")
            return dict(f["summary"].attrs)
        if "checkpoint" not in f:
            ck = None
        else:
            ck = f["checkpoint"]
            state = {k: (ck[k][()] if k in ck else ck.attrs[k])
                     for k in ("t_s", "s_m", "x", "next_stats_m", "last_stats_t_s", "last_stats_q", "sample_index")}
            counts = (int(ck.attrs["n_samples"]), int(ck.attrs["n_stats"]), float(ck.attrs.get("wall_s", 0.0)))
    if src is not None and src.text != stored.text:
        raise UserInputError(f"{out}: the scenario {src.name} differs from the one this run started with "
                             "(stored in the file); resume without changing it, or start again with --overwrite")
    prep = prepare(stored)
    model, drive = prep.drive(completing_drive_class())
    f = h5py.File(out, "r+")
    try:
        if ck is None:
            n_samples, n_stats, wall0, st = 0, 0, 0.0, None
        else:
            n_samples, n_stats, wall0 = counts
            st = DriveState.from_dict(state)
        truncate(f, n_samples, n_stats)
        sink = H5Results(f, prep.scenario.output.stored(), prep.scenario.output.compression,
                         model.station_names, [f"axle{k + 1}" for k in range(model.params.n_axles)],
                         wall_before_s=wall0)
        sink.status("running", build_s=drive.build_s, resumed_at_km=0.0 if st is None else st.s_m / 1e3)
        if "equilibrium" not in f or "before" not in f["equilibrium"]:
            sink.equilibrium("before", drive.initial_equilibrium())
        if st is not None:
            log(f"{out}: resuming at {st.s_m / 1e3:.3f} km of {prep.scenario.distance / 1e3:.6g} km")
        return _drive(drive, sink, st, prep, out, progress, log, checkpoint_every_blocks)
    finally:
        f.close()


def _drive(drive, sink: H5Results, state, prep, out: Path, progress: bool, log, checkpoint_every_blocks) -> dict:
    total_km = prep.scenario.distance / 1e3
    bar = None
    cb = None
    if progress:
        from tqdm import tqdm

        start_km = 0.0 if state is None else state.s_m / 1e3
        bar = tqdm(total=round(total_km, 3), initial=round(start_km, 3), unit="km", desc=out.name,
                   bar_format="{desc}: {percentage:3.0f}%|{bar}| {n:.2f}/{total:.2f} km [{elapsed}<{remaining}{postfix}]",
                   dynamic_ncols=True, leave=True)

        def cb(s_m, v, t_s):
            bar.n = round(min(s_m / 1e3, total_km), 3)
            bar.set_postfix_str(f"{v * 3.6:.1f} km/h, t={t_s / 3600:.2f} h", refresh=False)
            bar.refresh()
    try:
        res = drive.run(sink, state=state, progress=cb, checkpoint_every_blocks=checkpoint_every_blocks)
    except SimulationError as exc:
        if bar is not None:
            bar.close()
        where = sink.last_state["s_m"] / 1e3 if sink.last_state else 0.0
        sink.status("failed", error=str(exc), wall_s=sink.wall_s(), stopped_at_km=float(where))
        raise SimulationError(f"{exc} (results up to {where:.3f} km kept in {out})") from None
    except KeyboardInterrupt:
        if bar is not None:
            bar.close()
        where = sink.last_state["s_m"] / 1e3 if sink.last_state else 0.0
        sink.status("interrupted", wall_s=sink.wall_s(), stopped_at_km=float(where))
        raise RunInterrupted(f"interrupted at {where:.3f} km of {total_km:.6g} km; {out} holds what was done. "
                             f"Continue with: hpsim run {prep.source.name} -o {out} --resume", out) from None
    if bar is not None:
        bar.close()
    sink.equilibrium("after", res.after)
    m = drive.model
    g = sink.f.require_group("summary")
    x = res.state.x
    for e, idx in m.energy_index.items():
        if f"energy_{e}_J" in g:
            del g[f"energy_{e}_J"]
        g.create_dataset(f"energy_{e}_J", data=np.asarray(x[idx], float))
    if "strut_temperature_end_K" in g:
        del g["strut_temperature_end_K"]
    g.create_dataset("strut_temperature_end_K", data=np.asarray(x[drive.T_index], float))
    summary = {"distance_km": float(res.state.s_m / 1e3), "simulated_s": float(res.state.t_s),
               "wall_s": float(sink.wall_s()), "build_s": float(drive.build_s),
               "integration_s": float(res.integration_s), "n_samples": sink.n_samples, "n_stats": sink.n_stats,
               "finished_at": _now()}
    sink.status("complete", **summary)
    return {"status": "complete", **summary}
