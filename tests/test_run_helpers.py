"""Shared helpers of the run/sweep/report tests (no tests here)."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SCENARIOS = REPO / "scenarios"


def hpsim_subprocess(args: list[str], cwd=None, env=None, **kw) -> subprocess.Popen:
    """`hpsim ARGS` in a new Python process."""
    e = dict(os.environ)
    e.update(env or {})
    return subprocess.Popen([sys.executable, "-m", "vehicle.cli", *map(str, args)], cwd=cwd, env=e, **kw)


def run_hpsim(args: list[str], cwd=None, timeout=300, env=None) -> subprocess.CompletedProcess:
    p = hpsim_subprocess(args, cwd=cwd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    out, err = p.communicate(timeout=timeout)
    return subprocess.CompletedProcess(p.args, p.returncode, out, err)
