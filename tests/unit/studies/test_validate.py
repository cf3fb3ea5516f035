"""Predictions against measurements (`hpsim validate`, vehicle.analysis.measurements / instruments,
vehicle.studies.validate) and per-axle priors of `hpsim uq` (hpsim.priors `per`, `correlation`).

- the issue's example measurement file (invented values, a tiny CSV series with a BOM and CRLF) through
  `hpsim validate` on a short drive and on a tiny per-axle UQ study;
- the band edge counts as inside, just beyond it as outside;
- units: degC and K readings give the same rise, daN and N the same load change, mm and m the same height;
- bad measurement files: one line naming the file, the key and the allowed range, exit code 2;
- measurement models: the radiometric equation's limits, the tyre lift's ideal-gas limit, the standing heat
  network cools toward the ambient;
- per-axle priors: independent draws are uncorrelated, rank-correlated draws have the stated correlation, and
  Sobol' indices by group see the per-axle group.
"""
from __future__ import annotations

import json
import math

import numpy as np
import pytest
import yaml

from hpsim.errors import UserInputError
from hpsim.priors import collect_priors, correlated_quantile
from vehicle import cli
from vehicle.analysis import instruments as inst
from vehicle.analysis.measurements import read_measurements
from vehicle.studies import uq
from vehicle.studies.validate import validate
from tests.helpers import MEASUREMENT_POINTS


# the example (values invented), the series shortened to the 150 m drive (27 s)
EXAMPLE = MEASUREMENT_POINTS + """\
series:
  - {quantity: surface_temperature, axle: 1, csv: logs/t1.csv, x: {column: time_s, unit: s}, y: {column: T_C, unit: degC}}
"""
SERIES_CSV = b"\xef\xbb\xbftime_s,T_C\r\n2,45.1\r\n10,45.6\r\n18,46.0\r\n26,46.4\r\n"   # BOM, CRLF
SCENARIO = """\
vehicle:
  name: apc_8x8
  overrides:
    heat.capacity: "2 kJ/K"
    heat.view_factor: {value: 0.5, prior: {uniform: [0.3, 0.7], per: axle}, source: "REFERENCE §10"}
road: {iso_class: D, seed: 3}
speed: 20 km/h
distance: 150 m
ambient_temperature: 25 degC
initial_temperatures: [45 degC, 40 degC, 35 degC, 30 degC]
output: {interval: 1 s, stats_interval: 0.1 km}
"""


@pytest.fixture(scope="module")
def work(tmp_path_factory):
    """A tiny per-axle study of a 150 m drive (LHS, 2 draws + the nominal drive, which is the scenario as
    written: the one-drive prediction) and the example measurement file."""
    import shutil

    d = tmp_path_factory.mktemp("validate")
    (d / "logs").mkdir()
    (d / "logs" / "t1.csv").write_bytes(SERIES_CSV)
    (d / "example.yaml").write_text(EXAMPLE)
    (d / "s.yaml").write_text(SCENARIO)
    assert cli.main(["uq", str(d / "s.yaml"), "--samples", "2", "--method", "lhs", "--workers", "1", "-q",
                     "--parameters", "vehicle.heat.view_factor*", "-o", str(d / "study"), "--json"]) == 0
    shutil.copy(d / "study" / "cases" / "nominal.h5", d / "drive.h5")
    return d


def _point(v, quantity):
    return next(p for p in v["points"] if p["quantity"] == quantity)


def test_example_file_through_validate_on_a_drive(work, capsys):
    assert cli.main(["validate", str(work / "drive.h5"), str(work / "example.yaml"), "--json",
                     "--plot", str(work / "v.png")]) == 0
    v = json.loads(capsys.readouterr().out)
    assert v["kind"] == "drive" and v["drives"] == 1 and (work / "v.png").stat().st_size > 10_000
    for p in v["points"]:
        assert {"quantity", "axle", "predicted", "band", "measured", "inside"} <= set(p)
        assert p["band"][0] <= p["band"][1] and p["inside"] == (p["band"][0] <= p["measured"] <= p["band"][1])
        assert p["difference"] == pytest.approx(p["measured"] - p["predicted"])
    t = _point(v, "surface_temperature")
    assert t["unit"] == "K" and t["measured"] == pytest.approx(60.0) and t["uncertainty"] == pytest.approx(2 * 2 ** 0.5)
    assert _point(v, "height")["measured"] == pytest.approx(70.0) and _point(v, "height")["unit"] == "mm"
    assert _point(v, "wheel_load")["measured"] == pytest.approx(100.0) and _point(v, "wheel_load")["unit"] == "daN"
    # the nominal prediction is the drive's report (axle 1 mean of its two stations)
    from vehicle.analysis.summary import report

    a1 = report(work / "drive.h5")["axles"][0]
    assert t["predicted"] == pytest.approx(a1["T_end_C"] - a1["T_start_C"], abs=1e-9)
    assert _point(v, "height")["predicted"] == pytest.approx(a1["dh_mm"], abs=1e-6)
    assert _point(v, "wheel_load")["predicted"] == pytest.approx(a1["N_after_daN"] - a1["N_before_daN"], abs=1e-6)
    assert v["coverage"]["points"] == 3 and v["coverage"]["inside"] == sum(p["inside"] for p in v["points"])
    s = v["series"][0]
    assert s["samples"] == 4 and s["x"][0] == 2.0 and s["measured"][0] == pytest.approx(45.1)
    err = np.array(s["measured"]) - np.array(s["predicted"])
    assert s["rms_error"] == pytest.approx(math.sqrt(np.mean(err ** 2)))


def test_example_file_through_validate_on_a_per_axle_study(work, capsys):
    study = work / "study"
    s = json.loads((study / "summary.json").read_text())
    assert s["done"] == 2 and s["nominal_done"]
    assert [p["name"] for p in s["parameters"]] == [f"vehicle.heat.view_factor[axle{k}]" for k in (1, 2, 3, 4)]
    # each axle ran with its own draw
    with open(study / "samples.csv") as fh:
        rows = [ln.strip().split(",") for ln in fh if not ln.startswith("#")]
    import h5py

    with h5py.File(study / "cases" / "s00001.h5", "r") as f:
        resolved = json.loads(f["scenario"].attrs["resolved_json"])
    drawn = [float(x) for x in rows[-1][1:]]
    assert [resolved["vehicle"]["axles"][k]["heat"]["view_factor"] for k in range(4)] == pytest.approx(drawn, rel=1e-9)
    assert len(set(np.round(drawn, 9))) == 4
    assert cli.main(["validate", str(study), str(work / "example.yaml"), "--json"]) == 0
    v = json.loads(capsys.readouterr().out)
    assert v["kind"] == "study" and v["drives"] == 2 and v["nominal"].endswith("nominal.h5")
    for p in v["points"]:
        lo, hi = p["predicted_band"]
        assert lo <= p["predicted_median"] <= hi and p["band"][0] <= p["reading_median"] <= p["band"][1]
    assert len(v["series"][0]["band"][0]) == 4
    # without measurements: what the usual instruments would read, per axle
    assert cli.main(["validate", str(study), "--json"]) == 0
    r = json.loads(capsys.readouterr().out)
    assert [(p["instrument"], p["axle"]) for p in r["points"]] == \
        [(i, a) for i in ("pyrometer", "photogrammetry", "scale") for a in (1, 2, 3, 4)]
    for p in r["points"]:
        assert p["band"][0] <= p["reading_median"] <= p["band"][1] and p["compared"] == "change"


def _with(text: str, **repl) -> str:
    for old, new in repl.items():
        text = text.replace(old.replace("_", " "), new)
    return text


def test_band_edge_counts_inside_and_beyond_it_outside(work, tmp_path):
    """The band does not depend on the measured value (only on its uncertainty) and the draws are seeded:
    the same file with the measured value at the band's low edge, and 1e-9 below it, gives the same band.
    Heights in m (the SI unit: no conversion rounding between the file, the comparison and the JSON)."""
    from vehicle.studies.validate import compare_points, read_drive

    d = read_drive(work / "drive.h5")

    def run(after_m: str) -> dict:
        f = tmp_path / "edge.yaml"
        f.write_text("instruments: {photogrammetry: {uncertainty: 5 mm}}\npoints:\n"
                     f"  - {{quantity: height, axle: 2, after: '{after_m} m', instrument: photogrammetry}}\n")
        return compare_points(read_measurements(f).points, [d], d, seed=5)[0]

    p = run("1.5")
    assert p["unit"] == "m"
    at_edge = run(repr(p["band"][0]))
    assert at_edge["band"] == p["band"] and at_edge["measured"] == p["band"][0] and at_edge["inside"]
    beyond = run(repr(p["band"][0] * (1 - 1e-9)))
    assert beyond["band"] == p["band"] and not beyond["inside"]
    assert run(repr(p["band"][1]))["inside"] and not run(repr(p["band"][1] * (1 + 1e-9)))["inside"]


def test_units_degC_and_K_daN_and_N_mm_and_m_read_alike(tmp_path):
    def measured(points: str):
        f = tmp_path / "u.yaml"
        f.write_text("points:\n" + points)
        return [(p.measured, p.measured_uncertainty, p.compared) for p in read_measurements(f).points]

    a = measured("  - {quantity: surface_temperature, axle: 1, before: 20 degC, after: 80 degC, uncertainty: 2 K}\n"
                 "  - {quantity: wheel_load, wheel: 1L, before: 3000 daN, after: 3100 daN, uncertainty: 20 daN}\n"
                 "  - {quantity: height, axle: 2, after: 1470 mm, uncertainty: 5 mm}\n")
    b = measured("  - {quantity: surface_temperature, axle: 1, before: 293.15 K, after: 353.15 K, uncertainty: 2 K}\n"
                 "  - {quantity: wheel_load, wheel: 1L, before: 30 kN, after: 31000 N, uncertainty: 200 N}\n"
                 "  - {quantity: height, axle: 2, after: 1.47 m, uncertainty: 0.005 m}\n")
    for (ma, ua, ca), (mb, ub, cb) in zip(a, b):
        assert ma == pytest.approx(mb, rel=1e-12) and ua == pytest.approx(ub, rel=1e-12) and ca == cb
    assert a[0][0] == pytest.approx(60.0) and a[1][0] == pytest.approx(1000.0) and a[2][0] == pytest.approx(1.47)
    assert a[0][1] == pytest.approx(2 * math.sqrt(2)) and a[2][2] == "after"


@pytest.mark.parametrize("point, message", [
    ("{quantity: surface_temperature, axle: 0, after: 80 degC, uncertainty: 2 K}", "points[0].axle: expected an axle number in [1, 20]"),
    ("{quantity: surface_temperature, axle: 1, after: 80, uncertainty: 2 K}", "points[0].after: expected a quantity with its unit"),
    ("{quantity: surface_temperature, axle: 1, after: 900 degC, uncertainty: 2 K}", "points[0].after: '900 degC' outside the allowed range [-60 degC, 300 degC]"),
    ("{quantity: surface_temperature, axle: 1, after: 80 degC, uncertainty: 2 degC}", "points[0].uncertainty: a temperature uncertainty is a difference"),
    ("{quantity: wheel_load, axle: 1, after: 3100 daN, uncertainty: 2 K}", "points[0].uncertainty: '2 K' has units of"),
    ("{quantity: wheel_load, axle: 1, after: 3100 daN}", "points[0].uncertainty: missing"),
    ("{quantity: tyre_pressure, axle: 1, after: 3 bar}", "points[0].quantity: 'tyre_pressure'; allowed: surface_temperature"),
    ("{quantity: height, wheel: 1X, after: 1 m, uncertainty: 5 mm}", "points[0].wheel: expected an axle number and a side"),
    ("{quantity: height, axle: 9, after: 1 m, uncertainty: 5 mm}", "points[0]: axle 9: the prediction has axles 1-4"),
])
def test_bad_measurement_file_is_one_line_with_file_key_and_range(work, tmp_path, capsys, point, message):
    f = tmp_path / "bad.yaml"
    f.write_text(f"points:\n  - {point}\n")
    assert cli.main(["validate", str(work / "drive.h5"), str(f)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and str(f) in err and message in err, err


def test_bad_series_and_missing_mdf_reader(work, tmp_path):
    (tmp_path / "t.csv").write_text("time_s,T_C\n0,25\n1,oops\n")
    f = tmp_path / "s.yaml"
    f.write_text("series:\n  - {quantity: surface_temperature, axle: 1, csv: t.csv, uncertainty: 1 K,"
                 " x: {column: time_s, unit: s}, y: {column: T_C, unit: degC}}\n")
    with pytest.raises(UserInputError, match=r"t\.csv:3: column 'T_C': expected a number"):
        read_measurements(f)
    f.write_text(f.read_text().replace("unit: s}", "unit: degC}"))
    with pytest.raises(UserInputError, match=r"series\[0\]\.x\.unit: 'degC' is neither a time"):
        read_measurements(f)
    import importlib.util

    if importlib.util.find_spec("asammdf") is None:
        f.write_text("series:\n  - {quantity: oil_temperature, axle: 1, mdf: run.mf4, uncertainty: 1 K,"
                     " y: {channel: T1, unit: degC}}\n")
        with pytest.raises(UserInputError, match=r'pip install "hpsim\[mdf\]"'):
            read_measurements(f)


def test_mdf4_series_by_time_and_by_distance_agree_at_constant_speed(work):
    """An MDF4 log (asammdf) read by its time stamps and by a distance channel: at the drive's constant
    20 km/h the two compare with the same prediction (distance = speed x time)."""
    asammdf = pytest.importorskip("asammdf")
    t = np.array([2.0, 10.0, 18.0, 26.0])
    mdf = asammdf.MDF(version="4.10")
    mdf.append([asammdf.Signal(samples=np.array([45.1, 45.6, 46.0, 46.4]), timestamps=t, name="T1", unit="degC"),
                asammdf.Signal(samples=t * 20 / 3.6, timestamps=t, name="s", unit="m")])
    mdf.save(str(work / "logs" / "run.mf4"), overwrite=True)
    f = work / "mdf.yaml"
    f.write_text("series:\n"
                 "  - {quantity: surface_temperature, axle: 1, mdf: logs/run.mf4, uncertainty: 1 K, y: {channel: T1, unit: degC}}\n"
                 "  - {quantity: surface_temperature, axle: 1, mdf: logs/run.mf4, uncertainty: 1 K,"
                 " x: {channel: s, unit: m}, y: {channel: T1, unit: degC}}\n")
    v = validate(work / "drive.h5", f)
    by_time, by_distance = v["series"]
    assert by_time["x_kind"] == "time" and by_distance["x_kind"] == "distance"
    assert by_time["measured"] == pytest.approx([45.1, 45.6, 46.0, 46.4])
    assert by_distance["predicted"] == pytest.approx(by_time["predicted"], abs=0.02)    # 1 s output sampling


# --- measurement models ---------------------------------------------------------------------------------
def test_radiometric_reading_limits():
    T, Tb = 373.15, 298.15
    assert inst.radiometric_reading_K(T, 0.95, 0.95, Tb) == pytest.approx(T, abs=1e-9)    # right setting
    assert inst.radiometric_reading_K(Tb, 0.7, 0.95, Tb) == pytest.approx(Tb, abs=1e-9)   # at the background
    # a surface of lower emissivity than set reads low; REFERENCE §11: 0-3 K at 100 degC for 0.90-0.95
    low = inst.radiometric_reading_K(T, 0.90, 0.95, Tb)
    assert -3.5 < low - T < -2.0
    # analytic small-error limit: dT = -(de/e) (T^4 - Tb^4) / (4 T^3)
    de = 1e-4
    small = inst.radiometric_reading_K(T, 0.95 - de, 0.95, Tb) - T
    assert small == pytest.approx(-(de / 0.95) * (T ** 4 - Tb ** 4) / (4 * T ** 3), rel=1e-3)


def test_tyre_lift_follows_the_ideal_gas_and_stiffness_law():
    d0, T0, p = 0.033, 298.15, 3.5e5
    assert inst.tyre_lift_m(d0, 0.0, T0, p, 0.15) == 0.0
    # small-rise limit: lift = d0 dp / k1 with dp = (p + p_atm) dT / T0, k1 ~ p (1 + c)
    dT = 1e-3
    assert inst.tyre_lift_m(d0, dT, T0, p, 0.15) == pytest.approx(
        d0 * (p + inst.ATMOSPHERE_PA) * dT / T0 / (p * 1.15), rel=1e-5)
    lifts = inst.tyre_lift_m(d0, np.array([15.0, 40.0]), T0, p, 0.15)
    assert 0 < lifts[0] < lifts[1] < d0 and 1e-3 < lifts[1] < 6e-3     # a few mm (REFERENCE §11)


def test_a_thermocouple_read_at_once_reads_the_oil_and_later_less(work, tmp_path):
    """delay 0: the reading is the model's oil temperature with the noise (0.1 K: the 5-95 % band is
    +-1.645 x 0.1 K around it, sampled by 4000 draws); an hour later the strut has cooled."""
    from vehicle.studies.validate import compare_points, read_drive

    d = read_drive(work / "drive.h5")
    f = tmp_path / "tc.yaml"
    for delay in ("0 s", "60 min"):
        f.write_text(f"instruments: {{tc: {{type: thermocouple, uncertainty: 0.1 K, delay: {delay}}}}}\n"
                     "points:\n  - {quantity: oil_temperature, axle: 1, after: 40 degC, instrument: tc}\n")
        p = compare_points(read_measurements(f).points, [d], d, seed=1)[0]
        lo, hi = p["band"]
        if delay == "0 s":
            assert p["reading_median"] == pytest.approx(p["predicted"], abs=0.02)
            assert hi - lo == pytest.approx(2 * 1.645 * 0.1, rel=0.1)
        else:
            assert hi < p["predicted"] - 1.0


@pytest.mark.parametrize("warming_K", [0.0, 2.0])
def test_a_strut_that_did_not_warm_reads_no_pyrometer_change(work, tmp_path, warming_K):
    """The pyrometer's offsets (the visible spot below the hidden hottest part, the emissivity) scale with the
    skin's excess over the ambient and the same spot is read before and after: a strut standing at the ambient
    that did not warm reads a change band holding 0 with a median within the noise (0.1 K per reading: the
    5-95 % band of a change is +-1.645 x 0.14 K); one warmed by 2 K reads a warming of less than 2 K (the
    spot up to 18.5 % below, minutes of cooling of the fixture's light 2 kJ/K struts), never a cooling."""
    import dataclasses

    from vehicle.studies.validate import compare_points, read_drive

    d = read_drive(work / "drive.h5")
    T0 = np.full_like(d.T_start, d.ambient_K)
    d = dataclasses.replace(d, T_start=T0, T_oil=T0 + warming_K, T_wall=T0 + warming_K, T_surface=T0 + warming_K)
    f = tmp_path / "pyro.yaml"
    f.write_text("instruments: {pyro: {type: pyrometer, uncertainty: 0.1 K}}\npoints:\n"
                 "  - {quantity: surface_temperature, axle: 1, before: 25 degC, after: 25 degC, instrument: pyro}\n")
    p = compare_points(read_measurements(f).points, [d], d, seed=1)[0]
    lo, hi = p["band"]
    if warming_K == 0.0:
        assert lo < 0.0 < hi and hi - lo < 0.5
        assert abs(p["reading_median"]) < 0.03
    else:
        assert 0.2 < p["reading_median"] < warming_K and lo > -0.3


def test_a_temperature_reading_band_width_is_relative_to_its_excess_over_the_ambient(work, tmp_path):
    """A strut read at 80 degC with the ambient at 25 degC: the band width is a fraction of the 55 K excess, not
    of 353 K (which makes any band look narrow)."""
    from vehicle.studies.validate import compare_points, read_drive

    d = read_drive(work / "drive.h5")
    f = tmp_path / "after.yaml"
    f.write_text("instruments: {pyro: {type: pyrometer, uncertainty: 1 K}}\npoints:\n"
                 "  - {quantity: surface_temperature, axle: 1, after: 80 degC, instrument: pyro}\n")
    p = compare_points(read_measurements(f).points, [d], d, seed=1)[0]
    width = p["band"][1] - p["band"][0]
    assert p["relative_width"] == pytest.approx(width / (353.15 - d.ambient_K), rel=1e-9)
    assert d.ambient_K == pytest.approx(298.15)


def test_standing_struts_cool_toward_the_ambient(work):
    from vehicle.studies.validate import read_drive

    d = read_drive(work / "drive.h5")
    T = d.network.cool(d.T_oil, d.T_wall, d.T_surface, [0.0, 600.0, 3600.0, 8 * 3600.0])
    assert T[:, :, 0] == pytest.approx(np.stack([d.T_oil, d.T_wall, d.T_surface]), abs=1e-9)
    hot = np.stack([d.T_oil, d.T_wall, d.T_surface]).mean(axis=0) > d.ambient_K + 5
    assert np.all(np.diff(T.mean(axis=0)[hot], axis=-1) < 0)                    # the heat content falls
    assert np.all(T >= d.ambient_K - 1e-6)                                       # never below the ambient
    assert np.all(np.abs(T[:, :, -1] - d.ambient_K) < 0.05 * (T[:, :, 0].max() - d.ambient_K))


# --- per-axle priors ------------------------------------------------------------------------------------
def _per_axle_params(correlation: float | None):
    corr = "" if correlation is None else f", correlation: {correlation}"
    data = yaml.safe_load(f"heat: {{view_factor: {{value: 0.5, prior: {{uniform: [0.3, 0.7], per: axle{corr}}}}}}}")
    return uq.parameters_from(collect_priors(data, "v.yaml"), "vehicle", "vehicle", n_axles=4)


def _draws(params, n=256, method="lhs"):
    X = uq.design(params, method, n, seed=1)
    names = [p.name for p in params]
    return np.array([[uq.physical_values(params, dict(zip(names, x)))[f"vehicle.heat.view_factor[axle{k}]"]
                      for k in (1, 2, 3, 4)] for x in X])


def test_per_axle_draws_are_independent_or_have_the_stated_rank_correlation():
    """256 draws: under independence Spearman's rho has a standard deviation 1/sqrt(n - 1) = 0.063, and for a
    correlation rho its Fisher z = atanh(r) one of sqrt(1.06 / (n - 3)) = 0.065 (Fieller, Hartley & Pearson
    1957): the tolerances are 4 of them (a failure by chance: < 1e-4)."""
    from scipy.stats import spearmanr

    ind = _per_axle_params(None)
    assert len(ind) == 4 and {p.section for p in ind} == {"vehicle.heat.view_factor (per axle)"}
    V = _draws(ind)
    assert V.min() >= 0.3 and V.max() <= 0.7
    for i in range(4):
        for j in range(i + 1, 4):
            assert abs(spearmanr(V[:, i], V[:, j]).statistic) < 4 / math.sqrt(255)
    cor = _per_axle_params(0.5)
    assert len(cor) == 5 and cor[0].latent == "common"
    V = _draws(cor)
    tol = 4 * math.sqrt(1.06 / 253)
    for i in range(4):
        for j in range(i + 1, 4):
            r = spearmanr(V[:, i], V[:, j]).statistic
            assert abs(math.atanh(r) - math.atanh(0.5)) < tol, (i, j, r)
    # every draw stays a draw of the prior (uniform 0.3..0.7: mean 0.5, sd 0.4/sqrt(12))
    assert V.min() >= 0.3 and V.max() <= 0.7 and V.mean() == pytest.approx(0.5, abs=4 * 0.115 / math.sqrt(1024))
    # the nominal case gives the file's value on every axle
    nom = uq.physical_values(cor, {p.name: p.nominal() for p in cor})
    assert [nom[p.name] for p in cor[1:]] == pytest.approx([0.5] * 4, abs=1e-9)


def test_copula_gives_the_stated_rank_correlation_precisely():
    """The normal correlation 2 sin(pi r / 6) gives Spearman r (Kruskal 1958): over 200000 pairs the sample
    rho has a standard deviation < 0.002, well below the 0.018 by which the plain normal correlation would
    miss r = 0.5 (6/pi asin(0.25) = 0.482)."""
    from scipy.stats import spearmanr

    rng = np.random.default_rng(0)
    zc, z1, z2 = rng.standard_normal((3, 200_000))
    for r in (0.2, 0.5, 0.8):
        rho = spearmanr(correlated_quantile(zc, z1, r), correlated_quantile(zc, z2, r)).statistic
        assert rho == pytest.approx(r, abs=0.008)


def test_per_axle_prior_errors_and_sobol_by_group(tmp_path):
    with pytest.raises(UserInputError, match=r"v\.yaml: tyre\.stiffness\.prior: give shared .* or per"):
        collect_priors(yaml.safe_load("tyre: {stiffness: {value: 1, prior: {uniform: [0, 2], per: axle, shared: t}}}"),
                       "v.yaml")
    with pytest.raises(UserInputError, match=r"correlation: expected a number in \[0, 1\)"):
        collect_priors(yaml.safe_load("heat: {view_factor: {value: 0.5, prior: {uniform: [0.3, 0.7], per: axle, "
                                      "correlation: 1.2}}}"), "v.yaml")
    with pytest.raises(UserInputError, match=r"v\.yaml: hull\.cg_height\.prior\.per: 'axle' is allowed on"):
        uq.parameters_from(collect_priors(yaml.safe_load("hull: {cg_height: {value: 1.3, prior: {uniform: [1.1, 1.5], "
                                                         "per: axle}}}"), "v.yaml"), "vehicle", "vehicle", n_axles=4)
    # an additive model y = sum of the per-axle draws + x: by group the per-axle group's total index is its
    # variance share (4 x var(U(0.3, 0.7)) against var(x) = 4 x the same: 0.5 each)
    data = yaml.safe_load("heat: {view_factor: {value: 0.5, prior: {uniform: [0.3, 0.7], per: axle}}}\n"
                          "x: {value: 0.0, prior: {uniform: [-0.4, 0.4]}}")
    params = uq.parameters_from(collect_priors(data, "v.yaml"), "", "vehicle", n_axles=4)
    s = uq.run_study(tmp_path / "g", params, _additive, method="sobol", samples=512, seed=2, groups="section", workers=1)
    rows = {r["parameter"]: r for r in s["sobol"]["y"]["rows"]}
    assert set(rows) == {"heat.view_factor (per axle)", "x"}
    assert rows["heat.view_factor (per axle)"]["ST"] == pytest.approx(0.5, abs=0.05)
    assert rows["x"]["S1"] == pytest.approx(0.5, abs=0.05)


def _additive(case: str, values: dict) -> dict:
    return {"y": sum(v for k, v in values.items() if k.startswith("heat.view_factor")) + values["x"]}
