"""OpenCRG roads (terrain.crg, `road: {crg: ...}`, `hpsim road import/psd`): a CRG surface written by the
OpenCRG library's own writer (pycrg.write, the reference conventions of the OpenCRG tools) from an ISO 8608
class C road gives back its tracks at +-track/2: equal to the library's own evaluation at 100 points and to
the written grid (single precision) within 1e-6 m, linearly interpolated across the road between long
sections, and the PSD class it was made with."""
from __future__ import annotations

import json
import logging
import os
import sys

import numpy as np
import pytest

pycrg = pytest.importorskip("pycrg")

from hpsim.errors import UserInputError                      # noqa: E402
from terrain import iso8608                                   # noqa: E402
from terrain.road import Road                                 # noqa: E402
from vehicle import cli                                       # noqa: E402

from .crg_files import write_minimalist                       # noqa: E402

SPACING, N = 0.05, 12001              # 600 m at 50 mm
V = np.array([-1.6, -1.25, 0.0, 1.25, 1.6])     # long sections [m], + left


@pytest.fixture(scope="module")
def crg_file(tmp_path_factory):
    """A class C road (Gd(n0) = 256e-6 m^3) as an OpenCRG surface: right track at v = -1.25 m, left at +1.25 m,
    the centre their mean, the borders 2 mm above the tracks; KRBI (single precision, OpenCRG's default)."""
    left, right = iso8608.generate_tracks(iso8608.ISO_CLASS_GD_N0_M3["C"], 2.0, SPACING, N, seed=11)
    z = np.column_stack([right + 0.002, right, 0.5 * (left + right), left, left + 0.002])
    path = tmp_path_factory.mktemp("crg") / "track.crg"
    pycrg.write(path, z, SPACING, V, comment="hpsim test: ISO 8608 class C, seed 11")
    return path, z.astype(np.float32).astype(float)


def test_tracks_match_the_library_and_the_written_grid(crg_file):
    path, z32 = crg_file
    road = Road.from_crg(path, track_width_m=2.5)
    assert road.n_points == N and road.spacing_m == pytest.approx(SPACING)
    off = road.info["z_offset_m"]
    idx = np.sort(np.random.default_rng(0).choice(N, 100, replace=False))
    u = idx * SPACING
    with pycrg.RoadSurface.open(str(path)) as s:
        lib_left = np.asarray(s.uv_to_z_many(u, 1.25))
        lib_right = np.asarray(s.uv_to_z_many(u, -1.25))
        lib_mid = np.asarray(s.uv_to_z_many(u, 1.0))
        shift = float(s.uv_to_z(0.0, 1.25)) - z32[0, 3]   # the library's default modifiers move the reference point
    np.testing.assert_allclose(road.left_m[idx] + off, lib_left, atol=1e-6)
    np.testing.assert_allclose(road.right_m[idx] + off, lib_right, atol=1e-6)
    # against the grid as written (float32): the same tracks, the same constant shift for both
    np.testing.assert_allclose(road.left_m + off - shift, z32[:, 3], atol=1e-6)
    np.testing.assert_allclose(road.right_m + off - shift, z32[:, 1], atol=1e-6)
    # a track between long sections (track 2.0 m: v = +1.0 between 0 and 1.25) is interpolated linearly across
    narrow = Road.from_crg(path, track_width_m=2.0)
    hand = z32[idx, 2] + (1.0 / 1.25) * (z32[idx, 3] - z32[idx, 2])
    np.testing.assert_allclose(narrow.left_m[idx] + narrow.info["z_offset_m"] - shift, hand, atol=1e-6)
    np.testing.assert_allclose(lib_mid - shift, hand, atol=1e-6)


def test_psd_class_is_the_one_the_file_was_made_with(crg_file, capsys):
    path, _ = crg_file
    assert cli.main(["road", "psd", str(path), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["iso_class"] == "C"
    lo, hi = iso8608.class_limits("C")
    assert lo <= out["gd_n0_m3"] <= hi


def test_import_and_scenario_use_the_same_tracks(crg_file, tmp_path, capsys):
    from vehicle.scenario.schema import prepare, read_scenario

    path, _ = crg_file
    out = tmp_path / "road.csv"
    assert cli.main(["road", "import", str(path), "-o", str(out)]) == 0
    csv = Road.from_csv(out)
    road = Road.from_crg(path, 2.5)
    np.testing.assert_allclose(csv.left_m, road.left_m, atol=1e-9)
    scen = tmp_path / "s.yaml"
    scen.write_text(f"vehicle: {{name: apc_8x8}}\nroad: {{crg: {path.name}}}\nspeed: 20 km/h\ndistance: 300 m\n"
                    "ambient_temperature: 25 degC\n")
    (tmp_path / path.name).write_bytes(path.read_bytes())
    from_scenario = prepare(read_scenario(scen)).road()
    np.testing.assert_allclose(from_scenario.right_m, road.right_m, atol=1e-12)
    # a track wider than the surface and a file that is not OpenCRG: one line, exit 2
    assert cli.main(["road", "import", str(path), "-o", str(tmp_path / "w.csv"), "--track", "4m"]) == 2
    bad = tmp_path / "bad.crg"
    bad.write_text("not a crg file\n")
    assert cli.main(["road", "import", str(bad), "-o", str(tmp_path / "b.csv")]) == 2
    err = capsys.readouterr().err
    assert "fall outside the file's v range [-1.6, 1.6] m" in err and "not a readable OpenCRG file" in err


def test_without_the_library_the_message_names_the_extra(crg_file, tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "pycrg", None)
    assert cli.main(["road", "import", str(crg_file[0]), "-o", str(tmp_path / "r.csv")]) == 2
    assert 'pip install -e ".[crg]"' in capsys.readouterr().err


# -- lateral placement: the vehicle's centre line at v = lateral_offset (OpenCRG's v positive to the left) --------

def _scenario(tmp_path, road: str):
    from vehicle.scenario.schema import prepare, read_scenario

    scen = tmp_path / "s.yaml"
    scen.write_text(f"vehicle: {{name: apc_8x8}}\nroad: {road}\nspeed: 20 km/h\ndistance: 10 m\n"
                    "ambient_temperature: 25 degC\n")
    return prepare(read_scenario(scen))


def test_a_minimalist_file_is_placed_by_its_lateral_offset_and_equals_its_centred_twin(tmp_path, capsys):
    """A file without LONG_SECTION_V_RIGHT/LEFT has its long sections at v = 0 .. width: with the lateral offset
    width/2 its tracks are those of the same grid written centred on the reference line."""
    z = np.random.default_rng(2).normal(0.0, 0.01, (301, 7))        # 30 m at 0.1 m; v = 0 .. 3 m at 0.5 m
    mini = write_minimalist(tmp_path / "mini.crg", z, 0.1, 0.5)
    twin = tmp_path / "twin.crg"
    pycrg.write(twin, z, 0.1, np.linspace(-1.5, 1.5, 7), comment="hpsim test: the minimalist grid, centred")
    with pytest.raises(UserInputError, match=r"mini\.crg: the tracks at v = -1\.25 and 1\.25 m \(track 2\.5 m, "
                                             r"lateral offset 0 m\) fall outside the file's v range \[0, 3\] m; a "
                                             r"lateral offset from 1\.25 to 1\.75 m keeps both on it"):
        Road.from_crg(mini, 2.5)
    placed = Road.from_crg(mini, 2.5, lateral_offset_m=1.5)
    centred = Road.from_crg(twin, 2.5)
    assert placed.info["lateral_offset_m"] == 1.5
    np.testing.assert_allclose(placed.left_m, centred.left_m, atol=1e-6)     # the grid in single precision
    np.testing.assert_allclose(placed.right_m, centred.right_m, atol=1e-6)
    # the command line and a scenario place them the same way; a refusal names the way out
    out = tmp_path / "road.csv"
    assert cli.main(["road", "import", str(mini), "-o", str(out), "--lateral-offset", "150cm"]) == 0
    np.testing.assert_allclose(Road.from_csv(out).left_m, placed.left_m, atol=1e-9)
    assert "tracks at v = 0.25 and 2.75 m" in capsys.readouterr().out
    road = _scenario(tmp_path, "{crg: mini.crg, lateral_offset: 1.5 m}").road()
    np.testing.assert_allclose(road.right_m, placed.right_m, atol=1e-12)
    with pytest.raises(UserInputError, match=r"s\.yaml: road: .*mini\.crg: the tracks .* a lateral offset from "
                                             r"1\.25 to 1\.75 m"):
        _scenario(tmp_path, "{crg: mini.crg}").road()
    with pytest.raises(UserInputError, match=r"s\.yaml: road: lateral_offset places the tracks on an OpenCRG"):
        _scenario(tmp_path, "{iso_class: C, lateral_offset: 1 m}")


def test_the_left_track_is_at_positive_v(tmp_path):
    """On a surface tilted across the road, z = 0.1·v, the left track is 0.1·track above the right, and moving the
    vehicle by d to the left lifts both by 0.1·d."""
    v = np.linspace(-1.5, 1.5, 7)
    path = tmp_path / "tilted.crg"
    pycrg.write(path, np.tile(0.1 * v, (201, 1)), 0.1, v, comment="hpsim test: tilted across, z = 0.1 v")
    centred = Road.from_crg(path, 2.0)
    moved = Road.from_crg(path, 2.0, lateral_offset_m=0.5)
    for road in (centred, moved):
        np.testing.assert_allclose(road.left_m - road.right_m, 0.1 * 2.0, atol=1e-6)
    assert moved.info["z_offset_m"] - centred.info["z_offset_m"] == pytest.approx(0.1 * 0.5, abs=1e-6)


def test_cells_without_elevation_are_filled_by_the_library_or_refused_where_a_wheel_runs(tmp_path):
    """A minimalist file with *missing* cells in the long section at v = 2.5 m from u = 10 to 11 m: the library's
    default modifiers fill them; without modifiers (an empty $ROAD_CRG_MODS) they are holes, refused from
    the grid step before them (bilinear interpolation reaches them) when the left track runs there (lateral
    offset 1.5 m, track 2 m) and no matter when it does not (track 1 m at 1.25
    m: the left track halfway between the long sections at v = 1.5 and 2 m)."""
    z = np.random.default_rng(3).normal(0.0, 0.01, (301, 7))
    z[100:111, 5] = np.nan
    filled = Road.from_crg(write_minimalist(tmp_path / "nan.crg", z, 0.1, 0.5), 2.0, lateral_offset_m=1.5)
    assert np.isfinite(filled.left_m).all()
    holes = write_minimalist(tmp_path / "holes.crg", z, 0.1, 0.5, empty_mods=True)
    with pytest.raises(UserInputError, match=r"holes\.crg: not a vehicle road: at u = 9\.9 m the left track has "
                                             r"no finite elevation"):
        Road.from_crg(holes, 2.0, lateral_offset_m=1.5)
    beside = Road.from_crg(holes, 1.0, lateral_offset_m=1.25)
    written = z.astype(np.float32).astype(float)
    np.testing.assert_allclose(beside.left_m + beside.info["z_offset_m"], 0.5 * (written[:, 3] + written[:, 4]),
                               atol=1e-6)


# -- the library's messages, and paths that are not files ----------------------------------------------------------

class _Records(logging.Handler):
    def __init__(self):
        super().__init__(logging.DEBUG)
        self.records: list[logging.LogRecord] = []

    def emit(self, record):
        self.records.append(record)


@pytest.fixture
def log_records():
    """The records of the "hpsim.crg" and "pycrg" loggers at every level, whatever the CLI set up before."""
    records = _Records()
    loggers = [logging.getLogger(name) for name in ("hpsim.crg", "pycrg")]
    levels = [lg.level for lg in loggers]
    for lg in loggers:
        lg.addHandler(records)
        lg.setLevel(logging.DEBUG)
    yield records.records
    for lg, level in zip(loggers, levels):
        lg.removeHandler(records)
        lg.setLevel(level)


def test_the_librarys_messages_are_debug_records_of_hpsims_log(crg_file, log_records):
    """Every load: the library's statistics (NOTICE) and any warning are debug records of "hpsim.crg", never
    above; after the load pycrg routes messages to its own logger again."""
    from terrain.crg import library_messages_logged

    Road.from_crg(crg_file[0], 2.5)
    with library_messages_logged(pycrg):
        pycrg.msg_print(pycrg.MSG_LEVEL_WARN, "hpsim test: a warning from the library\n")
    assert {r.name for r in log_records} == {"hpsim.crg"}
    assert {r.levelno for r in log_records} == {logging.DEBUG}
    texts = [r.getMessage() for r in log_records]
    assert any(t.startswith("OpenCRG NOTICE: crgCalcStatistics") for t in texts)
    assert "OpenCRG WARNING: hpsim test: a warning from the library" in texts
    log_records.clear()
    pycrg.msg_print(pycrg.MSG_LEVEL_WARN, "hpsim test: outside a load\n")
    assert [(r.name, r.levelno) for r in log_records] == [("pycrg", logging.WARNING)]


def test_the_terminal_shows_the_librarys_messages_only_with_verbose(crg_file, tmp_path, hpsim):
    quiet = hpsim(["road", "import", str(crg_file[0]), "-o", str(tmp_path / "a.csv")])
    assert quiet.returncode == 0 and quiet.stderr == "" and len(quiet.stdout.splitlines()) == 1
    verbose = hpsim(["road", "import", "-v", str(crg_file[0]), "-o", str(tmp_path / "b.csv")])
    assert verbose.returncode == 0 and "OpenCRG NOTICE: crgCalcStatistics" in verbose.stderr


def test_a_fifo_or_a_folder_given_as_opencrg_file_is_named_as_such(tmp_path, capsys):
    fifo, folder = tmp_path / "pipe.crg", tmp_path / "folder.crg"
    os.mkfifo(fifo)
    folder.mkdir()
    for path, what in ((fifo, "a FIFO (named pipe)"), (folder, "a directory"), (tmp_path / "none.crg", None)):
        assert cli.main(["road", "import", str(path), "-o", str(tmp_path / "r.csv")]) == 2
        err = capsys.readouterr().err.strip()
        expected = "no such OpenCRG file" if what is None else f"is {what}, expected an OpenCRG file (a regular file)"
        assert err == f"hpsim road: error: {path}: {expected}"
    assert not (tmp_path / "r.csv").exists()
