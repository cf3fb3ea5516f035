"""Issue 27, the input families (no drive runs): special files, CSVs as loggers write them, output paths, study
arguments and work limits. Every case runs `hpsim ...` in a forked child under a timeout (tests.test_fuzz): exit
code, a one-line message, no traceback, no hang, nothing written outside the named output."""
from __future__ import annotations

import os

import numpy as np
import pytest

from hpsim.errors import UserInputError

from tests.integration.test_fuzz import SCENARIO, VEHICLE_FILE, case_dir, check_user_error, run_case, warm_imports  # noqa: F401

ROAD_ROWS = "".join(f"{0.05 * i:.2f},{0.001 * np.sin(i / 7):.6f},0.0\r\n" for i in range(400))


def one_line(res) -> str:
    lines = [ln for ln in res.err.strip().splitlines() if ln.strip()]
    assert len(lines) == 1, res.err
    return lines[0]


# --- special files as inputs (the reader never blocks on a FIFO nor reads a device for ever) -------------------
def _special(case_dir, kind):
    if kind == "fifo":
        p = case_dir / "in" / "pipe.csv"
        os.mkfifo(p)
        return p, "FIFO"
    return "/dev/zero", "character device"


@pytest.mark.parametrize("kind", ["fifo", "device"])
@pytest.mark.parametrize("reader", ["road psd", "road csv of a run", "speed csv of a run", "scenario"])
def test_special_files_are_refused_at_once(case_dir, kind, reader):
    path, what = _special(case_dir, kind)
    scen = case_dir / "in" / "s.yaml"
    if reader == "road psd":
        argv = ["road", "psd", path]
    else:
        text = SCENARIO
        if reader == "road csv of a run":
            text = text.replace("road: {iso_class: D, seed: 3}", f"road: {{csv: '{path}'}}")
        elif reader == "speed csv of a run":
            text = text.replace("speed: 20 km/h", f"speed: {{csv: '{path}'}}")
        scen.write_text(text)
        argv = ["run", path if reader == "scenario" else scen, "-o", case_dir / "work" / "o.h5", "--no-progress"]
    res = run_case(case_dir, argv, timeout=20)
    check_user_error(res, must_say=(what,))
    one_line(res)


# --- CSVs as loggers and spreadsheets write them ---------------------------------------------------------------
def test_road_csv_with_bom_crlf_and_extra_columns_is_read(tmp_path):
    from terrain.profile_io import read_profile_csv

    plain = tmp_path / "plain.csv"
    plain.write_text("distance_m,left_m,right_m\n" + ROAD_ROWS.replace(",0.0\r\n", ",0.0\n"))
    excel = tmp_path / "excel.csv"
    rows = "".join(line.rstrip("\r") + ",7,x\r\n" for line in ROAD_ROWS.split("\n") if line)
    excel.write_bytes(b"\xef\xbb\xbf" + ("Distance_m,left_m,right_m,gear,note\r\n" + rows).encode())
    for a, b in zip(read_profile_csv(plain), read_profile_csv(excel)):
        np.testing.assert_array_equal(a, b)


def test_road_csv_with_an_ambiguous_header_is_refused(tmp_path):
    from terrain.profile_io import read_profile_csv

    p = tmp_path / "twice.csv"
    p.write_text("distance_m,left_m,left,right_m\n0,0,0,0\n1,0,0,0\n")
    with pytest.raises(UserInputError, match="left_m' appears 2 times"):
        read_profile_csv(p)


def test_speed_csv_with_bom_crlf_and_a_gear_column_gives_the_plain_profile(tmp_path):
    from vehicle.scenario.speed import CsvSpeedSpec, read_speed_csv

    rows = [(0.0, 10.0), (10.0, 20.0), (20.0, 20.0), (40.0, 15.0)]
    plain = tmp_path / "plain.csv"
    plain.write_text("time_s,speed_km_h\n" + "".join(f"{t},{v}\n" for t, v in rows))
    logger = tmp_path / "logger.csv"
    logger.write_bytes(b"\xef\xbb\xbf" + ("time_s,gear,speed_km_h,rpm\r\n"
                                          + "".join(f"{t},3,{v},1800\r\n" for t, v in rows)).encode())
    a = read_speed_csv(CsvSpeedSpec(csv=str(plain)), 50.0)
    b = read_speed_csv(CsvSpeedSpec(csv=str(logger)), 50.0)
    np.testing.assert_array_equal(a.distances_m, b.distances_m)
    np.testing.assert_array_equal(a.speeds_m_per_s, b.speeds_m_per_s)
    twice = tmp_path / "twice.csv"
    twice.write_text("time_s,speed_km_h,speed_m_s\n0,10,3\n10,20,6\n")
    with pytest.raises(UserInputError, match="2 speed columns"):
        read_speed_csv(CsvSpeedSpec(csv=str(twice)), 10.0)


@pytest.mark.parametrize("rows", [2, 3, 31])
@pytest.mark.parametrize("command", ["psd", "plot"])
def test_road_spectrum_of_a_few_rows_is_a_one_line_error(case_dir, rows, command):
    csv = case_dir / "in" / "short.csv"
    csv.write_text("distance_m,left_m,right_m\n" + "".join(f"{i},0.00{i % 3},0\n" for i in range(rows)))
    argv = ["road", command, csv] + (["-o", case_dir / "work" / "p.png"] if command == "plot" else [])
    res = run_case(case_dir, argv)
    check_user_error(res, must_say=(f"{rows} points", "at least 32"))


# --- output paths -------------------------------------------------------------------------------------------
@pytest.mark.parametrize("argv", [["run", "{s}", "-o", ""], ["sweep", "{w}", "-o", ""], ["uq", "{s}", "--samples",
                                                                                          "4", "-o", " "]])
def test_empty_output_path_is_refused(case_dir, argv):
    scen = case_dir / "in" / "s.yaml"
    scen.write_text(SCENARIO)
    (case_dir / "in" / "w.yaml").write_text("base: s.yaml\ngrid: {speed: [20 km/h]}\n")
    argv = [a.format(s=scen, w=case_dir / "in" / "w.yaml") for a in argv]
    res = run_case(case_dir, argv)
    check_user_error(res, must_say=("empty",))


@pytest.mark.parametrize("which", ["scenario", "road csv", "vehicle"])
def test_output_equal_to_an_input_is_refused_even_with_overwrite(case_dir, which):
    d = case_dir / "in"
    (d / "road.csv").write_text("distance_m,left_m,right_m\n" + ROAD_ROWS)
    (d / "vehicle.yaml").write_text(VEHICLE_FILE.read_text())
    text = SCENARIO.replace("vehicle: {name: apc_8x8}", "vehicle: {file: vehicle.yaml}")
    if which == "road csv":
        text = text.replace("road: {iso_class: D, seed: 3}", "road: {csv: road.csv}")
    (d / "s.yaml").write_text(text)
    target = {"scenario": d / "s.yaml", "road csv": d / "road.csv", "vehicle": d / "vehicle.yaml"}[which]
    before = target.read_bytes()
    for extra in ([], ["--overwrite"]):
        res = run_case(case_dir, ["run", d / "s.yaml", "-o", target, "--no-progress"] + extra)
        # one check for every input (hpsim.outputs.check_not_input), in one wording
        check_user_error(res, must_say=(f"-o/--output: {target} is also an input of this command",
                                        "give another output file"))
        assert target.read_bytes() == before


def test_resume_and_overwrite_together_are_refused(case_dir):
    (case_dir / "in" / "s.yaml").write_text(SCENARIO)
    res = run_case(case_dir, ["run", case_dir / "in" / "s.yaml", "-o", case_dir / "work" / "o.h5", "--resume",
                              "--overwrite"])
    check_user_error(res, must_say=("--resume and --overwrite",))


# --- study arguments ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("args,says", [
    (["--samples", "4", "--seed", "-1"], ("--seed", "0")),
    (["--samples", "4", "--parameters", ","], ("--parameters",)),
    (["--samples", "4", "--parameters", "no_such_prior"], ("no_such_prior", "matches no prior")),
    (["--samples", "1000000", "--method", "lhs"], ("--samples", "at most")),
])
def test_uq_arguments_are_one_line_errors(case_dir, args, says):
    (case_dir / "in" / "s.yaml").write_text(SCENARIO)
    res = run_case(case_dir, ["uq", case_dir / "in" / "s.yaml", "-o", case_dir / "work" / "study"] + args,
                   allowed=[case_dir / "work" / "study"])
    check_user_error(res, must_say=says)
    one_line(res)


def test_a_damaged_samples_csv_names_file_and_line_and_is_left_as_it_is(tmp_path):
    from vehicle.studies.uq_files import read_samples as _read_samples

    p = tmp_path / "samples.csv"
    p.write_text('# fingerprint: {"method": "lhs"}\ncase,a,b\nnominal,1,2\ns00000,1.5,oops\n')
    before = p.read_bytes()
    with pytest.raises(UserInputError, match=r"samples.csv:4: case 's00000'"):
        _read_samples(p)
    assert p.read_bytes() == before


def test_a_huge_sweep_grid_is_refused_before_it_is_expanded(case_dir):
    (case_dir / "in" / "s.yaml").write_text(SCENARIO)
    values = ", ".join(f"{20 + 0.01 * i:.2f} km/h" for i in range(100))
    (case_dir / "in" / "w.yaml").write_text(f"base: s.yaml\ngrid:\n  speed: [{values}]\n"
                                            f"  ambient_temperature: [{', '.join(f'{t - 40} degC' for t in range(100))}]\n")
    res = run_case(case_dir, ["sweep", case_dir / "in" / "w.yaml", "-o", case_dir / "work" / "sw"], timeout=15,
                   allowed=[case_dir / "work" / "sw"])
    check_user_error(res, must_say=("10000 cases", "at most"))


def test_case_names_are_sanitised_and_collision_free():
    from vehicle.studies.study_folder import safe_names

    names = safe_names(["../evil", "..", "A b", "Ab", "ab", ".hidden", "study", "x/../../y"])
    assert all("/" not in n and not n.startswith(".") for n in names)
    assert len({n.lower() for n in names}) == len(names)
    assert names[2:5] == ["Ab", "Ab-2", "ab-3"]


# --- work limits (before anything is compiled) ---------------------------------------------------------------
@pytest.mark.parametrize("interval", ["20 s", "3600 s"])
def test_output_interval_longer_than_the_drive_is_refused_before_compiling(case_dir, interval):
    (case_dir / "in" / "s.yaml").write_text(SCENARIO.replace("interval: 1 s", f"interval: {interval}"))
    res = run_case(case_dir, ["run", case_dir / "in" / "s.yaml", "-o", case_dir / "work" / "o.h5", "--no-progress"],
                   timeout=20, env={"HPSIM_CACHE": str(case_dir / "work" / "cache")},
                   allowed=[case_dir / "work" / "cache"])
    check_user_error(res, must_say=("output.interval", "longer than the drive", "10.8 s"))


def test_work_beyond_the_limit_is_refused_with_its_figures():
    from vehicle.scenario.work_limits import MAX_RESULT_BYTES, check, estimate

    # 1000 km at 20 km/h stored every 4 ms: 45 M samples of ~200 values
    est = estimate(180_000.0, 0.004, 0.004, 8, 200)
    assert est["bytes"] > MAX_RESULT_BYTES
    with pytest.raises(UserInputError, match="stored samples.*limit"):
        check(est, "s.yaml")
    # 5 km at 4 ms output, store: all: allowed, announced with its size and time
    est = estimate(900.0, 0.004, 0.004, 8, 8 * 26)
    line = check(est, "s.yaml")
    assert line and "MB of results" in line and "s of computing" in line


# --- what a speed profile asks of the vehicle ----------------------------------------------------------------
@pytest.mark.parametrize("speed,says", [
    ("{profile: [[0 m, 5 km/h], [30 m, 5 km/h], [30.1 m, 150 km/h]]}", "g) at 30"),
    ("{random: {mean: 40 km/h, spread: 10 km/h, correlation_length: 1 m}}", "correlation_length"),
])
def test_profiles_beyond_1_g_are_refused_with_the_figure(case_dir, speed, says):
    """A step 5 -> 150 km/h within 0.1 m asks for v dv/ds = 41.7 m/s * 40.3 m/s / 0.1 m = 1.7e4 m/s^2 (1700 g); a
    random profile of 10 km/h spread over a 1 m correlation length some g. Both refused before anything runs."""
    (case_dir / "in" / "s.yaml").write_text(SCENARIO.replace("speed: 20 km/h", f"speed: {speed}"))
    res = run_case(case_dir, ["run", case_dir / "in" / "s.yaml", "-o", case_dir / "work" / "o.h5", "--no-progress"],
                   timeout=20)
    check_user_error(res, must_say=("longitudinal acceleration", "max_acceleration", says))


def test_the_acceleration_limit_is_exact_and_the_scenario_may_raise_it():
    """A constant-acceleration ramp v^2 = v0^2 + 2 a s (a table fine in speed, as the stop-go ramps): 1.2 g is refused
    at the default 1 g and accepted with max_acceleration: 1.5 g; the figure is the table's (v dv/ds at a segment's
    faster end: the ramp's 1.2 g within the table's speed steps, 11.97 m/s^2 for 11.77)."""
    from vehicle.scenario.speed import SpeedProfile
    from vehicle.scenario.speed_limits import G_M_PER_S2, check_profile

    a = 1.2 * G_M_PER_S2
    v = np.linspace(2.0, 30.0, 400)
    s = (v * v - v[0] ** 2) / (2 * a)
    profile = SpeedProfile(s, v)
    with pytest.raises(UserInputError, match=r"acceleration of 1[12]\.\d+ m/s\^2 \(1\.2\d* g\)"):
        check_profile(profile, float(s[-1]))
    check_profile(profile, float(s[-1]), max_acceleration=1.5 * G_M_PER_S2, max_jerk=1e4)


def test_the_work_per_compiled_call_does_not_grow_with_the_interval():
    """solver.dt 0.1 ms with 1 s output: 10000 steps per sample are 40 pieces of 250 steps in a loop, one sample per
    call (not 10: 1e5 steps of inputs held at once); the defaults stay as they were (250 unrolled steps, 10 samples)."""
    from vehicle.numerics.solvers import _pieces
    from vehicle.scenario.work_limits import samples_per_call

    assert _pieces(10_000) == [250] * 40 and samples_per_call(10_000, 10) == 1
    assert _pieces(250) == [250] and samples_per_call(250, 10) == 10
    assert samples_per_call(1, 10) == 10 and samples_per_call(900_000, 10) == 1
