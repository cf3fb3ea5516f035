"""`hpsim road ...`: generate / psd / plot, JSON output, one-line errors with exit code 2."""
from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from terrain import Road, iso8608
from vehicle.cli import main


def run(capsys, *argv):
    code = main(list(argv))
    out = capsys.readouterr()
    return code, out.out, out.err


@pytest.fixture(scope="module")
def road_csv(tmp_path_factory):
    path = tmp_path_factory.mktemp("road") / "road.csv"
    assert main(["road", "generate", "--class", "D", "--length", "5km", "--seed", "7", "-o", str(path),
                 "--json"]) == 0
    return path


def test_generate_writes_csv_with_header(road_csv):
    lines = road_csv.read_text().splitlines()
    assert lines[0] == "distance_m,left_m,right_m"
    assert len(lines) == 1 + 100001
    r = Road.from_csv(road_csv)
    assert r.spacing_m == pytest.approx(0.05) and r.length_m == pytest.approx(5000.0)


def test_generate_options_and_table(capsys, tmp_path):
    out_csv = tmp_path / "e.csv"
    code, out, err = run(capsys, "road", "generate", "--class", "e", "--length", "500 m", "--seed", "3",
                         "--spacing", "100mm", "--track", "2.2m", "--coherence", "identical", "-o", str(out_csv))
    assert code == 0 and err == ""
    assert "target_iso_class" in out and "identical" in out
    r = Road.from_csv(out_csv)
    assert r.spacing_m == pytest.approx(0.1)
    np.testing.assert_allclose(r.left_m, r.right_m)


def test_psd_json_from_csv(capsys, road_csv, tmp_path):
    png = tmp_path / "psd.png"
    code, out, err = run(capsys, "road", "psd", str(road_csv), "--json", "--plot", str(png))
    assert code == 0
    data = json.loads(out)  # only JSON on stdout
    for key in ("gd_n0_m3", "waviness", "iso_class", "rms_m", "coherence_at_0p1_cycle_per_m"):
        assert key in data
    assert data["iso_class"] == "D"
    assert abs(np.log(data["gd_n0_m3"] / 1024e-6)) < 4 * data["gd_n0_rel_se"]
    assert png.stat().st_size > 10000


def test_psd_from_spec_matches_csv(capsys, road_csv):
    code, out, _ = run(capsys, "road", "psd", "--class", "D", "--length", "5km", "--seed", "7", "--json")
    assert code == 0
    spec_stats = json.loads(out)
    code, out, _ = run(capsys, "road", "psd", str(road_csv), "--json")
    csv_stats = json.loads(out)
    # the CSV holds 10 significant digits: the same road, the same statistics
    assert spec_stats["gd_n0_m3"] == pytest.approx(csv_stats["gd_n0_m3"], rel=1e-6)
    assert spec_stats["target_gd_n0_m3"] == iso8608.ISO_CLASS_GD_N0_M3["D"]


def test_psd_table_is_default(capsys, road_csv):
    code, out, _ = run(capsys, "road", "psd", str(road_csv))
    assert code == 0 and "ISO 8608 class" in out and "Gd(n0) fitted" in out


def test_plot(capsys, road_csv, tmp_path):
    png = tmp_path / "road.png"
    code, out, _ = run(capsys, "road", "plot", str(road_csv), "-o", str(png))
    assert code == 0 and png.read_bytes()[:4] == b"\x89PNG"


def test_generate_from_yaml_spec_with_events(capsys, tmp_path):
    spec = tmp_path / "road.yaml"
    spec.write_text("flat: true\nlength: 100 m\nevents:\n"
                    "  - {type: bump_cosine, position: 10 m, length: 1 m, height: 50 mm, track: left}\n")
    out_csv = tmp_path / "ev.csv"
    code, _, err = run(capsys, "road", "generate", "--spec", str(spec), "-o", str(out_csv))
    assert code == 0, err
    r = Road.from_csv(out_csv)
    assert r.left_m.max() == pytest.approx(0.05) and r.right_m.max() == 0.0


@pytest.mark.parametrize("argv, match", [
    (["road", "generate", "--class", "Z", "--length", "1km", "-o", "x.csv"], "--class: 'Z' is not an ISO 8608 class"),
    (["road", "generate", "--class", "D", "--length=-5km", "-o", "x.csv"], "--length: length must be in"),
    (["road", "generate", "--class", "D", "--length", "1km", "--spacing", "0.5m", "-o", "x.csv"],
     "--spacing: spacing 0.5 m is too coarse for the shortest wavelength"),
    (["road", "generate", "--class", "D", "--length", "1 parsec/s", "-o", "x.csv"], "--length"),
    (["road", "generate", "--class", "D", "-o", "x.csv"], "--length is required"),
    (["road", "generate", "--length", "1km", "-o", "x.csv"], "give exactly one road source: --class A-H"),
    (["road", "generate", "-o", "x.csv"], "give --class A-H"),
    (["road", "psd", "--class", "D", "--length", "1km", "--coherence", "sometimes"], "--coherence"),
    (["road", "psd", "--class", "D", "--length", "1km", "--band", "2.8,0.01"], "--band"),
    (["road", "generate", "--class", "D", "--length", "1km", "--lateral-offset", "1m", "-o", "x.csv"],
     "--lateral-offset places the tracks on an OpenCRG surface: give it with crg only"),
    (["road", "import", "x.crg", "-o", "x.csv", "--lateral-offset", "2kg"], "--lateral-offset: '2kg' has units"),
    (["road", "import", "x.crg", "-o", "x.csv", "--lateral-offset", "inf"], "--lateral-offset: 'inf' is not a finite"),
])
def test_bad_arguments_exit_2_with_one_line(capsys, tmp_path, monkeypatch, argv, match):
    monkeypatch.chdir(tmp_path)
    code, out, err = run(capsys, *argv)
    assert code == 2 and out == ""
    assert err.count("\n") == 1 and match in err, err


@pytest.mark.parametrize("text, match", [
    ("distance_m,left_m,right_m\n0,0,0\n0.05,0,0\n0.1,0,100\n0.15,0,100\n", "bad.csv: not a vehicle road: at 0 m "
                                                                           "the right track goes from 0 m to 100 m"),
    ("distance_m,left_m\n0,0\n1,0\n", "bad.csv:1: missing column 'right_m'"),
    ("distance_m,left_m,right_m\n0,0,0\n2,0,0\n1,0,0\n", "bad.csv:4: distance 1 m does not increase"),
    ("distance_m,left_m,right_m\n0,0,0\n1,0,NaN\n2,0,0\n", "bad.csv:3: right_m = nan is not a finite number"),
])
def test_malformed_csv_exit_2(capsys, tmp_path, text, match):
    bad = tmp_path / "bad.csv"
    bad.write_text(text)
    code, out, err = run(capsys, "road", "psd", str(bad))
    assert code == 2 and out == "" and match in err and err.count("\n") == 1, err


def test_console_script_exit_code(tmp_path):
    """The installed `hpsim` entry point: bad class -> exit status 2, message on stderr."""
    res = subprocess.run([sys.executable, "-m", "vehicle.cli", "road", "generate", "--class", "Q",
                          "--length", "1km", "-o", str(tmp_path / "x.csv")], capture_output=True, text=True)
    assert res.returncode == 2 and "hpsim road: error: --class" in res.stderr and res.stdout == ""
