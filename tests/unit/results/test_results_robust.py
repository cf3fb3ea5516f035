"""Robust reading and writing of results files (issue 13): damaged, truncated, foreign and partial files
fail fast with exit 2 and one line naming the file and the damage (never a hang: each under a timeout);
`--resume` refuses a damaged file untouched; a kill during the final write, a full disk, a second
writer, and symbolic links at the temporary paths are all handled."""
from __future__ import annotations

import errno
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest

from vehicle import cli

from tests.helpers import scenario_yaml, run_hpsim

SCENARIO = scenario_yaml(road={"iso_class": "D", "seed": 8}, distance="0.5 km",
                         initial_temperatures=["40 degC", "35 degC", "30 degC", "25 degC"],
                         output={"interval": "1 s", "stats_interval": "0.1 km", "chunk_samples": 20})
TIMEOUT = 60        # every command must end well within this (a hang fails the test)


@pytest.fixture(scope="module")
def work(tmp_path_factory):
    d = tmp_path_factory.mktemp("robust")
    (d / "drive.yaml").write_text(SCENARIO)
    ref = d / "ref.h5"
    assert cli.main(["run", str(d / "drive.yaml"), "-o", str(ref), "--no-progress"]) == 0
    return d, ref


def _values(path: Path) -> dict:
    with h5py.File(path, "r") as f:
        out = {}
        for g in ("timeseries", "stats", "equilibrium/before", "equilibrium/before_band", "equilibrium/after",
                  "equilibrium/after_band", "summary"):
            for k, ds in f[g].items():
                out[f"{g}/{k}"] = ds[()]
        out["status"] = f["summary"].attrs["status"]
    return out


def assert_same(a: Path, b: Path):
    va, vb = _values(a), _values(b)
    assert set(va) == set(vb)
    for k in va:
        np.testing.assert_array_equal(va[k], vb[k], err_msg=k)


class _Result:
    def __init__(self, returncode, stdout, stderr):
        self.returncode, self.stdout, self.stderr = returncode, stdout, stderr


def hpsim(capsys, args, seconds=TIMEOUT) -> _Result:
    """`hpsim ARGS` in this process, failing the test if it does not end within `seconds` (the reading
    of a file happens in a child process under its own time limit, so nothing here can block in C)."""
    def expired(signum, frame):
        raise AssertionError(f"hpsim {' '.join(map(str, args))}: no answer within {seconds} s")

    capsys.readouterr()
    old = signal.signal(signal.SIGALRM, expired)
    signal.alarm(seconds)
    try:
        code = cli.main([str(a) for a in args])
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)
    out, err = capsys.readouterr()
    return _Result(code, out, err)


def _one_line_exit_2(r, path):
    assert r.returncode == 2, (r.returncode, r.stderr)
    assert "Traceback" not in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert str(path) in r.stderr


def _flip(src: Path, dst: Path, offset: int, n: int = 8) -> Path:
    shutil.copy(src, dst)
    with open(dst, "r+b") as fh:
        fh.seek(offset)
        b = fh.read(n)
        fh.seek(offset)
        fh.write(bytes(x ^ 0xFF for x in b))
    return dst


def test_damaged_files_fail_fast_with_one_line(work, capsys):
    d, ref = work
    size = ref.stat().st_size
    with h5py.File(ref, "r") as f:
        chunk = f["timeseries/wheel_load"].id.get_chunk_info(0).byte_offset
    cases = {"signature": _flip(ref, d / "sig.h5", 0),
             "chunk": _flip(ref, d / "chunk.h5", chunk + 40),
             "truncated": d / "trunc.h5", "text": d / "text.h5"}
    shutil.copy(ref, cases["truncated"])
    os.truncate(cases["truncated"], size // 2)
    cases["text"].write_text("not a results file\n")
    expect = {"signature": "not an HDF5 file", "chunk": "/timeseries/wheel_load", "truncated": "truncated",
              "text": "not an HDF5 file"}
    for name, path in cases.items():
        for cmd in (["report", path], ["plot", path, "-o", d / "x.png"], ["compare", ref, path]):
            r = hpsim(capsys, cmd)
            _one_line_exit_2(r, path)
            assert expect[name] in r.stderr and "damaged" in r.stderr, (name, r.stderr)
    # the real command line, in its own process
    r = run_hpsim(["report", cases["chunk"]], timeout=TIMEOUT)
    _one_line_exit_2(r, cases["chunk"])
    # flipped bytes anywhere: a clean exit (0 if the bytes were unused, else 2 naming the damage), no traceback
    for off in (24, 200, 1000, 5000, size // 3, size // 2, size - 600):
        path = _flip(ref, d / f"flip{off}.h5", off)
        r = hpsim(capsys, ["report", path])
        assert r.returncode in (0, 2) and "Traceback" not in r.stderr, (off, r.stderr)
        if r.returncode == 2:
            assert str(path) in r.stderr and len(r.stderr.strip().splitlines()) == 1


def test_resume_refuses_a_damaged_file_without_touching_it(work, capsys):
    d, ref = work
    path = _flip(ref, d / "resume_damaged.h5", 0)
    before = (path.read_bytes(), path.stat().st_mtime_ns)
    r = hpsim(capsys, ["run", d / "drive.yaml", "-o", path, "--resume", "--no-progress"])
    _one_line_exit_2(r, path)
    assert "not touched" in r.stderr and "--overwrite" in r.stderr
    assert (path.read_bytes(), path.stat().st_mtime_ns) == before
    assert not [p for p in d.iterdir() if p.name.startswith("resume_damaged.h5.")]


def test_a_read_that_never_ends_is_cut_off(work, capsys, monkeypatch):
    d, ref = work
    monkeypatch.setenv("HPSIM_FAULT", "read_hang")
    monkeypatch.setenv("HPSIM_READ_TIMEOUT", "2")
    r = hpsim(capsys, ["report", ref])
    _one_line_exit_2(r, ref)
    assert "did not finish within 2 s" in r.stderr


def test_hdf5_files_that_are_not_or_not_complete_results(work, capsys):
    d, ref = work
    foreign = d / "foreign.h5"
    with h5py.File(foreign, "w") as f:
        f["x"] = 1
    assert cli.main(["report", str(foreign)]) == 2
    assert "not an hpsim results file" in capsys.readouterr().err
    for what, edit in (("axles", lambda f: f["scenario"].attrs.__delitem__("axles")),
                       ("/scenario", lambda f: f.__delitem__("scenario")),
                       ("/equilibrium/before", lambda f: f["equilibrium"].__delitem__("before"))):
        partial = d / "partial.h5"
        shutil.copy(ref, partial)
        with h5py.File(partial, "r+") as f:
            edit(f)
        for cmd in (["report", str(partial)], ["plot", str(partial), "-o", str(d / "p.png")]):
            assert cli.main(cmd) == 2
            err = capsys.readouterr().err
            assert what in err and str(partial) in err and "incomplete" in err and len(err.strip().splitlines()) == 1


def test_a_kill_during_the_final_write_leaves_a_file_that_resumes(work, capsys):
    d, ref = work
    out = d / "final_kill.h5"
    for point in ("during_final_write",):        # killed with the copy holding the after-drive equilibrium
        r = run_hpsim(["run", d / "drive.yaml", "-o", out, "--no-progress", "--overwrite"], timeout=TIMEOUT * 2,
                      env={"HPSIM_FAULT": point})
        assert r.returncode == -signal.SIGKILL, r.stderr
        rep = hpsim(capsys, ["report", out, "--json"])
        assert rep.returncode == 0, rep.stderr
        assert json.loads(rep.stdout)["status"] == "running"
        r = hpsim(capsys, ["run", d / "drive.yaml", "-o", out, "--resume", "--no-progress"])
        assert r.returncode == 0, r.stderr
        assert_same(ref, out)
        assert not [p for p in d.iterdir() if p.name.startswith("final_kill.h5.")]   # no .final, .lock left


def test_full_disk_says_so_keeps_a_readable_file_and_resumes(work, monkeypatch, capsys):
    from vehicle.results import sinks

    d, ref = work
    out = d / "full.h5"
    real = sinks.H5Sink._append
    calls = {"n": 0}

    def append(self, ds, start, rows):
        calls["n"] += 1
        if start >= 40:                      # the disk fills up after two chunks
            raise OSError(errno.ENOSPC, "No space left on device")
        real(self, ds, start, rows)

    monkeypatch.setattr(sinks.H5Sink, "_append", append)
    assert cli.main(["run", str(d / "drive.yaml"), "-o", str(out), "--no-progress"]) == 3
    err = capsys.readouterr().err
    assert "disk full" in err and "--resume" in err and len(err.strip().splitlines()) == 1
    rep = hpsim(capsys, ["report", out, "--json"])
    assert rep.returncode == 0, rep.stderr
    assert json.loads(rep.stdout)["n_samples"] == 40
    # resuming on the still-full disk: disk full again, the file unchanged, no 0-byte .resume left
    before = out.read_bytes()

    def full_clone(*a, **kw):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr("vehicle.results.layout.clone_group", full_clone)
    assert cli.main(["run", str(d / "drive.yaml"), "-o", str(out), "--resume", "--no-progress"]) == 3
    assert "disk full" in capsys.readouterr().err
    assert out.read_bytes() == before and not (d / "full.h5.resume").exists()
    # space freed: resume completes to the uninterrupted result
    monkeypatch.undo()
    assert cli.main(["run", str(d / "drive.yaml"), "-o", str(out), "--resume", "--no-progress"]) == 0
    assert_same(ref, out)


class _RequestedAfter:
    """A cancellation token requested from its n-th reading on (the drive reads it once per checkpointed block)."""

    def __init__(self, n: int):
        self.n, self.reads = n, 0

    def request(self) -> None:
        self.reads = self.n

    @property
    def requested(self) -> bool:
        self.reads += 1
        return self.reads >= self.n


def test_a_requested_stop_ends_the_drive_at_a_checkpoint_and_it_resumes(work):
    """The token passed to run_scenario stops the drive after the block at which it is requested: status
    interrupted, the rows up to that checkpoint kept (no exception raised from the sink), and --resume completes the
    file to the uninterrupted result, weighing bands included."""
    from vehicle.results.reader import open_results
    from vehicle.results.run import RunInterrupted, run_scenario

    d, ref = work
    out = d / "cancelled.h5"
    with pytest.raises(RunInterrupted) as info:
        run_scenario(d / "drive.yaml", out, progress=False, cancel=_RequestedAfter(5))
    assert "--resume" in str(info.value)
    with open_results(out) as r:
        assert r.status() == "interrupted"
        n_samples, _ = r.counts()
        km = r.state()["s_m"] / 1e3
    with open_results(ref) as r:
        total = r.counts()[0]
    assert 0 < n_samples < total and 0 < km < 0.5
    assert run_scenario(d / "drive.yaml", out, resume=True, progress=False)["status"] == "complete"
    assert_same(ref, out)


@pytest.mark.parametrize("fraction", [0.45, 0.75])
def test_the_file_size_limit_stops_the_run_cleanly_and_it_resumes(work, capsys, fraction):
    """Under a file-size limit (ulimit -f: EFBIG, errno 27) below the result's size, a run stops as on a full disk:
    one line naming the file and the limit, exit 3, no traceback (h5py's "Exception ignored" included), no crash at
    exit; the limit lifted, --resume completes it to the uninterrupted result (weighing bands included)."""
    import resource

    d, ref = work
    out = d / f"limited_{fraction}.h5"
    limit = int(ref.stat().st_size * fraction)

    def limited():
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

    p = subprocess.run([sys.executable, "-m", "vehicle.cli", "run", str(d / "drive.yaml"), "-o", str(out),
                        "--no-progress"], capture_output=True, text=True, timeout=TIMEOUT * 2, preexec_fn=limited)
    assert p.returncode == 3, p.stderr[-2000:]
    assert "Traceback" not in p.stderr and "Exception ignored" not in p.stderr, p.stderr[-2000:]
    assert len(p.stderr.strip().splitlines()) == 1, p.stderr
    assert str(out) in p.stderr and "file too large" in p.stderr and "ulimit -f" in p.stderr and "--resume" in p.stderr
    r = hpsim(capsys, ["run", d / "drive.yaml", "-o", out, "--resume", "--no-progress"])
    assert r.returncode == 0, r.stderr
    assert_same(ref, out)
    assert not [q for q in d.iterdir() if q.name.startswith(out.name + ".")]


def test_a_second_writer_is_refused_and_a_stale_lock_taken_over(work, capsys):
    d, ref = work
    out = d / "locked.h5"
    lock = d / "locked.h5.lock"
    holder = subprocess.Popen([sys.executable, "-c", "import sys, time; sys.stdin.read()"], stdin=subprocess.PIPE)
    try:
        lock.write_text(json.dumps({"pid": holder.pid, "host": socket.gethostname(), "started": "now"}))
        for extra in ([], ["--resume"], ["--overwrite"]):
            r = hpsim(capsys, ["run", d / "drive.yaml", "-o", out, "--no-progress", *extra])
            _one_line_exit_2(r, out)
            assert f"pid {holder.pid}" in r.stderr and "another hpsim process" in r.stderr
        assert not out.exists()
    finally:
        holder.stdin.close()
        holder.wait(timeout=TIMEOUT)
    # the holder is gone: its lock is stale and taken over
    r = hpsim(capsys, ["run", d / "drive.yaml", "-o", out, "--no-progress"])
    assert r.returncode == 0, r.stderr
    assert not lock.exists()
    assert_same(ref, out)


def test_links_at_temporary_paths_are_never_followed(work, capsys):
    d, ref = work
    victim = d / "victim.txt"
    victim.write_text("precious\n")
    out = d / "linked.h5"
    (d / "linked.h5.partial").symlink_to(victim)
    assert cli.main(["run", str(d / "drive.yaml"), "-o", str(out), "--no-progress"]) == 0
    assert victim.read_text() == "precious\n" and not (d / "linked.h5.partial").exists()
    # .resume and .final during a resume
    with h5py.File(out, "r+") as f:
        f["summary"].attrs["status"] = "interrupted"
    for suffix in (".resume", ".final"):
        (d / f"linked.h5{suffix}").symlink_to(victim)
    capsys.readouterr()
    assert cli.main(["run", str(d / "drive.yaml"), "-o", str(out), "--resume", "--no-progress"]) == 0
    assert victim.read_text() == "precious\n"
    assert_same(ref, out)
    # a link as the lock file: refused
    (d / "linked.h5.lock").symlink_to(victim)
    assert cli.main(["run", str(d / "drive.yaml"), "-o", str(out), "--overwrite", "--no-progress"]) == 2
    assert "symbolic link" in capsys.readouterr().err and victim.read_text() == "precious\n"


def test_a_reader_holding_a_new_file_does_not_stop_the_run(tmp_path):
    """A reader in another process (hpsim report, a notebook: a plain h5py.File(path, "r")) that opens a results file
    between its creation and the moment the run reopens it to write holds HDF5's file lock: the run opens the file
    without HDF5's lock (issue 27; it used to wait, then fail with "unable to lock file") and goes to SWMR mode."""
    import time

    from vehicle.results.layout import LIBVER
    from vehicle.results.results_file import open_for_append

    path = tmp_path / "run.h5"
    with h5py.File(path, "x", libver=LIBVER) as f:
        f.attrs["format"] = "test"
        f.create_dataset("x", shape=(0,), maxshape=(None,), chunks=(4,), dtype=float)

    code = (f"import h5py, sys, time; f = h5py.File({str(path)!r}, 'r'); print('open', flush=True); "
            "sys.stdin.read(); f.close()")
    p = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, stdin=subprocess.PIPE, text=True)
    try:
        assert p.stdout.readline().strip() == "open"
        t0 = time.monotonic()
        f = open_for_append(path, wait_s=10.0)
        assert time.monotonic() - t0 < 1.0
        f.swmr_mode = True
        f["x"].resize((3,))
        f["x"][:] = [1.0, 2.0, 3.0]
        f.flush()
        f.close()
    finally:
        p.stdin.close()
        p.wait(timeout=TIMEOUT)
    assert p.returncode == 0
    with h5py.File(path, "r") as f:
        np.testing.assert_array_equal(f["x"][:], [1.0, 2.0, 3.0])


def test_a_batch_check_names_the_damaged_file_among_whole_ones(work, monkeypatch):
    """`check_files` reads a study's files in one child process; a damaged one among them is named as
    `check_file` names it, whole ones pass, and a hang is still cut off per file."""
    from vehicle.results.reader import DamagedResults, check_file, check_files

    d, ref = work
    whole = [shutil.copy(ref, d / f"whole{k}.h5") for k in range(3)]
    check_files(whole)                                             # nothing damaged: no error
    size = ref.stat().st_size
    damaged = d / "batch_trunc.h5"
    shutil.copy(ref, damaged)
    os.truncate(damaged, size // 2)
    with pytest.raises(DamagedResults) as batch:
        check_files([whole[0], damaged, whole[1]])
    with pytest.raises(DamagedResults) as alone:
        check_file(damaged)
    assert str(batch.value) == str(alone.value) and str(damaged) in str(batch.value)
    monkeypatch.setenv("HPSIM_FAULT", "read_hang")
    monkeypatch.setenv("HPSIM_READ_TIMEOUT", "1")
    with pytest.raises(DamagedResults, match="did not finish within 1 s"):
        check_files(whole)
