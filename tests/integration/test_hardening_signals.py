"""Issue 27, signals: SIGTERM while the model compiles stops the compilers too; Ctrl-C pressed twice during a sweep
ends it at once (exit 130, no worker left), and the interrupted sweep then resumes to the end."""
from __future__ import annotations

import os
import signal
import time

import psutil

from tests.integration.test_fuzz import SCENARIO, _hpsim_process, _wait_for
from tests.helpers import run_hpsim


def _compilers(proc) -> list:
    """The compilers anywhere on the machine that build in this test's cache (their own session)."""
    out = []
    for p in psutil.process_iter(["name", "cwd"]):
        try:
            if p.info["name"] in ("cc1", "cc1plus", "as", "cc", "gcc", "clang") and str(proc) in (p.info["cwd"] or ""):
                out.append(p)
        except psutil.Error:
            pass
    return out


def test_sigterm_while_the_model_compiles_stops_the_compilers(tmp_path):
    (tmp_path / "s.yaml").write_text(SCENARIO)
    cache = tmp_path / "cache"          # empty: the model is compiled
    proc = _hpsim_process(["run", "s.yaml", "-o", "out.h5", "--no-progress"], tmp_path, {"HPSIM_CACHE": str(cache)})
    assert _wait_for(proc, lambda: bool(_compilers(cache))), "the compiler never started"
    proc.send_signal(signal.SIGTERM)                  # to hpsim only: its compilers run in their own session
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 143, (proc.returncode, err[-2000:])
    # the one line of the interrupt, after the announcement of the compile it interrupted (issue 20)
    lines = [ln for ln in err.strip().splitlines() if not ln.startswith("compiling the vehicle model")]
    assert lines == ["hpsim run: terminated (SIGTERM)"], err[-2000:]
    deadline = time.monotonic() + 10
    while _compilers(cache) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not _compilers(cache), "compilers left running"
    assert not list(cache.glob(".build-*"))


SWEEP = "base: s.yaml\noverrides: {distance: 0.3 km}\ngrid:\n  ambient_temperature: [20 degC, 30 degC, 40 degC]\n"


def test_ctrl_c_twice_ends_a_sweep_at_once_and_it_resumes(tmp_path):
    (tmp_path / "s.yaml").write_text(SCENARIO)
    (tmp_path / "w.yaml").write_text(SWEEP)
    args = ["sweep", "w.yaml", "-o", "sw", "--workers", "2"]
    proc = _hpsim_process(args, tmp_path, {})
    me = psutil.Process(proc.pid)
    assert _wait_for(proc, lambda: bool(list((tmp_path / "sw").glob("*.h5"))), timeout=120)
    workers = [c.pid for c in me.children(recursive=True)]
    os.killpg(proc.pid, signal.SIGINT)
    time.sleep(0.3)
    os.killpg(proc.pid, signal.SIGINT)
    t0 = time.monotonic()
    out, err = proc.communicate(timeout=30)
    assert time.monotonic() - t0 < 20
    assert proc.returncode == 130, (proc.returncode, err[-2000:])
    assert "Traceback" not in err
    assert not [p for p in workers if psutil.pid_exists(p) and psutil.Process(p).status() != psutil.STATUS_ZOMBIE]
    # the same command again (in one process: quicker here) resumes the interrupted cases and runs the rest
    res = run_hpsim(args[:-1] + ["1"], cwd=tmp_path, timeout=240)
    assert res.returncode == 0, res.stderr[-2000:]
    assert len(list((tmp_path / "sw").glob("*.h5"))) == 3
    import h5py

    for f in (tmp_path / "sw").glob("*.h5"):
        with h5py.File(f, "r") as h:
            assert h["summary"].attrs["status"] == "complete"
