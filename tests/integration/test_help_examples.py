"""Every `hpsim ... --help` ends with examples, and the examples work (issue 20): each one is run here,
as written, in a folder where `scenarios/quick_demo.yaml` and `scenarios/mileage_106km.yaml` are the
shipped scenarios cut to 300 m (the drives are the same code, only shorter). The few that are studies of
many drives are parsed, not run (a uq study is listed: its priors, design and cost checked); each says why
in LONG, and is run by its own tests."""
from __future__ import annotations

import glob
import shlex
import time
from pathlib import Path

import pytest

from vehicle import cli
from vehicle.cli import examples
from tests.helpers import MEASUREMENT_POINTS, REPO

ROOT = REPO

# examples parsed (arguments checked) but not run: studies of many drives, each covered by its own tests
LONG = {
    "hpsim strut fit": "a fit of the rig model to the measured energies (tests/test_fit*.py)",
    "hpsim run scenarios/mileage_106km.yaml -o mileage.h5 --time-parallel 2": "two processes (tests/test_time_parallel.py)",
    "hpsim sweep": "four drives of the compensation sweep (tests/test_sweep.py, tests/test_study_cost.py)",
    "hpsim calibrate": "several drives and the noise probe (tests/test_calibration.py)",
    "hpsim uq scenarios/quick_demo.yaml --method lhs": "nine 1 km drives (tests/test_uq.py)",
    "hpsim uq scenarios/quick_demo.yaml --samples 16 --workers 2": "833 drives (the example says: hours)",
    "hpsim report quick_sweep/": "a sweep folder (tests/integration/test_html_report.py reports one)",
    "hpsim animate demo.h5 -o drive.gif --from 1km": "a drive of 1.2 km stored densely (test_html_report.py animates one)",
    "hpsim animate demo.h5 -o drive.mp4": "ffmpeg, where installed",
    "hpsim validate mileage_uq": "a uq study folder (tests/unit/studies/test_validate.py validates one)",
    "hpsim export fmu": "an FMU's C compiled (tests/integration/test_fmu.py builds and runs both kinds)",
    "hpsim strut identify": "rig loops of fifteen tests (tests/unit/struts/test_identify.py identifies loops)",
    "hpsim optimize": "a study of 24 trials of two drives (tests/integration/test_optimize_cli.py runs a small one)",
    "hpsim report strut_opt": "an optimisation folder (tests/integration/test_optimize_cli.py reports one)",
}


def _example_lines():
    parser = cli.build_parser()
    for path, p in examples.parsers(parser):
        text = p.epilog or ""
        for line in text.split("examples:\n", 1)[-1].splitlines():
            line = line.strip()
            if line.startswith("hpsim"):
                yield path, line


def _argv(line: str) -> list[str]:
    words = shlex.split(line.split(" | ")[0], comments=True)     # the hpsim part of a pipe
    assert words[0] == "hpsim"
    out = []
    for w in words[1:]:                                           # the shell's glob of results files
        out += (sorted(glob.glob(w)) or [w]) if "*" in w and w.endswith(".h5") else [w]
    return out


def test_every_help_ends_with_examples():
    parser = cli.build_parser()
    found = list(examples.parsers(parser))
    assert {"", "strut", "road", "vehicle"} <= {path for path, _ in found}
    for path, p in found:
        text = p.format_help().rstrip("\n")
        tail = text.split("\nexamples:\n")
        assert len(tail) == 2, path or "hpsim"
        lines = [line.strip() for line in tail[1].splitlines() if line.strip()]
        assert lines and lines[-1].startswith(("hpsim", "(")) and all(
            line.startswith(("hpsim", "(")) for line in lines), (path, lines)      # nothing after the examples
        assert all(line.startswith(f"hpsim {path}".rstrip()) for line in lines if line.startswith("hpsim")
                   and path in ("strut", "road", "vehicle")), path


OUTPUT_OPTIONS = ("-o", "--output", "--plot", "--html", "--pdf", "--psd")


@pytest.fixture(scope="module")
def workdir(tmp_path_factory):
    d = tmp_path_factory.mktemp("examples")
    (d / "scenarios").mkdir()
    for name, distance in (("quick_demo.yaml", "distance: 5 km"), ("mileage_106km.yaml", "distance: 106 km")):
        text = (ROOT / "scenarios" / name).read_text()
        assert distance in text
        (d / "scenarios" / name).write_text(text.replace(distance, "distance: 300 m"))
    (d / "struts").symlink_to(ROOT / "struts")        # struts/data/apc_rig_energy.csv, as from the repository root
    # the user's own files the examples name: a road surface (OpenCRG), a vehicle and a strut file
    (d / "track.crg").write_bytes((ROOT / "examples" / "track_class_C.crg").read_bytes())
    (d / "my_truck.yaml").write_text((ROOT / "vehicle" / "data" / "truck_6x6.yaml").read_text())
    (d / "my_strut.yaml").write_text((ROOT / "struts" / "data" / "apc.yaml").read_text())
    (d / "test.yaml").write_text(MEASUREMENT_POINTS)                 # the measurement file of docs/measurements.md
    return d


@pytest.mark.slow      # ~40 commands, four 300 m drives among them
def test_the_examples_run(workdir, monkeypatch, capsys):
    monkeypatch.chdir(workdir)
    # the same command shown at two levels (hpsim --help and hpsim run --help) runs once, as a user would
    lines = list({tuple(_argv(line)): line for _, line in reversed(list(_example_lines()))}.values())[::-1]
    # the results files the report/compare/plot examples read come from the run examples: runs first
    lines.sort(key=lambda line: (not line.startswith(("hpsim run", "hpsim road generate", "hpsim strut cycle")),
                                 "--data" in line))
    timings, failures = {}, []
    for line in lines:
        if line.startswith(("hpsim compare", "hpsim validate")):   # a.h5, b.h5, results/*.h5: copies of demo.h5
            Path("results").mkdir(exist_ok=True)
            for name in ("a.h5", "b.h5", "results/demo.h5", "results/mileage_106km.h5"):
                if not Path(name).exists():
                    Path(name).write_bytes(Path("demo.h5").read_bytes())
        argv = _argv(line)
        if argv[0] not in ("run", "sweep", "uq") and "--overwrite" not in argv:
            # each example is shown on its own: a file an earlier example wrote is not this one's to replace
            for flag, value in zip(argv, argv[1:]):
                if flag in OUTPUT_OPTIONS and Path(value).is_file():
                    Path(value).unlink()
        t0 = time.perf_counter()
        long = next((reason for start, reason in LONG.items() if line.startswith(start)), None)
        try:
            if long and argv[0] == "uq":
                code = cli.main(argv + ["--list"])        # the study's settings checked (priors, design), no drive
            elif long:
                parsed = cli.build_parser().parse_args(argv)       # the arguments are valid
                assert callable(parsed.func)
                code = 0
            else:
                code = cli.main(argv)
        except SystemExit as exc:                                   # --help
            code = exc.code
        timings[line] = time.perf_counter() - t0
        capsys.readouterr()
        if code != 0:
            failures.append((line, code))
    assert failures == [], failures
    assert len(timings) >= 40
    slow = sorted(timings.items(), key=lambda kv: -kv[1])[:5]
    print("slowest examples:", [(k[:60], round(v, 1)) for k, v in slow])
