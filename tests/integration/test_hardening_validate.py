"""`hpsim validate` on hostile input: arguments checked before any computing, MDF4 channels that hold no numbers or
too many samples, a log whose x unit is mixed up (the unit that would overlap is named), a study whose failed draws
are not in its bands (said so). One line, exit code 2, no traceback."""
from __future__ import annotations

import json
from types import SimpleNamespace

import numpy as np
import pytest

from hpsim.errors import UserInputError
from vehicle.analysis import measurements
from vehicle.analysis.measurements import Instrument, Series, read_mdf_channels
from vehicle.studies.validate import compare_series, failed_cases, format_readings, format_validation

from tests.integration.test_fuzz import case_dir, check_user_error, run_case, warm_imports  # noqa: F401


def _results(case_dir):
    import shutil

    src = __file__.rsplit("/", 2)[0] + "/data/results_v1.h5"
    shutil.copy(src, case_dir / "in" / "r.h5")
    return case_dir / "in" / "r.h5"


@pytest.mark.parametrize("extra, says", [(["--seed=-1"], "--seed"), (["--plot", "v.txt"], "--plot"),
                                         (["--plot", "{r}"], "also an input")])
def test_arguments_are_checked_before_any_computing(case_dir, extra, says, monkeypatch):
    """The results file is one the comparison cannot read (an old format): a message about the argument, not about
    the file, shows the argument was checked first."""
    r = _results(case_dir)
    res = run_case(case_dir, ["validate", r, *[e.replace("{r}", str(r)) for e in extra]])
    check_user_error(res, must_say=(says,))
    assert "oil_temperature" not in res.err


# --- MDF4 channels --------------------------------------------------------------------------------------------------
@pytest.fixture
def mdf_file(tmp_path):
    asammdf = pytest.importorskip("asammdf")
    mdf = asammdf.MDF(version="4.10")
    t = np.arange(5.0)
    mdf.append([asammdf.Signal(samples=np.array([b"a", b"bb", b"c", b"d", b"e"]), timestamps=t, name="label",
                               encoding="utf-8")])
    mdf.append([asammdf.Signal(samples=20.0 + t, timestamps=t, name="T1", unit="degC")])
    path = tmp_path / "run.mf4"
    mdf.save(str(path))
    return path


def test_an_mdf_string_channel_is_one_line_naming_it(mdf_file):
    with pytest.raises(UserInputError, match=r"channel 'label' of .*run\.mf4 holds byte strings, not numbers"):
        read_mdf_channels(mdf_file, "label", None, "series[0]")
    with pytest.raises(UserInputError, match=r"channel 'label' .* not numbers"):
        read_mdf_channels(mdf_file, "T1", "label", "series[0]")          # a text channel as the distance
    x, y = read_mdf_channels(mdf_file, "T1", None, "series[0]")
    np.testing.assert_array_equal(y, 20.0 + x)


def test_an_mdf_series_has_the_csv_row_limit(mdf_file, monkeypatch):
    """One limit for a series, whichever file it comes from: the channel's sample count is checked before its samples
    are read (the limit lowered here to the test file's size)."""
    monkeypatch.setattr(measurements, "MAX_SERIES_ROWS", 4)
    with pytest.raises(UserInputError, match=r"channel 'T1' of .*: 5 samples, at most 4 in one series"):
        read_mdf_channels(mdf_file, "T1", None, "series[0]")
    monkeypatch.setattr(measurements, "MAX_SERIES_ROWS", 5)
    assert read_mdf_channels(mdf_file, "T1", None, "series[0]")[1].size == 5


# --- a log in the wrong unit ----------------------------------------------------------------------------------------
def _drive(length_m=2000.0, duration_s=360.0):
    t = np.linspace(0.0, duration_s, 50)
    return SimpleNamespace(name="drive.h5", per_axle=2, heights_charged=np.zeros(4),
                           series={"strut_temperature": (t, t / duration_s * length_m, np.full((50, 8), 300.0))})


def _series(x, x_kind, x_unit):
    inst = Instrument(name="thermocouple", type="thermocouple", uncertainty=1.0, unit="K")
    return Series(where="series[0]", quantity="surface_temperature", axle=1, side=None, x=np.asarray(x, float),
                  x_kind=x_kind, y=np.full(len(x), 300.0), unit="K", instrument=inst, uncertainty=1.0,
                  file="log.csv", x_unit=x_unit)


@pytest.mark.parametrize("written, kind, declared, would", [
    ([100.0, 1000.0, 1900.0], "distance", "km", "m"),    # metres declared as km: 100 km .. 1900 km
    ([30.0, 180.0, 330.0], "time", "min", "s"),           # seconds declared as minutes
    ([1e3, 2e5, 3.5e5], "time", "s", "ms"),              # milliseconds declared as seconds
])
def test_a_unit_mix_up_names_the_unit_that_would_overlap(written, kind, declared, would):
    """The drive: 2 km in 360 s. A log whose numbers fit it in another unit of the same kind names that unit."""
    scale = {"m": 1.0, "km": 1000.0, "s": 1.0, "min": 60.0}[declared]
    with pytest.raises(UserInputError, match=rf"does not overlap .*read in {would} \(not {declared}\) it would"):
        compare_series(_series(np.asarray(written) * scale, kind, declared), [_drive()], None)


def test_a_log_outside_the_drive_in_any_unit_says_only_that():
    with pytest.raises(UserInputError, match=r"does not overlap the drive's 0 \.\. 2000 m$"):
        compare_series(_series([5e7, 6e7, 7e7], "distance", "m"), [_drive()], None)


# --- a study with failed draws ----------------------------------------------------------------------------------
def test_the_bands_of_a_study_say_they_exclude_its_failed_draws(tmp_path):
    records = [{"case": "nominal", "status": "done"}, {"case": "d0001", "status": "done"},
               {"case": "d0002", "status": "failed", "error": "solver"}, {"case": "d0003", "status": "interrupted"},
               {"case": "d0003", "status": "done"}]
    (tmp_path / "cases.jsonl").write_text("".join(json.dumps(r) + "\n" for r in records) + "not json\n")
    assert failed_cases(tmp_path) == ["d0002"]
    assert failed_cases(tmp_path / "missing") == []
    v = {"prediction": str(tmp_path), "kind": "study", "drives": 2, "measurements": "m.yaml", "description": "",
         "points": [], "series": [], "nominal": None, "instruments": {}, "excluded_cases": failed_cases(tmp_path)}
    for text in (format_validation(v), format_readings(v)):
        assert "2 finished drive(s); 1 failed draw(s) are excluded (d0002)" in text
    v["excluded_cases"] = []
    assert "excluded" not in format_validation(v)
