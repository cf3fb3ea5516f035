"""Road: spline evaluation (NumPy and CasADi), clamping, axles, CSV round trip, resampling, bad files."""
from __future__ import annotations

from pathlib import Path

import casadi as ca
import numpy as np
import pytest

from hpsim.errors import UserInputError
from terrain import Road, RoadSpec, build_road


@pytest.fixture(scope="module")
def road():
    return build_road(RoadSpec(iso_class="D", length="2 km", seed=1))


def test_grid_properties(road):
    assert road.spacing_m == 0.05 and road.n_points == 40001 and road.length_m == pytest.approx(2000.0)
    assert road.distance_m[0] == 0.0 and road.distance_m[-1] == pytest.approx(2000.0)
    with pytest.raises(ValueError):
        road.left_m[0] = 1.0  # read-only: the cached spline slopes stay valid


def test_evaluate_interpolates_and_is_c1(road):
    for track in ("left", "right", 0, 1):
        z = road.heights(track)
        h, _ = road.evaluate(road.distance_m[::7], track)
        np.testing.assert_allclose(h, z[::7], rtol=0, atol=1e-13)  # s/Δ may land a hair below a knot
    # slope continuous across knots: left and right limits agree
    knots = road.distance_m[1000:1010]
    eps = 1e-9
    _, s_minus = road.evaluate(knots - eps, "left")
    _, s_plus = road.evaluate(knots + eps, "left")
    np.testing.assert_allclose(s_minus, s_plus, atol=1e-6)
    # slope is the derivative of the height
    s = np.linspace(100.0, 101.0, 401)
    h, sl = road.evaluate(s, "left")
    d = 1e-6
    num = (road.evaluate(s + d, "left")[0] - road.evaluate(s - d, "left")[0]) / (2 * d)
    np.testing.assert_allclose(sl, num, atol=1e-6)


def test_spline_accuracy_on_a_smooth_profile():
    """Clamped cubic spline: interior error O(Δ⁴) on a smooth wave (≈ (2πΔ/λ)⁴/384 of the amplitude)."""
    x = np.arange(2001) * 0.05
    z = 0.01 * np.sin(2 * np.pi * x / 3.0)
    r = Road(0.05, z, z)
    s = np.linspace(10, 90, 10007)
    h, sl = r.evaluate(s, "left")
    assert np.max(np.abs(h - 0.01 * np.sin(2 * np.pi * s / 3.0))) < 0.01 * (2 * np.pi * 0.05 / 3.0) ** 4 / 100
    np.testing.assert_allclose(sl, 0.01 * 2 * np.pi / 3.0 * np.cos(2 * np.pi * s / 3.0), atol=2e-6)


def test_clamped_outside_the_road(road):
    h, sl = road.evaluate(np.array([-50.0, -0.1, 0.0, road.length_m, road.length_m + 3.0]), "right")
    z = road.right_m
    np.testing.assert_allclose(h, [z[0], z[0], z[0], z[-1], z[-1]], atol=1e-15)
    np.testing.assert_array_equal(sl, 0.0)  # zero end slopes: C1 across the clamp
    _, sl_in = road.evaluate(np.array([1e-6, road.length_m - 1e-6]), "right")
    assert np.max(np.abs(sl_in)) < 1e-3


def test_axles_read_the_same_track_delayed(road):
    offsets = [0.0, 1.55, 3.45, 5.0]
    s = np.linspace(0, 100, 11)
    h, sl = road.evaluate_axles(s, offsets, "left")
    assert h.shape == (4, 11)
    for k, a in enumerate(offsets):
        hk, slk = road.evaluate(s - a, "left")
        np.testing.assert_array_equal(h[k], hk)
        np.testing.assert_array_equal(sl[k], slk)


def test_bad_track_name(road):
    with pytest.raises(UserInputError, match="track: 'middle'"):
        road.evaluate(1.0, "middle")


def test_casadi_function_equals_numpy_spline(road):
    funcs = road.casadi_functions()
    assert set(funcs) == {"left", "right"}
    rng = np.random.default_rng(3)
    s = np.concatenate([rng.uniform(-5, road.length_m + 5, 300), [0.0, road.length_m, 1000.0]])
    for track, f in funcs.items():
        assert f.name_in() == ["s"] and f.name_out() == ["height", "slope"]
        fm = f.map(s.size)
        h, sl = fm(s[None, :])
        h_np, sl_np = road.evaluate(s, track)
        np.testing.assert_allclose(np.array(h).ravel(), h_np, atol=1e-12)
        np.testing.assert_allclose(np.array(sl).ravel(), sl_np, atol=1e-9)
    # usable inside an expression and differentiable: d(height)/ds == slope
    x = ca.MX.sym("x")
    hx, slx = funcs["left"](x)
    g = ca.Function("g", [x], [ca.jacobian(hx, x), slx])
    for v in (12.34, 1500.01):
        dh, sl1 = g(v)
        assert float(dh) == pytest.approx(float(sl1), abs=1e-9)


def test_casadi_window_equals_full_spline_inside(road):
    f = road.casadi_function("left", window_m=(500.0, 520.0))
    s = np.linspace(500.0, 520.0, 57)
    h, sl = f.map(s.size)(s[None, :])
    h_np, sl_np = road.evaluate(s, "left")
    np.testing.assert_allclose(np.array(h).ravel(), h_np, atol=1e-12)
    np.testing.assert_allclose(np.array(sl).ravel(), sl_np, atol=1e-9)
    h_out, sl_out = f(600.0)
    assert float(h_out) == pytest.approx(road.evaluate(520.0, "left")[0], abs=1e-12) and float(sl_out) == 0.0


def test_csv_round_trip(road, tmp_path):
    p = tmp_path / "road.csv"
    road.to_csv(p)
    assert p.read_text().splitlines()[0] == "distance_m,left_m,right_m"
    back = Road.from_csv(p)
    assert back.spacing_m == pytest.approx(road.spacing_m, rel=1e-12) and back.n_points == road.n_points
    np.testing.assert_allclose(back.left_m, road.left_m, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(back.right_m, road.right_m, rtol=1e-9, atol=1e-12)
    assert back.info["resampled"] is False


def _write(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


def test_measured_profile_irregular_and_offset_is_resampled(tmp_path):
    """A profile measured at irregular points from 100 m on: linear in the file -> exact on the new grid."""
    rng = np.random.default_rng(0)
    d = 100.0 + np.cumsum(rng.uniform(0.02, 0.08, 3000))
    rows = "\n".join(f"{a:.6f},{0.01 * (a - 100):.9f},{-0.002 * (a - 100):.9f}" for a in d)
    p = _write(tmp_path / "m.csv", "# measured\nDistance,Left,Right,quality\n" +
               "\n".join(r + ",1" for r in rows.splitlines()) + "\n")
    r = Road.from_csv(p, spacing_m=0.05)
    assert r.info["distance_offset_m"] == pytest.approx(d[0])
    np.testing.assert_allclose(r.left_m, 0.01 * (r.distance_m + d[0] - 100), atol=1e-8)
    np.testing.assert_allclose(r.right_m, -0.002 * (r.distance_m + d[0] - 100), atol=1e-8)


def test_downsampling_averages_over_the_new_spacing(tmp_path):
    """Coarser grid: the box average of width Δ' attenuates a sinusoid by sinc(n·Δ') (anti-aliasing)."""
    x = np.arange(200001) * 0.001
    n = 2.0
    z = np.sin(2 * np.pi * n * x)
    p = tmp_path / "fine.csv"
    Road(0.001, z, z).to_csv(p)
    r = Road.from_csv(p, spacing_m=0.1)
    want = np.sinc(n * 0.1) * np.sin(2 * np.pi * n * r.distance_m)
    # plus the linear interpolation between the 1 mm samples (relative error ~ (π·n·1 mm)², ≈ 4e-5)
    np.testing.assert_allclose(r.left_m[1:-1], want[1:-1], atol=1e-4)


@pytest.mark.parametrize("text, match", [
    ("distance_m,left_m\n0,0\n1,0\n", r"bad\.csv:1: missing column 'right_m'"),
    ("distance_m,left_m,right_m\n0,0,0\n1,0,0\n1,0,0\n", r"bad\.csv:4: distance 1 m does not increase"),
    ("distance_m,left_m,right_m\n0,0,0\n1,nan,0\n2,0,0\n", r"bad\.csv:3: left_m = nan is not a finite number"),
    ("distance_m,left_m,right_m\n0,0,0\n1,abc,0\n", r"bad\.csv:3: the left_m field is not a number"),
    ("distance_m,left_m,right_m\n0,0,0\n1,0\n", r"bad\.csv:3: 2 fields, expected 3"),
    ("", r"bad\.csv: empty file"),
    ("distance_m,left_m,right_m\n0,0,0\n", r"bad\.csv: 1 data row"),
])
def test_malformed_csv_messages_name_file_and_line(tmp_path, text, match):
    p = _write(tmp_path / "bad.csv", text)
    with pytest.raises(UserInputError, match=match):
        Road.from_csv(p)


def test_missing_file(tmp_path):
    with pytest.raises(UserInputError, match="file not found"):
        Road.from_csv(tmp_path / "nope.csv")


def test_spec_csv_relative_to_base_dir_with_events(tmp_path):
    x = np.arange(2001) * 0.1
    Road(0.1, 0.001 * x, 0.0 * x).to_csv(tmp_path / "meas.csv")
    spec = RoadSpec(csv="meas.csv", length="150 m",
                    events=[dict(type="step", position=100, height=0.02, track="right")])
    r = build_road(spec, base_dir=tmp_path)
    assert r.spacing_m == pytest.approx(0.1) and r.length_m == pytest.approx(150.0)  # file spacing kept
    assert r.right_m[-1] == pytest.approx(0.02) and r.left_m[-1] == pytest.approx(0.15)
    r2 = build_road(RoadSpec(csv=str(tmp_path / "meas.csv"), spacing="0.05 m"))
    assert r2.spacing_m == 0.05 and r2.length_m == pytest.approx(200.0)
    with pytest.raises(UserInputError, match="longer than the profile"):
        build_road(RoadSpec(csv="meas.csv", length="1 km"), base_dir=tmp_path)
