"""OpenCRG roads (terrain.crg, `road: {crg: ...}`, `hpsim road import/psd`): a CRG surface written by the
OpenCRG library's own writer (pycrg.write, the reference conventions of the OpenCRG tools) from an ISO 8608
class C road gives back its tracks at +-track/2: equal to the library's own evaluation at 100 points and to
the written grid (single precision) within 1e-6 m, linearly interpolated across the road between long
sections, and the PSD class it was made with."""
from __future__ import annotations

import json
import sys

import numpy as np
import pytest

pycrg = pytest.importorskip("pycrg")

from terrain import iso8608                                   # noqa: E402
from terrain.road import Road                                 # noqa: E402
from vehicle import cli                                       # noqa: E402

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
    assert "the file covers v in [-1.6, 1.6] m" in err and "not a readable OpenCRG file" in err


def test_without_the_library_the_message_names_the_extra(crg_file, tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "pycrg", None)
    assert cli.main(["road", "import", str(crg_file[0]), "-o", str(tmp_path / "r.csv")]) == 2
    assert 'pip install -e ".[crg]"' in capsys.readouterr().err
