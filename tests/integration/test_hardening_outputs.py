"""Every output a command writes goes through hpsim.outputs: refused when it is one of the command's inputs,
refused when it exists without --overwrite, written to a unique temporary name beside it and renamed when complete,
removed on failure, Ctrl-C or SIGTERM (the old output stays intact), a full disk named in one line."""
from __future__ import annotations

import errno
import os
import stat
from pathlib import Path

import pytest

from hpsim.errors import Terminated, UserInputError
from hpsim.outputs import atomic_output, check_output_file

from tests.integration.test_fuzz import case_dir, check_user_error, run_case, warm_imports  # noqa: F401

OLD = b"the old output, which must survive\n"


def _leftovers(folder) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if p.name.startswith("."))


# --- the helper itself ------------------------------------------------------------------------------------------
def test_atomic_output_replaces_only_when_complete(tmp_path):
    out = tmp_path / "x.fmu"
    out.write_bytes(OLD)
    os.chmod(out, 0o640)
    with atomic_output(out) as tmp:
        assert tmp.parent == out.parent and tmp.suffix == ".fmu" and tmp != out
        tmp.write_bytes(b"new")
        assert out.read_bytes() == OLD          # nothing replaced before the block completes
    assert out.read_bytes() == b"new"
    assert stat.S_IMODE(out.stat().st_mode) == 0o640        # the replaced file's mode, not mkstemp's 0600
    assert _leftovers(tmp_path) == []


@pytest.mark.parametrize("stop", [RuntimeError("a bug"), KeyboardInterrupt(), Terminated()])
def test_atomic_output_removes_its_temporary_file_and_keeps_the_old_output(tmp_path, stop):
    out = tmp_path / "x.csv"
    out.write_bytes(OLD)
    with pytest.raises(type(stop)):
        with atomic_output(out) as tmp:
            tmp.write_bytes(b"half a fi")
            raise stop
    assert out.read_bytes() == OLD
    assert _leftovers(tmp_path) == []


def test_atomic_output_never_uses_a_fixed_temporary_name(tmp_path):
    out = tmp_path / "x.fmu"
    users = [tmp_path / "x.fmu.tmp", tmp_path / ".x.fmu.tmp", tmp_path / "x.tmp"]
    for u in users:
        u.write_bytes(b"a user's file")
    with pytest.raises(RuntimeError):
        with atomic_output(out) as tmp:
            assert tmp not in users
            raise RuntimeError
    with atomic_output(out) as tmp:
        tmp.write_bytes(b"fmu")
    assert all(u.read_bytes() == b"a user's file" for u in users)


@pytest.mark.parametrize("code", [errno.ENOSPC, errno.EFBIG, errno.EDQUOT])
def test_a_full_disk_is_one_line_naming_the_output(tmp_path, code):
    out = tmp_path / "x.html"
    out.write_bytes(OLD)
    with pytest.raises(UserInputError, match=r"x\.html: cannot write .*nothing was written over"):
        with atomic_output(out) as tmp:
            raise OSError(code, os.strerror(code), str(tmp))
    assert out.read_bytes() == OLD
    assert _leftovers(tmp_path) == []


def test_an_input_is_never_an_output(tmp_path):
    src = tmp_path / "my.yaml"
    src.write_text("a: 1\n")
    (tmp_path / "link.yaml").symlink_to(src)
    os.link(src, tmp_path / "hard.yaml")
    for spelled in (src, tmp_path / "link.yaml", tmp_path / "hard.yaml", tmp_path / "." / "my.yaml"):
        with pytest.raises(UserInputError, match="also an input"):
            check_output_file(spelled, "-o/--output", inputs=[None, "apc", src], overwrite=True)
    check_output_file(tmp_path / "other.fmu", "-o/--output", inputs=[None, "apc", src], overwrite=False)


def test_an_existing_output_needs_overwrite(tmp_path):
    out = tmp_path / "x.png"
    out.write_bytes(OLD)
    with pytest.raises(UserInputError, match=r"exists \(--overwrite replaces it\)"):
        check_output_file(out, "-o/--output", overwrite=False)
    assert check_output_file(out, "-o/--output", overwrite=True) == out


# --- the commands -------------------------------------------------------------------------------------------------
RESULTS = "tests/data/results_v1.h5"


def _inputs(case_dir):
    d = case_dir / "in"
    (d / "t.crg").write_bytes(b"* a CRG file\n")
    (d / "my.yaml").write_text("name: my strut\n")
    (d / "s.yaml").write_text("vehicle: {name: apc_8x8}\n")
    (d / "road.yaml").write_text("iso_class: C\nlength: 100 m\n")
    r = d / "r.h5"
    r.write_bytes(open(os.path.join(os.path.dirname(__file__), "..", "data", "results_v1.h5"), "rb").read())
    return d


@pytest.mark.parametrize("argv", [
    ["road", "import", "{in}/t.crg", "-o", "{in}/t.crg"],
    ["road", "generate", "--spec", "{in}/road.yaml", "-o", "{in}/road.yaml"],
    ["road", "plot", "--spec", "{in}/road.yaml", "-o", "{in}/road.yaml"],
    ["export", "fmu", "--strut", "{in}/my.yaml", "-o", "{in}/my.yaml"],
    ["export", "fmu", "--scenario", "{in}/s.yaml", "-o", "{in}/s.yaml"],
    ["animate", "{in}/r.h5", "-o", "{in}/r.h5"],
    ["report", "{in}/r.h5", "--html", "{in}/r.h5"],
    ["plot", "{in}/r.h5", "-o", "{in}/r.h5", "--overwrite"],
    ["validate", "{in}/r.h5", "--plot", "{in}/r.h5", "--overwrite"],
    ["run", "{in}/s.yaml", "-o", "{in}/s.yaml", "--overwrite", "--no-progress"],
    ["strut", "characteristic", "--strut", "{in}/my.yaml", "--csv", "{in}/my.yaml", "--overwrite"],
    ["strut", "cycle", "--strut", "{in}/my.yaml", "--amplitude", "10mm", "--frequency", "1Hz", "--mean", "115mm",
     "--plot", "{in}/my.yaml", "--overwrite"],
    ["strut", "fit", "--strut", "{in}/my.yaml", "--data", "struts/data/apc_rig_energy.csv", "--fit", "F0",
     "--write", "{in}/my.yaml", "--overwrite"],
], ids=lambda a: " ".join(a[:2]))
def test_a_command_never_writes_over_its_input(case_dir, argv):
    d = _inputs(case_dir)
    before = {p.name: p.read_bytes() for p in d.iterdir()}
    res = run_case(case_dir, [a.replace("{in}", str(d)) for a in argv])
    check_user_error(res)
    assert "also an input" in res.err, res.err
    assert {p.name: p.read_bytes() for p in d.iterdir()} == before


@pytest.mark.parametrize("argv", [
    ["road", "generate", "--class", "C", "--length", "100m", "-o", "{out}.csv"],
    ["road", "plot", "--class", "C", "--length", "100m", "-o", "{out}.png"],
    ["road", "psd", "--class", "C", "--length", "100m", "--plot", "{out}.png"],
    ["export", "fmu", "--strut", "apc", "-o", "{out}.fmu"],
    ["animate", "{in}/r.h5", "-o", "{out}.gif"],
    ["report", "{in}/r.h5", "--html", "{out}.html"],
    ["report", "{in}/r.h5", "--pdf", "{out}.pdf"],
    ["plot", "{in}/r.h5", "-o", "{out}.png"],
    ["compare", "{in}/r.h5", "{in}/r.h5", "--plot", "{out}.png"],
    ["validate", "{in}/r.h5", "--plot", "{out}.png"],
    ["vehicle", "response", "--plot", "{out}.png"],
    ["strut", "characteristic", "--csv", "{out}.csv"],
    ["strut", "characteristic", "--plot", "{out}.png"],
    ["strut", "cycle", "--amplitude", "10mm", "--frequency", "1Hz", "--mean", "115mm", "--cycles", "1",
     "--csv", "{out}.csv"],
    ["strut", "gas", "--temperatures", "300K", "--plot", "{out}.png"],
    ["strut", "identify", "--strut", "yin2023", "--csv", "{out}.csv"],
    ["strut", "fit", "--data", "struts/data/apc_rig_energy.csv", "--fit", "F0", "--write", "{out}.yaml"],
], ids=lambda a: " ".join(a[:3]))
def test_an_existing_output_is_refused_without_overwrite(case_dir, argv):
    d = _inputs(case_dir)
    out = case_dir / "work" / "out"
    argv = [a.replace("{in}", str(d)).replace("{out}", str(out)) for a in argv]
    target = next(a for a in argv if a.startswith(str(out)))
    with open(target, "wb") as fh:
        fh.write(OLD)
    res = run_case(case_dir, argv)
    check_user_error(res, must_say=("--overwrite",))
    assert open(target, "rb").read() == OLD


def _generate(out, *extra):
    from vehicle.cli import main

    return main(["-q", "road", "generate", "--class", "C", "--length", "200m", "-o", str(out), *extra])


@pytest.mark.parametrize("stop, code", [(KeyboardInterrupt, 130), (Terminated, 143),
                                        (lambda: OSError(errno.ENOSPC, "No space left on device"), 2)])
def test_an_interrupted_or_failed_write_keeps_the_old_output(tmp_path, monkeypatch, capsys, stop, code):
    """Ctrl-C, SIGTERM or a full disk halfway through writing the road: the old file is as it was, no temporary
    file is left, the exit code is the command line's for that event."""
    from terrain.road import Road

    out = tmp_path / "road.csv"
    out.write_bytes(OLD)

    def half_then_stop(self, path):
        with open(path, "w") as fh:
            fh.write("distance_m,left_m,right_m\n0.0,0.0")
        raise stop()

    monkeypatch.setattr(Road, "to_csv", half_then_stop)
    assert _generate(out, "--overwrite") == code
    assert out.read_bytes() == OLD
    assert _leftovers(tmp_path) == []
    if code == 2:
        assert "road.csv: cannot write (No space left on device)" in capsys.readouterr().err


def test_a_completed_write_replaces_with_overwrite(tmp_path, capsys):
    out = tmp_path / "road.csv"
    out.write_bytes(OLD)
    assert _generate(out, "--overwrite") == 0
    assert out.read_text().startswith("distance_m,left_m,right_m")
    assert _leftovers(tmp_path) == []


def test_road_generate_quiet_prints_only_the_path(tmp_path, capsys):
    out = tmp_path / "road.csv"
    assert _generate(out) == 0
    assert capsys.readouterr().out.strip() == str(out)


# --- a study folder holds one kind of study -------------------------------------------------------------------------
@pytest.mark.parametrize("command, other, marker", [("sweep", "uq", "samples.csv"), ("uq", "sweep", "summary.csv")])
def test_a_study_folder_of_the_other_kind_is_refused_before_any_drive(case_dir, command, other, marker):
    from tests.integration.test_fuzz import SCENARIO, SWEEP

    d = case_dir / "in"
    (d / "base.yaml").write_text(SCENARIO)
    (d / "sweep.yaml").write_text(SWEEP)
    study = case_dir / "work" / "study"
    study.mkdir()
    (study / marker).write_text("a,b\n1,2\n")
    argv = (["sweep", d / "sweep.yaml", "-o", study, "--yes"] if command == "sweep" else
            ["uq", d / "base.yaml", "--samples", "4", "--method", "lhs", "-o", study, "--yes"])
    res = run_case(case_dir, argv, timeout=60)
    check_user_error(res, must_say=(f"hpsim {other}", marker))
    assert sorted(p.name for p in study.iterdir()) == [marker]


def test_vehicle_new_never_writes_over_its_strut_file_and_writes_whole(tmp_path, capsys, monkeypatch):
    from vehicle.cli import main

    strut = tmp_path / "my.yaml"
    strut.write_bytes((Path(__file__).resolve().parents[2] / "struts" / "data" / "apc.yaml").read_bytes())
    before = strut.read_bytes()
    args = ["--positions", "0m,3.5m,4.9m", "--axle-loads", "7t", "--track", "2m", "--ride-height", "1.2m",
            "--strut", str(strut)]
    assert main(["vehicle", "new", "-o", str(strut), *args, "--overwrite"]) == 2
    assert "also an input" in capsys.readouterr().err and strut.read_bytes() == before
    out = tmp_path / "v.yaml"
    out.write_bytes(OLD)
    assert main(["vehicle", "new", "-o", str(out), *args]) == 2
    assert "--overwrite" in capsys.readouterr().err and out.read_bytes() == OLD
    assert _leftovers(tmp_path) == []


@pytest.mark.parametrize("stop, code", [(KeyboardInterrupt, 130), (Terminated, 143)])
def test_animate_and_report_stopped_midway_keep_the_old_output(tmp_path, monkeypatch, stop, code):
    """Ctrl-C or SIGTERM after the first frame of a movie, or halfway through the HTML: the old movie and report are
    as they were, no temporary file is left (they used to be left truncated, 0 B to 760 kB)."""
    import shutil

    from vehicle.cli import main
    from vehicle.presentation.animation import SideView

    r = tmp_path / "r.h5"
    shutil.copy(Path(__file__).resolve().parents[1] / "data" / "results_v1.h5", r)
    gif, html = tmp_path / "a.gif", tmp_path / "r.html"
    for f in (gif, html):
        f.write_bytes(OLD)
    update = SideView.update
    drawn = []

    def draw_then_stop(self, k):
        update(self, k)
        drawn.append(k)
        if len(drawn) == 2:
            raise stop()

    monkeypatch.setattr(SideView, "update", draw_then_stop)
    assert main(["animate", str(r), "-o", str(gif), "--from", "0.1km", "--to", "0.12km", "--overwrite"]) == code
    write_text = Path.write_text

    def half_then_stop(self, text, *args, **kwargs):
        write_text(self, text[:len(text) // 2], *args, **kwargs)
        raise stop()

    monkeypatch.setattr(Path, "write_text", half_then_stop)
    assert main(["report", str(r), "--html", str(html), "--overwrite"]) == code
    assert gif.read_bytes() == OLD and html.read_bytes() == OLD
    assert _leftovers(tmp_path) == []


def test_export_fmu_never_writes_over_a_file_its_scenario_reads(case_dir):
    d = case_dir / "in"
    road = d / "road.csv"
    road.write_text("distance_m,left_m,right_m\n" + "".join(f"{0.05 * i:.2f},0.0,0.0\n" for i in range(4000)))
    (d / "s.yaml").write_text(f"vehicle: {{name: apc_8x8}}\nroad: {{csv: '{road}'}}\nspeed: 20 km/h\n"
                              "distance: 100 m\nambient_temperature: 25 degC\n")
    before = road.read_bytes()
    res = run_case(case_dir, ["export", "fmu", "--scenario", d / "s.yaml", "-o", road, "--overwrite"], timeout=60)
    check_user_error(res, must_say=("also an input",))
    assert road.read_bytes() == before


def test_a_new_output_gets_the_umask_mode_not_mkstemps_0600(tmp_path):
    old = os.umask(0o027)
    try:
        with atomic_output(tmp_path / "new.csv") as tmp:
            tmp.write_text("a\n")
    finally:
        os.umask(old)
    assert stat.S_IMODE((tmp_path / "new.csv").stat().st_mode) == 0o640


# --- strut rig outputs and the UQ summary ------------------------------------------------------------------------
@pytest.mark.parametrize("stop, code", [(KeyboardInterrupt, 130), (Terminated, 143),
                                        (lambda: OSError(errno.ENOSPC, "No space left on device"), 2)])
@pytest.mark.parametrize("flag", ["--csv", "--plot"])
def test_strut_outputs_stopped_midway_keep_the_old_output(tmp_path, monkeypatch, capsys, flag, stop, code):
    """Ctrl-C, SIGTERM or a full disk halfway through a strut rig's CSV or figure: the old file is as it was and no
    temporary file is left."""
    import csv

    from matplotlib.figure import Figure

    from vehicle.cli import main

    out = tmp_path / ("f.csv" if flag == "--csv" else "f.png")
    out.write_bytes(OLD)
    writer = csv.writer

    def half_a_table_then_stop(fh, *args, **kwargs):
        fh.write("x_m,force_N,gas_pressure_Pa\n0.0,")
        raise stop()

    def half_a_figure_then_stop(self, path, *args, **kwargs):
        Path(path).write_bytes(b"\x89PNG half")
        raise stop()

    monkeypatch.setattr(csv, "writer", half_a_table_then_stop if flag == "--csv" else writer)
    monkeypatch.setattr(Figure, "savefig", half_a_figure_then_stop)
    assert main(["strut", "characteristic", flag, str(out), "--overwrite"]) == code
    assert out.read_bytes() == OLD
    assert _leftovers(tmp_path) == []
    if code == 2:
        assert f"{out}: cannot write (No space left on device)" in capsys.readouterr().err


def test_strut_outputs_are_replaced_whole_with_overwrite(tmp_path, capsys):
    from vehicle.cli import main

    table, figure = tmp_path / "f.csv", tmp_path / "f.png"
    for f in (table, figure):
        f.write_bytes(OLD)
    assert main(["strut", "characteristic", "--csv", str(table), "--plot", str(figure), "--overwrite"]) == 0
    assert table.read_text().startswith("x_m,force_N,gas_pressure_Pa")
    assert figure.read_bytes().startswith(b"\x89PNG")
    assert _leftovers(tmp_path) == []


@pytest.mark.parametrize("stop", [KeyboardInterrupt, Terminated])
def test_uq_summary_stopped_midway_keeps_the_old_summary(tmp_path, monkeypatch, stop):
    import json

    from vehicle.studies.uq_tables import write_summary

    (tmp_path / "summary.json").write_bytes(OLD)
    write_text = Path.write_text

    def half_then_stop(self, text, *args, **kwargs):
        write_text(self, text[:len(text) // 2], *args, **kwargs)
        raise stop()

    monkeypatch.setattr(Path, "write_text", half_then_stop)
    with pytest.raises(stop):
        write_summary(tmp_path, {"samples": 8, "bands": {"T gas end": [50.0, 60.0]}})
    assert (tmp_path / "summary.json").read_bytes() == OLD
    assert _leftovers(tmp_path) == []
    monkeypatch.setattr(Path, "write_text", write_text)
    write_summary(tmp_path, {"samples": 8, "wall_s": float("nan")})
    assert json.loads((tmp_path / "summary.json").read_text())["samples"] == 8
    assert _leftovers(tmp_path) == []


def test_uq_table_failing_midway_keeps_the_old_table(tmp_path):
    from vehicle.studies.uq_tables import write_bands

    out = tmp_path / "bands.csv"
    out.write_bytes(OLD)
    band = {c: 1.0 for c in ("p5", "p50", "p95", "nominal", "mean", "sd", "min", "max")} | {"n": 8}
    summary = {"units": {}, "bands": {"axle1.rise_K": band, "axle2.rise_K": band | {"p5": "not a number"}}}
    with pytest.raises(ValueError):
        write_bands(out, summary)
    assert out.read_bytes() == OLD
    assert _leftovers(tmp_path) == []
    del summary["bands"]["axle2.rise_K"]
    write_bands(out, summary)
    assert out.read_text().splitlines()[1].startswith("axle1.rise_K,1,rise_K,")
