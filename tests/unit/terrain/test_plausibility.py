"""Road plausibility (terrain.plausibility): a road a vehicle can drive on has finite elevations, rises of at most 2 m
within a tyre's contact length and an elevation range within 100 m. Checked at the bounds (a sharp step and a wall-like
grade just below and above 2 m per contact length, a range just below and above 100 m), on the roughest ISO
8608 class (H, accepted), and on every source: a CSV road with a 100 m step, an OpenCRG grid holding 1e38 m, a
binary OpenCRG file damaged in its data section, a generated road with a 3 m step event. Each refusal is one line
naming the file (or the generated road), the track and the distance, exit code 2, and nothing is written."""
from __future__ import annotations

import numpy as np
import pytest

from hpsim.errors import UserInputError
from terrain import iso8608
from terrain.plausibility import (CONTACT_LENGTH_M, MAX_RANGE_M, MAX_RISE_M, check_plausible_tracks,
                                  track_implausibility)
from terrain.road import Road
from terrain.spec import RoadSpec, build_road
from vehicle import cli

SPACING = 0.01


def _step_profile(height_m: float, at_m: float = 5.0, length_m: float = 10.0) -> np.ndarray:
    s = np.arange(int(round(length_m / SPACING)) + 1) * SPACING
    return np.where(s >= at_m, height_m, 0.0)


def test_a_sharp_step_is_a_road_up_to_the_bound_and_a_wall_beyond():
    assert track_implausibility("left", SPACING, _step_profile(0.98 * MAX_RISE_M)) is None
    found = track_implausibility("left", SPACING, _step_profile(-1.02 * MAX_RISE_M))
    assert found is not None and found.track == "left"
    # the first chord over the contact length that spans the step starts one contact length before it
    assert found.distance_m == pytest.approx(5.0 - CONTACT_LENGTH_M, abs=1.5 * SPACING)


def test_a_grade_is_bounded_by_the_rise_over_the_contact_length():
    s = np.arange(501) * SPACING                       # 5 m: the range stays below its bound
    slope = MAX_RISE_M / CONTACT_LENGTH_M
    assert track_implausibility("right", SPACING, 0.98 * slope * s) is None
    found = track_implausibility("right", SPACING, 1.02 * slope * s)
    assert found is not None and found.distance_m == 0.0 and f"within {CONTACT_LENGTH_M:g} m" in found.reason


def test_the_roughest_iso_class_is_a_road():
    left, right = iso8608.generate_tracks(iso8608.ISO_CLASS_GD_N0_M3["H"], 2.0, 0.05, 400_001, seed=3)
    check_plausible_tracks("class H", 0.05, left, right)


def test_the_range_is_bounded_and_the_highest_point_is_named():
    s = np.arange(4001) * 0.5                          # 2 km at a 5 % grade: 100 m of climb
    assert track_implausibility("left", 0.5, 0.99 * MAX_RANGE_M / s[-1] * s) is None
    found = track_implausibility("left", 0.5, 1.01 * MAX_RANGE_M / s[-1] * s)
    assert found is not None and found.distance_m == pytest.approx(s[-1]) and "101 m above" in found.reason


def test_the_first_hole_is_named_with_the_sources_own_distance():
    z = np.zeros(101)
    z[[40, 70]] = np.nan
    with pytest.raises(UserInputError) as exc:
        check_plausible_tracks("road.crg", 0.1, np.zeros(101), z, start_m=730.0, coordinate="u = ")
    assert str(exc.value).startswith("road.crg: not a vehicle road: at u = 734 m the right track has no finite")


def _refused(argv, capsys) -> str:
    assert cli.main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "Traceback" not in err
    return err


def test_a_csv_road_with_a_100_m_step_is_refused_naming_file_and_distance(tmp_path, capsys):
    d = 100.0 + np.arange(2001) * 0.05                # the file's own distances start at 100 m
    z = np.where(d >= 150.0, 100.0, 0.0)
    src = tmp_path / "step.csv"
    np.savetxt(src, np.column_stack([d, z, np.zeros_like(z)]), delimiter=",", header="distance_m,left_m,right_m",
               comments="")
    with pytest.raises(UserInputError, match=r"step\.csv: not a vehicle road: at 149\.7 m the left track"):
        Road.from_csv(src)
    err = _refused(["road", "psd", str(src)], capsys)
    assert str(src) in err and "at 149.7 m the left track goes from 0 m to 100 m" in err
    # a drive on it stops before the results file is created
    scenario = tmp_path / "drive.yaml"
    scenario.write_text("vehicle: {name: apc_8x8}\nroad: {csv: step.csv}\nspeed: 20 km/h\ndistance: 80 m\n"
                        "ambient_temperature: 25 degC\n")
    out = tmp_path / "drive.h5"
    err = _refused(["run", str(scenario), "-o", str(out), "--no-progress"], capsys)
    assert f"drive.yaml: road: {src}: not a vehicle road: at 149.7 m" in err and not out.exists()


def test_a_generated_road_with_a_3_m_step_event_is_refused_and_nothing_written(tmp_path, capsys):
    spec = dict(iso_class="A", length="200 m", seed=3, events=[dict(type="step", position=120, length=0,
                                                                     height=3.0, track="right")])
    with pytest.raises(UserInputError, match=r"generated road \(ISO 8608 class A, seed 3, with its events\): "
                                             r"not a vehicle road: at 11\d\.\d+ m the right track"):
        build_road(RoadSpec.model_validate(spec))
    spec["events"][0]["height"] = 0.2                  # a kerb: a road
    build_road(RoadSpec.model_validate(spec))
    (tmp_path / "road.yaml").write_text("iso_class: A\nlength: 200 m\nevents: [{type: step, position: 120, "
                                        "length: 0, height: 3.0}]\n")
    out = tmp_path / "road.csv"
    err = _refused(["road", "generate", "--spec", str(tmp_path / "road.yaml"), "-o", str(out)], capsys)
    assert "not a vehicle road" in err and not out.exists()


def _pycrg():
    return pytest.importorskip("pycrg")


def test_an_opencrg_grid_holding_1e38_m_is_refused_and_nothing_written(tmp_path, capsys):
    pycrg = _pycrg()
    z = np.random.default_rng(5).normal(0.0, 0.005, (1001, 5))
    z[700:710, :] = 1e38                               # u = 7.00 .. 7.09 m
    path = tmp_path / "huge.crg"
    pycrg.write(path, z, SPACING, np.linspace(-1.7, 1.7, 5), comment="hpsim test: a grid holding 1e38 m")
    out = tmp_path / "road.csv"
    err = _refused(["road", "import", str(path), "-o", str(out)], capsys)
    assert err.startswith(f"hpsim road: error: {path}: not a vehicle road: at u = 6.7 m the left track goes from")
    assert "to 1e+38 m" in err and not out.exists()


def test_a_binary_opencrg_file_damaged_in_its_data_section_is_refused(tmp_path, capsys):
    pycrg = _pycrg()
    z = np.random.default_rng(6).normal(0.0, 0.01, (1001, 35))
    path = tmp_path / "damaged.crg"
    pycrg.write(path, z, SPACING, np.linspace(-1.7, 1.7, 35), fmt="KRBI", comment="hpsim test: damaged copy")
    data = bytearray(path.read_bytes())
    start = data.rindex(b"$$$$")                      # the binary grid follows the last $-line
    start = data.index(b"\n", start) + 1
    rng = np.random.default_rng(7)
    for k in rng.integers(start + (len(data) - start) * 3 // 4, len(data), 400):
        data[int(k)] = int(rng.integers(0, 256))      # noise over the last quarter of the grid
    path.write_bytes(bytes(data))
    out = tmp_path / "road.csv"
    err = _refused(["road", "import", str(path), "-o", str(out)], capsys)
    head = f"hpsim road: error: {path}: not a vehicle road: at u = "
    assert err.startswith(head) and not out.exists()
    # named where the damage begins: within one contact length before the last quarter of the grid
    assert 7.5 - CONTACT_LENGTH_M - SPACING <= float(err[len(head):].split()[0]) <= 10.0
