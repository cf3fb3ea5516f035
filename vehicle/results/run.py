"""Running a scenario into a sink: an HDF5 results file (layout: docs/hdf5.md), resumable, or memory.

`run_scenario()` is what `hpsim run` and every sweep case do:

1. validate the scenario and build the drive (nothing is written before the scenario is valid);
   take the output's lock file `<out>.lock` (pid and host of the writer; a lock whose process is
   gone is taken over), so that a second run, resume or overwrite on the same file is refused;
2. create the file (HDF5 1.10 format, netCDF-4/CF structure, written under `<out>.partial` and
   renamed): root and /scenario attributes, /equilibrium/charged and /before, and *every* variable
   the drive will fill (time series, statistics, checkpoint slots), so that nothing needs creating
   later;
3. switch to SWMR (single-writer/multiple-reader) mode and drive: each chunk of samples is
   appended to chunked, compressed, checksummed, resizable datasets and flushed; then the
   checkpoint (the drive's resume state plus the counts of samples and statistics rows it covers)
   is written to the inactive one of two slots, flushed, and only then the pointer to it is
   switched and flushed. SWMR's ordered metadata flushes keep the file valid whatever moment the
   process dies, and the double-buffered checkpoint is never half written;
4. close, and write /equilibrium/after and /summary (status complete) into a copy `<out>.final`
   that replaces the file when done: a kill during the final write leaves the previous file,
   which `--resume` completes.

Ctrl-C closes the file cleanly (status "interrupted"). A file whose writer was killed is still
readable (vehicle.results.reader opens it as an SWMR reader). `--resume` checks the whole file first
(a damaged one is refused untouched), copies what the checkpoint covers into a fresh file
(`<out>.resume`), rebuilds the drive from the scenario text stored in the file and continues from
the checkpoint: the result equals an uninterrupted run. A full disk stops the run with "disk
full" (exit 3); what was checkpointed stays readable and `--resume` continues once there is space.
No temporary path (`.partial`, `.resume`, `.final`, `.lock`) is written through a symbolic link.

`run_in_memory()` runs the same scenario into a MemorySink (vehicle.results.sinks): the same
variables, read through the same interface.
"""
from __future__ import annotations

import datetime as _dt
import contextlib
import json
import logging
import os
import signal
import socket
import time
import traceback
from pathlib import Path
from typing import Callable

import numpy as np

from hpsim.errors import SimulationError, UserInputError
from hpsim.outputs import check_not_input
from hpsim.stages import timed
from hpsim.threads import beside

from vehicle.numerics import compile_time, drive_rate
from vehicle.physics.weighing import band_datasets, weighing_bands
from vehicle.scenario.schema import ScenarioSource, prepare, read_scenario, read_scenario_text
from vehicle.engines.build import build_engine
from vehicle.engines.contract import DriveState
from vehicle.engines.multiscale import integrated_time_s
from hpsim.cancellation import CancelToken

from vehicle.results import provenance
from vehicle.results.provenance import code_version
from vehicle.results.layout import fault_point, h5py_releases_quietly, out_of_space, remove_stale
from vehicle.results.reader import FORMAT, FORMAT_VERSION, ResultsFile
from vehicle.results.results_file import DriveFile, ResumePoint
from vehicle.results.sinks import MemorySink
from vehicle.results.validity import check, summary_cell, summary_warnings_of

DISSIPATION = ("valve", "friction", "gas", "end_stop")
LOG = logging.getLogger("hpsim")


def _now() -> str:
    return _dt.datetime.now().astimezone().isoformat(timespec="seconds")


# --- what the runner hands a sink ------------------------------------------------------------------
def run_info(src: ScenarioSource, prep, model, drive, before) -> dict:
    """`start(info)`: root and scenario attributes, names, the charged and before-drive equilibria."""
    resolved = prep.resolved()
    resolved["vehicle_derived"]["gas_masses_kg"] = drive.gas_masses.tolist()
    resolved["vehicle_derived"]["charged_wheel_loads_N"] = model.charged_wheel_loads.tolist()
    stations = [str(s) for s in model.station_names]
    axles = [f"axle{k + 1}" for k in range(model.params.n_axles)]
    description = prep.scenario.description
    return {
        "attrs": {"format": FORMAT, "format_version": FORMAT_VERSION, "Conventions": "CF-1.8",
                  "title": description or f"hpsim drive: {src.name}",
                  "source": f"hpsim {code_version()}",
                  "history": f"{_now()}: hpsim run {src.name} (started)"},
        "scenario": {"yaml": src.text, "source": src.name, "base_dir": str(src.base_dir),
                     "resolved_json": json.dumps(resolved, indent=1, default=float),
                     # the hashes of the input files and of the definition, compared by --resume
                     "inputs_json": json.dumps(provenance.fingerprint(prep)),
                     "hpsim_version": code_version(), "created": _now(), "stations": stations, "axles": axles,
                     "distance_m": float(prep.scenario.distance), "total_time_s": float(drive.total_time_s),
                     **({"seats": list(model.seat_names)} if model.seat_names else {})},
        "stations": stations, "axles": axles,
        "equilibrium": {"charged": {"wheel_loads_N": np.asarray(model.charged_wheel_loads, float),
                                    "axle_height_change_m": np.zeros(len(axles)),
                                    "temperatures_K": np.full(len(stations), float(model.params.charging.temperature))},
                        "before": dict(before.__dict__),
                        # the weighing as a measurement: what seal friction lets a standing vehicle show
                        "before_band": weighing_band_datasets(drive, before.temperatures_K)},
        "summary": {"status": "running", "complete": False, "build_s": float(drive.build_s)},
        # ride metrics (vehicle.analysis.ride_metrics): the seat labels and the strut-travel bin edges
        "seats": list(model.seat_names),
        "stats_attrs": {"strut_travel_histogram": {"bin_edges_m": model.travel_bin_edges()}},
    }


def final_info(drive, res, n_samples: int, n_stats: int, wall_s: float) -> dict:
    """`finish(info)`: the after-drive equilibrium, the final energies and temperatures, the summary."""
    m = drive.model
    x = res.state.x
    values = drive.final_values(res.state)
    summary = {"distance_km": float(res.state.s_m / 1e3), "simulated_s": float(res.state.t_s),
               "wall_s": float(wall_s), "build_s": float(drive.build_s),
               "integration_s": float(res.integration_s), "n_samples": int(n_samples), "n_stats": int(n_stats),
               "finished_at": _now(), "status": "complete", "complete": True,
               "solver_mode": str(drive.mode)}
    if res.solver_error:
        summary.update(res.solver_error)          # the step-doubling estimate (vehicle.numerics.error_estimate)
    extra = drive.summary_extra()           # multiscale, time-parallel: their error estimates
    if extra:
        summary.update(extra["attrs"])
        values.update(extra["values"])
    after_band = weighing_band_datasets(drive, res.after.temperatures_K,
                                        np.array([x[m.idx(f"V_oil[{i}]")] for i in range(m.n)]))
    return {"equilibrium": {"after": dict(res.after.__dict__), "after_band": after_band},
            "summary_values": values, "summary": summary, "history": f"{_now()}: completed"}


def weighing_band_datasets(drive, temperatures_K, oil_volumes_m3=None) -> dict:
    """The /equilibrium/*_band datasets: wheel loads and heights over all seal-friction states of the standing
    vehicle (vehicle.physics.weighing)."""
    return band_datasets(weighing_bands(drive.model, temperatures_K, drive.gas_masses, oil_volumes_m3))


def run_in_memory(scenario: str | Path | ScenarioSource, *, progress=None) -> MemorySink:
    """Run a scenario into memory: a MemorySink holding what the HDF5 file would (same variables)."""
    src = scenario if isinstance(scenario, ScenarioSource) else read_scenario(scenario)
    prep = prepare(src)
    prep.in_memory = True                          # the work limits of a run kept in memory
    model, drive = build_engine(prep)
    if prep.work.get("announce"):
        LOG.warning(prep.work["announce"])         # a long run says so up front
    sink = MemorySink(src.name)
    sink.start(run_info(src, prep, model, drive, drive.initial_equilibrium()))
    t0 = time.perf_counter()
    res = drive.run(sink, progress=progress)
    n_samples, n_stats = sink.counts()
    sink.finish(final_info(drive, res, n_samples, n_stats, time.perf_counter() - t0))

    found = check(sink)                 # the validity warnings, as run_scenario records them in the file
    sink.final["summary"].update(warnings=summary_cell(found), warnings_json=json.dumps(found))
    return sink


# --- the output's lock file ------------------------------------------------------------------------
def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    try:                                   # a zombie (killed, not yet reaped) is gone too
        with open(f"/proc/{pid}/stat") as fh:
            return fh.read().rsplit(")", 1)[-1].split()[0] != "Z"
    except OSError:
        return True


class OutputLock:
    """`<out>.lock` (JSON: pid, host, started): one writer per results file. A lock whose process is
    gone (same host) is stale and taken over; a symbolic link there is never followed."""

    def __init__(self, out: Path):
        self.out = out
        self.path = out.with_name(out.name + ".lock")
        self.held = False

    def _holder(self) -> dict | None:
        try:
            fd = os.open(self.path, os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0))
        except FileNotFoundError:
            return {}
        except OSError:
            return None
        with os.fdopen(fd) as fh:
            try:
                data = json.loads(fh.read(4096))
                return data if isinstance(data, dict) else None
            except ValueError:
                return None

    def acquire(self) -> "OutputLock":
        for _ in range(3):
            try:
                fd = os.open(self.path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_NOFOLLOW", 0), 0o644)
            except FileExistsError:
                if self.path.is_symlink():
                    raise UserInputError(f"{self.path}: is a symbolic link (not followed); remove it if no hpsim run "
                                         f"is writing {self.out}") from None
                holder = self._holder()
                if holder == {}:
                    continue                       # removed in between: try again
                host = socket.gethostname()
                if holder is None or (holder.get("host") == host and not _pid_alive(int(holder.get("pid", -1)))):
                    remove_stale(self.path)        # the writer is gone (or the lock is unreadable): stale
                    continue
                raise UserInputError(
                    f"{self.out}: being written by another hpsim process (pid {holder.get('pid')} on "
                    f"{holder.get('host')}, since {holder.get('started', '?')}); wait for it to finish or stop it "
                    f"(lock file {self.path})") from None
            except FileNotFoundError:
                raise UserInputError(f"{self.out}: the folder {self.out.parent} does not exist") from None
            except (PermissionError, IsADirectoryError) as exc:
                raise UserInputError(f"{self.out}: cannot write in {self.out.parent} ({exc.strerror})") from None
            with os.fdopen(fd, "w") as fh:
                json.dump({"pid": os.getpid(), "host": socket.gethostname(), "started": _now()}, fh)
            self.held = True
            return self
        raise UserInputError(f"{self.out}: cannot take the lock file {self.path} (another process keeps changing it)")

    def release(self) -> None:
        if self.held:
            holder = self._holder()
            if holder and holder.get("pid") == os.getpid():
                remove_stale(self.path)
            self.held = False

    def __enter__(self):
        return self.acquire()

    def __exit__(self, *exc):
        self.release()


# --- running a scenario into a file ------------------------------------------------------------------
class RunInterrupted(Exception):
    """Ctrl-C during a run: the file is closed and readable; message says how far it got."""

    def __init__(self, message: str, path: Path):
        super().__init__(message)
        self.path = path


class NoRoomError(SimulationError):
    """A full disk, a quota or the file-size limit met while writing a results file (exit 3, the file named)."""


@contextlib.contextmanager
def _room_for(out: Path, what: str | Callable[[], str], then: str):
    """A write inside the block that finds no room raises NoRoomError: one line naming the file, why, where the run
    was (`what`, or what it returns when called then), the remedy and what to do `then`."""
    try:
        yield
    except (OSError, RuntimeError) as exc:
        no_room = out_of_space(exc)
        if no_room is None:
            raise
        where = what() if callable(what) else what
        with h5py_releases_quietly():     # the failed write's finished frames hold h5py handles: let go of them here
            traceback.clear_frames(exc.__traceback__)
        raise NoRoomError(f"{out}: {no_room.reason} {where}; {no_room.remedy} and {then}") from None


def inspect_results(path: str | Path) -> tuple[str, int]:
    """(status, format version) of a results file, after checking all of it; DamagedResults if it is damaged."""
    return DriveFile(path).status()


def results_status(path: str | Path) -> str | None:
    """'complete', 'running' (or killed), 'interrupted', 'failed'; None if no readable results file."""
    path = Path(path)
    if not path.exists():
        return None
    try:
        return inspect_results(path)[0]
    except UserInputError:
        return None


def run_scenario(scenario: str | Path | ScenarioSource | None, out: str | Path, *, resume: bool = False,
                 overwrite: bool = False, progress: bool = True, log: Callable[[str], None] | None = None,
                 checkpoint_every_blocks: int = 1, cancel: CancelToken | None = None,
                 make_solver: Callable[[float], object] | None = None, shared=None) -> dict:
    """Run a scenario into an HDF5 file; returns the summary attributes.

    cancel: a token whose request stops the drive at its next checkpoint (a study's scheduler, a worker whose
    parent died); Ctrl-C requests it too. Raises UserInputError (bad scenario, file exists, damaged, locked, cannot
    resume), SimulationError (solver failure after writing status 'failed'; no room on the disk) or RunInterrupted
    (a stop requested, status 'interrupted'). make_solver(dt): the solver of a full drive (an ensemble lane's,
    `vehicle.engines.build.build_engine`); None: the compiled ROS2. `shared`: the parts shared with a study's other
    drives in this process (`vehicle.engines.shared_builds.SharedBuilds`); None: all built for this drive.
    """
    log = log or (lambda msg: None)
    cancel = cancel if cancel is not None else CancelToken()
    t_start, compiled_before = time.perf_counter(), compile_time.compiled_s
    beside(code_version)             # `git describe` (a child process) looked up while the scenario is prepared
    out = Path(out)
    if resume and overwrite:
        raise UserInputError(f"{out}: --resume and --overwrite together: --resume continues the run in the file, "
                             "--overwrite throws it away; give one of them")
    src = scenario if isinstance(scenario, ScenarioSource) else (
        timed("reading", read_scenario, scenario) if scenario is not None else None)
    prepared, refusal = _prepare_kept(src)
    _check_output(out, src, prepared)
    results = DriveFile(out)
    with OutputLock(out):
        if out.exists() and not overwrite:
            _resumable(results, out, resume)
            return _resume(results, src, progress, log, checkpoint_every_blocks, cancel, make_solver, shared)
        if src is None:
            raise UserInputError(f"{out}: not found and no scenario given")
        if resume:
            log(f"{out}: nothing to resume, starting")
        if refusal is not None:                         # every check before any work
            raise refusal
        prep = prepared
        model, drive = build_engine(prep, make_solver, shared)
        info = run_info(src, prep, model, drive, drive.initial_equilibrium())
        block, row, state = drive.describe()
        if prep.work.get("announce"):
            log(prep.work["announce"])               # a long run says so up front (vehicle.scenario.work_limits)
        with _room_for(out, "before the drive started", "run again"):
            results.create(info, block, row, state, prep.scenario.output.stored(), prep.scenario.output.compression,
                           chunk_rows(prep.scenario))
        summary = _drive(drive, results, ResumePoint.start(), prep, progress, log, checkpoint_every_blocks, cancel)
        # this machine's drive rate and the run's set-up (all but the drive), for the cost previews of studies; not
        # from an ensemble lane, whose wall is its whole group's. The rate counts the steps the drive integrates: a
        # multiscale drive's windows (as the preview counts them, vehicle.studies.cost); a time-parallel scenario
        # too short for two segments drove as a full drive
        if make_solver is None:
            mode = "full" if drive.mode == "full" else drive_rate.mode_of(prep.scenario)
            integrated = (integrated_time_s(prep.settings(), prep.scenario.solver.multiscale_settings())
                          if mode == "multiscale" else summary["simulated_s"])
            drive_rate.record(mode, prep.scenario.solver.dt, integrated,
                              summary["wall_s"], time.perf_counter() - t_start - summary["wall_s"],
                              compiled_s=compile_time.compiled_s - compiled_before)
        return summary


def _resumable(results: DriveFile, out: Path, resume: bool) -> None:
    """Whether the existing file `out` may be continued: returns when --resume was given and the file can be
    resumed (or is complete); otherwise raises UserInputError saying what to do."""
    try:
        status, version = results.status_to_resume() if resume else results.status()
    except UserInputError as exc:
        raise type(exc)(f"{exc}; the file was not touched: start again with --overwrite or -o another "
                        "file") from None
    if resume:
        if status != "complete" and version < FORMAT_VERSION:
            raise UserInputError(f"{out}: written by an older hpsim (results format {version}); it can be "
                                 "read (report, plot, compare) but not resumed: run it again with --overwrite")
        return
    hint = "--resume to continue it or " if status != "complete" else ""
    raise UserInputError(f"{out}: exists (status {status}); use {hint}--overwrite to start again, or -o "
                         "another file")


def _prepare_kept(src: ScenarioSource | None) -> tuple:
    """(the prepared scenario or None, its refusal or None): prepared once, for the output's check (its input files)
    and the drive; a refusal is raised after the output's own checks, where a run checks its scenario."""
    if src is None:
        return None, None
    try:
        return timed("scenario checks", prepare, src), None
    except UserInputError as exc:
        return None, exc


def _check_output(out: Path, src: ScenarioSource | None, prep=None) -> None:
    """Refuse an output that is one of the scenario's inputs, a folder or not a regular file; make its folder.
    prep: `src` prepared (None: it could not be, and its own file is the one input known)."""
    if src is not None:
        # never replace an input, --overwrite or not: the same check and message as every command's outputs
        timed("output checked against the inputs", check_not_input, out, "-o/--output",
              provenance.run_inputs(src, prep))
    if out.is_dir():
        raise UserInputError(f"{out}: is a directory; give a file name with -o")
    if out.exists() and not out.is_file():
        raise UserInputError(f"{out}: is not a regular file")
    if not out.parent.exists():
        out.parent.mkdir(parents=True, exist_ok=True)


def _resume(results: DriveFile, src: ScenarioSource | None, progress, log, checkpoint_every_blocks,
            cancel: CancelToken, make_solver: Callable[[float], object] | None, shared=None) -> dict:
    out = results.path
    stored_run = results.stored_run()
    sc = stored_run.scenario_attrs
    stored = read_scenario_text(str(sc["yaml"]), str(sc.get("source", out)), str(sc.get("base_dir", out.resolve().parent)))
    stored_version = str(sc.get("hpsim_version", ""))
    stored_inputs = sc.get("inputs_json")
    if src is not None and src.text != stored.text:
        raise UserInputError(f"{out}: the scenario {src.name} differs from the one this run started with "
                             "(stored in the file); resume without changing it, or start again with --overwrite")
    if stored_run.complete and stored_inputs is None:           # written before input hashes were recorded
        log(f"{out}: already complete, nothing to do")
        return stored_run.summary_attrs
    prep = prepare(stored)
    provenance.compare(None if stored_inputs is None else str(stored_inputs), prep, out)   # no input file changed
    if stored_run.complete:
        log(f"{out}: already complete, nothing to do")
        return stored_run.summary_attrs
    if stored_version and stored_version != code_version():
        log(f"{out}: warning: the run started with hpsim {stored_version}, resuming with {code_version()}; "
            "if the model changed in between, the result differs from an uninterrupted run")
    point = stored_run.resume_point
    with _room_for(out, "while preparing the resume (the file was not changed)", "resume again"):
        results.truncate_for_resume(point)      # first: a full disk is found before the model is built
    model, drive = build_engine(prep, make_solver, shared)
    state = None if point.state is None else DriveState.from_dict(point.state)
    if state is not None and state.x.size != model.nx:
        raise UserInputError(f"{out}: its checkpoint holds {state.x.size} states, this hpsim's model has {model.nx} "
                             f"(the model changed since the run started with hpsim {stored_version or '?'}, e.g. the "
                             "ride-metric states); it can be read but not resumed: run it again with --overwrite")
    if state is not None:
        log(f"{out}: resuming at {state.s_m / 1e3:.3f} km of {prep.scenario.distance / 1e3:.6g} km")
    return _drive(drive, results, point, prep, progress, log, checkpoint_every_blocks, cancel)


class _StopAtOnce(KeyboardInterrupt):
    """A second Ctrl-C: raised wherever the drive is, between a block's samples and its checkpoint perhaps."""


SAME_CTRL_C_S = 1.0      # SIGINTs this close together are one Ctrl-C (a study's worker gets it from the terminal
#                          and again from its parent, vehicle.engines.pool.stop_workers)


@contextlib.contextmanager
def _ctrl_c_requests(cancel: CancelToken):
    """First Ctrl-C: request `cancel` (the drive stops after its next checkpoint; a KeyboardInterrupt raised at an
    arbitrary point can be swallowed by a weakref callback inside h5py); a second one, more than SAME_CTRL_C_S
    later: stop at once. Outside the main thread (a Dask worker, an ensemble lane) signals are left alone."""
    first: list[float] = []

    def handler(signum, frame):
        now = time.monotonic()
        if cancel.requested and first and now - first[0] > SAME_CTRL_C_S:
            raise _StopAtOnce
        if not first:
            first.append(now)
        cancel.request()

    try:
        old = signal.signal(signal.SIGINT, handler)
    except ValueError:
        old = None
    try:
        yield
    finally:
        if old is not None:
            signal.signal(signal.SIGINT, old)


def chunk_rows(scenario) -> int:
    """Samples per HDF5 chunk (and between checkpoints): output.chunk_samples rounded up to whole
    blocks of solver.samples_per_block."""
    M = scenario.solver.samples_per_block
    return int(M * max(1, -(-scenario.output.chunk_samples // M)))


class _ProgressBar:
    """The drive's progress in km on the terminal (tqdm), or nothing."""

    def __init__(self, shown: bool, name: str, total_km: float, start_km: float):
        self.total_km = total_km
        self.bar = None
        if shown:
            from tqdm import tqdm

            self.bar = tqdm(total=round(total_km, 3), initial=round(start_km, 3), unit="km", desc=name,
                            bar_format="{desc}: {percentage:3.0f}%|{bar}| {n:.2f}/{total:.2f} km "
                                       "[{elapsed}<{remaining}{postfix}]",
                            dynamic_ncols=True, mininterval=0.5)

    def callback(self):
        if self.bar is None:
            return None

        def cb(s_m, v, t_s):
            self.bar.update(round(min(s_m / 1e3, self.total_km), 3) - self.bar.n)
            self.bar.set_postfix_str(f"{v * 3.6:.1f} km/h, simulated {t_s / 3600:.2f} h", refresh=False)
        return cb

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
            self.bar = None


def _held_until_cancelled(progress, sink, cancel: CancelToken):
    """The drive's progress callback; test hook: HPSIM_FAULT=hold_until_cancelled writes the rows so far and their
    checkpoint after the first block, then holds the drive there until `cancel` is requested, so that a test
    interrupts a drive certain to be running."""
    if os.environ.get("HPSIM_FAULT") != "hold_until_cancelled":
        return progress

    def held(s_m, v, t_s):
        if progress is not None:
            progress(s_m, v, t_s)
        sink.flush()
        while not cancel.requested:
            time.sleep(0.02)
    return held


def _drive(drive, results: DriveFile, point: ResumePoint, prep, progress: bool, log, checkpoint_every_blocks,
           cancel: CancelToken) -> dict:
    out = results.path
    total_km = prep.scenario.distance / 1e3
    resume_cmd = f"hpsim run {prep.source.name} -o {out} " + ("--resume" if getattr(drive, "resumable", True) else
                                                              f"--overwrite (a {drive.mode} run starts again)")
    state = None if point.state is None else DriveState.from_dict(point.state)
    bar = _ProgressBar(progress, out.name, total_km, 0.0 if state is None else state.s_m / 1e3)
    sink = None

    def km_done():
        return sink.last_state["s_m"] / 1e3 if sink and sink.last_state else (state.s_m / 1e3 if state else 0.0)

    def wall_s():
        return sink.wall_s() if sink else point.wall_s

    then = f"continue with: {resume_cmd}"
    try:
        with _room_for(out, "when the drive started", then):
            sink = results.open_sink(point)
        with _room_for(out, lambda: f"at {km_done():.3f} km (the results up to the last checkpoint are kept)", then), \
                _ctrl_c_requests(cancel):
            progress_cb = _held_until_cancelled(bar.callback(), sink, cancel)
            res = timed("drive", drive.run, sink, state=state, progress=progress_cb,
                        checkpoint_every_blocks=checkpoint_every_blocks, cancel=cancel)
            where, wall = km_done(), wall_s()
            results.close_sink()
    except NoRoomError:
        results.abandon_sink()
        bar.close()
        raise
    except SimulationError as exc:
        try:
            results.close_sink()              # the blocks before the failure, with their checkpoint
        except (OSError, RuntimeError):
            pass
        bar.close()
        where = km_done()
        results.set_status("failed", error=str(exc), wall_s=wall_s(), stopped_at_km=float(where))
        raise SimulationError(f"{exc} (results up to {where:.3f} km kept in {out})") from None
    except KeyboardInterrupt as exc:
        # an engine that stops on `cancel` by raising does so right after a checkpoint: what the sink holds is
        # consistent and is written; any other interruption (a second Ctrl-C) keeps the last written checkpoint
        if cancel.requested and not isinstance(exc, _StopAtOnce):
            with contextlib.suppress(OSError, RuntimeError):
                results.close_sink()
        results.abandon_sink()
        bar.close()
        return _stopped(results, km_done(), wall_s(), total_km, resume_cmd)
    except BaseException:
        results.abandon_sink()
        bar.close()
        raise
    bar.close()
    if cancel.requested:
        return _stopped(results, where, wall, total_km, resume_cmd)
    return _finish(results, drive, res, sink, then)


def _finish(results: DriveFile, drive, res, sink, then: str) -> dict:
    """The after-drive equilibrium, the summary and the validity warnings written into the file; the summary."""
    fault_point("before_final_write")
    final = timed("summary", final_info, drive, res, sink.n_samples, sink.n_stats, sink.wall_s())
    with _room_for(results.path, "while writing the summary", then):
        # the validity warnings are read from the finished copy and recorded in it (/summary attrs) before it
        # replaces the file
        timed("summary: write", results.finish, final,
              lambda f: timed("summary: validity checks", summary_warnings_of, ResultsFile(results.path, f)))
    return {k: v for k, v in final["summary"].items()}


def _stopped(results: DriveFile, where_km: float, wall_s: float, total_km: float, resume_cmd: str):
    """A drive stopped on request: status 'interrupted' recorded, RunInterrupted raised (the file is resumable)."""
    results.set_status("interrupted", wall_s=wall_s, stopped_at_km=float(where_km))
    raise RunInterrupted(f"interrupted at {where_km:.3f} km of {total_km:.6g} km; {results.path} holds what was "
                         f"done. Continue with: {resume_cmd}", results.path)
