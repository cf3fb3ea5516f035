"""Results of a drive in HDF5 (layout: docs/hdf5.md), written as the drive goes, and resumable.

`run_scenario()` is what `hpsim run` and every sweep case do:

1. validate the scenario and build the drive (nothing is written before the scenario is valid);
2. create the file (HDF5 1.10 format, written under a temporary name and renamed): /scenario,
   /equilibrium/charged and /before, and *every* dataset the drive will fill (time series,
   statistics, checkpoint slots), so that nothing needs creating later;
3. switch to SWMR (single-writer/multiple-reader) mode and drive: each block of samples is
   appended to chunked, compressed, resizable datasets and flushed; then the checkpoint (the
   drive's resume state plus the counts of samples and statistics rows it covers) is written to
   the inactive one of two slots, flushed, and only then the pointer to it is switched and
   flushed. SWMR's ordered metadata flushes keep the file valid whatever moment the process
   dies, and the double-buffered checkpoint is never half written;
4. close, reopen normally and write /equilibrium/after and /summary (status, complete=True).

Ctrl-C closes the file cleanly (status "interrupted"). A file whose writer was killed is still
readable (open it with `h5py.File(path, "r", swmr=True)`; `open_read` does that). `--resume`
copies what the checkpoint covers into a fresh file, rebuilds the drive from the scenario text
stored in the file and continues from the checkpoint: the result equals an uninterrupted run.
"""
from __future__ import annotations

import datetime as _dt
import functools
import json
import os
import signal
import subprocess
import time
from pathlib import Path
from typing import Callable

import h5py
import numpy as np

from hpsim.errors import SimulationError, UserInputError

from vehicle.runs.scenario import ScenarioSource, prepare, read_scenario, read_scenario_text

FORMAT = "hpsim-drive"
FORMAT_VERSION = 1
LIBVER = ("v110", "v110")   # HDF5 1.10 file format: needed for SWMR, readable by HDF5 >= 1.10
CHUNK_ROWS = 512            # samples per HDF5 chunk of the time series
STATS_CHUNK_ROWS = 64
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
def drive_class():
    """`Drive` plus `describe()`: the keys and shapes of what it will hand to the sink, so the file's
    datasets can all be created before the drive starts (SWMR mode cannot create objects)."""
    from vehicle.runs.drive import Drive

    class RunDrive(Drive):
        def describe(self):
            """(one block of samples, one statistics row, one state dict) with the right keys and shapes."""
            st = self.initial_state()
            t = np.array([0.0])
            block = self._block_outputs(st.x[:, None], self.inputs(t), t, t)
            row = self._stats_row(self.settings.stats_interval_m, 1.0, np.zeros(len(self.quad_index)),
                                  st.x[self.T_index])
            return block, row, st.as_dict()

    return RunDrive


# --- the writer ------------------------------------------------------------------------------------
UNITS = {"t_s": "s", "distance_m": "m", "speed_m_per_s": "m/s", "strut_temperature_K": "K",
         "axle_height_change_m": "m", "hull_acceleration": "m/s^2 (heave), rad/s^2 (pitch, roll)", "heave_m": "m",
         "pitch_rad": "rad", "roll_rad": "rad", "oil_added_m3": "m^3", "strut_force": "N", "strut_deflection": "m",
         "gas_pressure": "Pa", "gas_temperature": "K", "wheel_load": "N", "distance_end_m": "m", "duration_s": "s",
         "rms_strut_velocity_m_per_s": "m/s", "rms_hull_acceleration": "m/s^2 (heave), rad/s^2 (pitch, roll)"}


def _unit(key: str) -> str:
    if key in UNITS:
        return UNITS[key]
    for suffix, unit in (("_J", "J"), ("_W", "W"), ("_K", "K"), ("_m", "m"), ("_s", "s")):
        if key.endswith(suffix):
            return unit
    return ""


def _rows(value, n: int | None = None) -> np.ndarray:
    """Drive arrays are (width, n_samples) or (n_samples,): stored time-major (n_samples, width)."""
    a = np.asarray(value, float)
    return a.T if a.ndim == 2 else a.reshape(-1)


def open_read(path: str | Path) -> h5py.File:
    """Open a results file for reading, also one whose writer was killed (SWMR read)."""
    try:
        return h5py.File(path, "r")
    except OSError as exc:
        if "already open for write" in str(exc):
            return h5py.File(path, "r", swmr=True)
        raise


class Checkpoint:
    """Double-buffered resume state in /checkpoint: slots (2, L) float64 and pointer [slot, seq].

    A slot packs the DriveState dict plus n_samples, n_stats and wall_s; attrs["fields"] (JSON)
    gives each field's [offset, length] and shape. pointer = [-1, 0] until the first checkpoint.
    """

    META = ("n_samples", "n_stats", "wall_s")

    def __init__(self, group: h5py.Group):
        self.g = group
        self.fields = json.loads(group.attrs["fields"])

    @classmethod
    def create(cls, f: h5py.File, state: dict) -> "Checkpoint":
        g = f.create_group("checkpoint")
        fields, off = {}, 0
        for k, v in list(state.items()) + [(m, 0.0) for m in cls.META]:
            a = np.asarray(v, float)
            fields[k] = [off, int(a.size), list(a.shape)]
            off += int(a.size)
        g.create_dataset("slots", shape=(2, off), dtype="f8")
        g.create_dataset("pointer", data=np.array([-1, 0], dtype="i8"))
        g.attrs["fields"] = json.dumps(fields)
        g.attrs["description"] = ("resume state of the drive: pointer = [active slot, sequence number] (slot -1: "
                                  "none yet); slots[slot] packs the fields listed in attrs['fields'] as "
                                  "name: [offset, length, shape]")
        return cls(g)

    def write(self, state: dict, meta: dict) -> None:
        slot, seq = (int(v) for v in self.g["pointer"][()])
        new = 1 - slot if slot in (0, 1) else 0
        vec = np.zeros(self.g["slots"].shape[1])
        values = {**state, **meta}
        for k, (off, size, _shape) in self.fields.items():
            vec[off:off + size] = np.asarray(values[k], float).ravel()
        self.g["slots"][new] = vec
        self.g.file.flush()
        self.g["pointer"][...] = np.array([new, seq + 1], dtype="i8")
        self.g.file.flush()

    def read(self) -> tuple[dict, dict] | None:
        slot, seq = (int(v) for v in self.g["pointer"][()])
        if slot not in (0, 1):
            return None
        vec = np.asarray(self.g["slots"][slot], float)
        out = {}
        for k, (off, size, shape) in self.fields.items():
            v = vec[off:off + size]
            out[k] = v.reshape(shape) if shape else float(v[0])
        meta = {m: out.pop(m) for m in self.META}
        meta["n_samples"], meta["n_stats"] = int(meta["n_samples"]), int(meta["n_stats"])
        return out, meta


class H5Results:
    """The drive's sink: buffers samples and statistics rows, writes them a whole HDF5 chunk at a
    time (each compressed chunk written once: appending block by block would rewrite the last
    chunk every time, and SWMR mode does not reuse the freed space), then the checkpoint."""

    def __init__(self, f: h5py.File, stored: set[str], n_samples: int = 0, n_stats: int = 0,
                 wall_before_s: float = 0.0):
        self.f = f
        self.stored = stored
        self.ts = f["timeseries"]
        self.st = f["stats"]
        self.ck = Checkpoint(f["checkpoint"])
        self.chunk = int(self.ts["t_s"].chunks[0])
        self.n_samples = n_samples          # rows written (and covered by the last checkpoint)
        self.n_stats = n_stats
        self.buffer: dict[str, list] = {}
        self.n_buffered = 0
        self.stats_buffer: list[dict] = []
        self.pending_state: dict | None = None
        self.wall_before_s = wall_before_s
        self.session_t0 = time.perf_counter()
        self.last_state: dict | None = None
        self.stop_requested = False

    @staticmethod
    def create_layout(f: h5py.File, block: dict, row: dict, state: dict, stored: set[str], compression: int,
                      chunk_rows: int, station_names, axle_names) -> None:
        """Every dataset the drive fills, empty and resizable (created before SWMR mode)."""
        kw = {"compression": "gzip", "compression_opts": int(compression), "shuffle": True} if compression else {}

        def columns(width):
            if width == len(station_names):
                return list(station_names)
            if width == len(axle_names):
                return list(axle_names)
            if width == 3:
                return ["heave", "pitch", "roll"]
            return None

        # a block's arrays are (width, n) or (n,); a statistics row holds scalars or (width,) arrays
        for gname, shapes, chunk in (("timeseries", {k: _rows(v).shape[1:] for k, v in block.items()
                                                     if k in stored or k == "t_s"}, chunk_rows),
                                     ("stats", {k: np.asarray(v, float).shape for k, v in row.items()},
                                      STATS_CHUNK_ROWS)):
            g = f.create_group(gname)
            for key, shape in shapes.items():
                ds = g.create_dataset(key, shape=(0,) + shape, maxshape=(None,) + shape, dtype="f8",
                                      chunks=(chunk,) + shape, **kw)
                ds.attrs["unit"] = _unit(key)
                if shape and columns(shape[0]) is not None:
                    ds.attrs["columns"] = columns(shape[0])
        Checkpoint.create(f, state)

    # DriveSink protocol
    def start(self, info: dict) -> None:  # pragma: no cover - not called by the drive
        pass

    def samples(self, block: dict) -> None:
        for key, value in block.items():
            if key in self.ts:
                self.buffer.setdefault(key, []).append(_rows(value))
        self.n_buffered += len(np.atleast_1d(block["t_s"]))

    def stats(self, rows: list[dict]) -> None:
        self.stats_buffer.extend(rows)

    def checkpoint(self, state: dict) -> None:
        """Called by the drive after every block: write when a chunk is full (or on Ctrl-C)."""
        self.pending_state = state
        full = (self.n_samples + self.n_buffered) // self.chunk > self.n_samples // self.chunk
        if full or self.stop_requested:
            self.flush()
        if self.stop_requested:
            # Ctrl-C arrived during the last block: stop here, where the file is consistent
            raise KeyboardInterrupt

    def flush(self) -> None:
        """Append the buffered rows, flush, then write the checkpoint that covers them."""
        if self.n_buffered:
            for key, parts in self.buffer.items():
                ds = self.ts[key]
                ds.resize(self.n_samples + self.n_buffered, axis=0)
                ds[self.n_samples:] = np.concatenate(parts, axis=0)
            self.n_samples += self.n_buffered
            self.buffer, self.n_buffered = {}, 0
        if self.stats_buffer:
            n = len(self.stats_buffer)
            for key in self.stats_buffer[0]:
                if key in self.st:
                    ds = self.st[key]
                    ds.resize(self.n_stats + n, axis=0)
                    ds[self.n_stats:] = np.array([np.asarray(r[key], float) for r in self.stats_buffer])
            self.n_stats += n
            self.stats_buffer = []
        self.f.flush()
        if self.pending_state is not None:
            self.ck.write(self.pending_state, {"n_samples": self.n_samples, "n_stats": self.n_stats,
                                               "wall_s": self.wall_s()})
            self.last_state = self.pending_state
            self.pending_state = None

    def wall_s(self) -> float:
        return self.wall_before_s + (time.perf_counter() - self.session_t0)


def write_equilibrium(g: h5py.Group, name: str, eq, station_names) -> None:
    if name in g:
        del g[name]
    e = g.create_group(name)
    for k, v in eq.__dict__.items():
        if isinstance(v, np.ndarray):
            e.create_dataset(k, data=np.asarray(v, float))
        else:
            e.attrs[k] = float(v)
    e.attrs["stations"] = list(station_names)


def _write_json_attr(obj, name: str, value) -> None:
    obj.attrs[name] = json.dumps(value, indent=1, default=float)


def set_status(path: Path, status: str, **attrs) -> None:
    """Reopen normally (after the SWMR writer closed) and record the run's status in /summary."""
    with h5py.File(path, "r+", libver=LIBVER) as f:
        g = f.require_group("summary")
        g.attrs["status"] = status
        g.attrs["complete"] = status == "complete"
        for k, v in attrs.items():
            g.attrs[k] = v


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
    """'complete', 'running' (or killed), 'interrupted', 'failed'; None if no readable results file."""
    path = Path(path)
    if not path.exists():
        return None
    try:
        with open_read(path) as f:
            if f.attrs.get("format") != FORMAT:
                return None
            g = f.get("summary")
            return "running" if g is None else str(g.attrs.get("status", "running"))
    except OSError:
        return None


def run_scenario(scenario: str | Path | ScenarioSource | None, out: str | Path, *, resume: bool = False,
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
    status = results_status(out)
    if out.exists() and status is None and not overwrite:
        raise UserInputError(f"{out}: exists and is not a readable hpsim results file (remove it or use --overwrite)")
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
    model, drive = prep.drive(drive_class())
    resolved = prep.resolved()
    resolved["vehicle_derived"]["gas_masses_kg"] = drive.gas_masses.tolist()
    resolved["vehicle_derived"]["charged_wheel_loads_N"] = model.charged_wheel_loads.tolist()
    stations = list(model.station_names)
    axles = [f"axle{k + 1}" for k in range(model.params.n_axles)]
    before = drive.initial_equilibrium()
    block, row, state = drive.describe()
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(out.name + ".partial")
    with h5py.File(tmp, "w", libver=LIBVER) as f:
        f.attrs["format"] = FORMAT
        f.attrs["format_version"] = FORMAT_VERSION
        g = f.create_group("scenario")
        g.attrs["yaml"] = src.text
        g.attrs["source"] = src.name
        g.attrs["base_dir"] = str(src.base_dir)
        _write_json_attr(g, "resolved_json", resolved)
        g.attrs["hpsim_version"] = code_version()
        g.attrs["created"] = _now()
        g.attrs["stations"] = stations
        g.attrs["axles"] = axles
        g.attrs["distance_m"] = prep.scenario.distance
        g.attrs["total_time_s"] = drive.total_time_s
        e = f.create_group("equilibrium")
        c = e.create_group("charged")
        c.create_dataset("wheel_loads_N", data=model.charged_wheel_loads)
        c.create_dataset("axle_height_change_m", data=np.zeros(model.params.n_axles))
        c.attrs["temperature_K"] = model.params.charging.temperature
        write_equilibrium(e, "before", before, stations)
        H5Results.create_layout(f, block, row, state, prep.scenario.output.stored(), prep.scenario.output.compression,
                                chunk_rows(prep.scenario), stations, axles)
        s = f.create_group("summary")
        s.attrs["status"] = "running"
        s.attrs["complete"] = False
        s.attrs["build_s"] = drive.build_s
    tmp.replace(out)
    return _drive(drive, out, None, (0, 0, 0.0), prep, progress, log, checkpoint_every_blocks)


def _copy_truncated(path: Path, n_samples: int, n_stats: int) -> None:
    """Copy what the checkpoint covers into a fresh file (clears a killed writer's state) and replace."""
    tmp = path.with_name(path.name + ".resume")
    with open_read(path) as src, h5py.File(tmp, "w", libver=LIBVER) as dst:
        for k, v in src.attrs.items():
            dst.attrs[k] = v
        for name in ("scenario", "timeseries", "stats", "checkpoint"):
            src.copy(src[name], dst, name=name)
        e = dst.create_group("equilibrium")
        for name in ("charged", "before"):
            src.copy(src["equilibrium"][name], e, name=name)
        for gname, n in (("timeseries", n_samples), ("stats", n_stats)):
            for ds in dst[gname].values():
                if ds.shape[0] < n:
                    raise UserInputError(f"{path}: /{gname}/{ds.name.rsplit('/', 1)[-1]} has {ds.shape[0]} rows, "
                                         f"fewer than the checkpoint's {n}: the file is damaged, start again with "
                                         "--overwrite")
                ds.resize(n, axis=0)
        s = dst.create_group("summary")
        for k, v in src["summary"].attrs.items() if "summary" in src else ():
            s.attrs[k] = v
        s.attrs["status"] = "running"
        s.attrs["complete"] = False
    os.replace(tmp, path)


def _resume(out: Path, src: ScenarioSource | None, progress, log, checkpoint_every_blocks) -> dict:
    from vehicle.runs.drive import DriveState

    with open_read(out) as f:
        stored = _stored_source(f, out)
        stored_version = str(f["scenario"].attrs.get("hpsim_version", ""))
        status = str(f["summary"].attrs.get("status", "running")) if "summary" in f else "running"
        if status == "complete":
            log(f"{out}: already complete, nothing to do")
            return {k: (v.item() if hasattr(v, "item") else v) for k, v in f["summary"].attrs.items()}
        ck = Checkpoint(f["checkpoint"]).read() if "checkpoint" in f else None
    if src is not None and src.text != stored.text:
        raise UserInputError(f"{out}: the scenario {src.name} differs from the one this run started with "
                             "(stored in the file); resume without changing it, or start again with --overwrite")
    prep = prepare(stored)
    if stored_version and stored_version != code_version():
        log(f"{out}: warning: the run started with hpsim {stored_version}, resuming with {code_version()}; "
            "if the model changed in between, the result differs from an uninterrupted run")
    model, drive = prep.drive(drive_class())
    if ck is None:
        state, counts = None, (0, 0, 0.0)
    else:
        d, meta = ck
        state = DriveState.from_dict(d)
        counts = (meta["n_samples"], meta["n_stats"], meta["wall_s"])
    _copy_truncated(out, counts[0], counts[1])
    if state is not None:
        log(f"{out}: resuming at {state.s_m / 1e3:.3f} km of {prep.scenario.distance / 1e3:.6g} km")
    return _drive(drive, out, state, counts, prep, progress, log, checkpoint_every_blocks)


def _catch_sigint(sink: H5Results):
    """First Ctrl-C: finish the current block and checkpoint, then stop (a KeyboardInterrupt raised at
    an arbitrary point can be swallowed by a weakref callback inside h5py); second: stop at once."""
    def handler(signum, frame):
        if sink.stop_requested:
            raise KeyboardInterrupt
        sink.stop_requested = True

    try:
        return signal.signal(signal.SIGINT, handler)
    except ValueError:          # not the main thread (e.g. a Dask worker): leave signals alone
        return None


def _restore_sigint(old) -> None:
    if old is not None:
        try:
            signal.signal(signal.SIGINT, old)
        except ValueError:
            pass


def chunk_rows(scenario) -> int:
    """Samples per HDF5 chunk (and between checkpoints): output.chunk_samples rounded up to whole
    blocks of solver.samples_per_block."""
    M = scenario.solver.samples_per_block
    return int(M * max(1, -(-scenario.output.chunk_samples // M)))


def _drive(drive, out: Path, state, counts, prep, progress: bool, log, checkpoint_every_blocks) -> dict:
    total_km = prep.scenario.distance / 1e3
    bar = cb = None
    if progress:
        from tqdm import tqdm

        start_km = 0.0 if state is None else state.s_m / 1e3
        bar = tqdm(total=round(total_km, 3), initial=round(start_km, 3), unit="km", desc=out.name,
                   bar_format="{desc}: {percentage:3.0f}%|{bar}| {n:.2f}/{total:.2f} km "
                              "[{elapsed}<{remaining}{postfix}]",
                   dynamic_ncols=True, mininterval=0.5)

        def cb(s_m, v, t_s):
            bar.update(round(min(s_m / 1e3, total_km), 3) - bar.n)
            bar.set_postfix_str(f"{v * 3.6:.1f} km/h, simulated {t_s / 3600:.2f} h", refresh=False)

    f = h5py.File(out, "r+", libver=LIBVER)
    sink = None
    old_handler = None
    try:
        sink = H5Results(f, prep.scenario.output.stored(), counts[0], counts[1], counts[2])
        f.swmr_mode = True
        old_handler = _catch_sigint(sink)
        res = drive.run(sink, state=state, progress=cb, checkpoint_every_blocks=checkpoint_every_blocks)
        sink.flush()
    except SimulationError as exc:
        if sink is not None:
            sink.flush()             # the blocks before the failure, with their checkpoint
        f.close()
        if bar is not None:
            bar.close()
        where = sink.last_state["s_m"] / 1e3 if sink and sink.last_state else (state.s_m / 1e3 if state else 0.0)
        set_status(out, "failed", error=str(exc), wall_s=sink.wall_s() if sink else 0.0, stopped_at_km=float(where))
        raise SimulationError(f"{exc} (results up to {where:.3f} km kept in {out})") from None
    except KeyboardInterrupt:
        f.close()
        if bar is not None:
            bar.close()
        where = sink.last_state["s_m"] / 1e3 if sink and sink.last_state else (state.s_m / 1e3 if state else 0.0)
        set_status(out, "interrupted", wall_s=sink.wall_s() if sink else 0.0, stopped_at_km=float(where))
        raise RunInterrupted(f"interrupted at {where:.3f} km of {total_km:.6g} km; {out} holds what was done. "
                             f"Continue with: hpsim run {prep.source.name} -o {out} --resume", out) from None
    except BaseException:
        f.close()
        if bar is not None:
            bar.close()
        raise
    finally:
        _restore_sigint(old_handler)
    f.close()
    if bar is not None:
        bar.close()
    m = drive.model
    x = res.state.x
    summary = {"distance_km": float(res.state.s_m / 1e3), "simulated_s": float(res.state.t_s),
               "wall_s": float(sink.wall_s()), "build_s": float(drive.build_s),
               "integration_s": float(res.integration_s), "n_samples": sink.n_samples, "n_stats": sink.n_stats,
               "finished_at": _now()}
    with h5py.File(out, "r+", libver=LIBVER) as f:
        write_equilibrium(f["equilibrium"], "after", res.after, m.station_names)
        g = f["summary"]
        for e, idx in m.energy_index.items():
            g.create_dataset(f"energy_{e}_J", data=np.asarray(x[idx], float))
        g.create_dataset("strut_temperature_end_K", data=np.asarray(x[drive.T_index], float))
        for k, v in summary.items():
            g.attrs[k] = v
        g.attrs["status"] = "complete"
        g.attrs["complete"] = True
    return {"status": "complete", **summary}


def valid_counts(f: h5py.File) -> tuple[int, int]:
    """(samples, statistics rows) covered by the last checkpoint: the rows to trust in a file
    whose writer may have been stopped between appending data and checkpointing."""
    ck = Checkpoint(f["checkpoint"]).read() if "checkpoint" in f else None
    if ck is not None:
        return ck[1]["n_samples"], ck[1]["n_stats"]
    return 0, 0


def read_state(f: h5py.File) -> dict | None:
    """The last checkpointed DriveState dict (t_s, s_m, x, ...) or None."""
    ck = Checkpoint(f["checkpoint"]).read() if "checkpoint" in f else None
    return None if ck is None else ck[0]
