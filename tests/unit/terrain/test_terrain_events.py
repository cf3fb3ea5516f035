"""Discrete events: exact shapes (values, areas, continuity), placement per track, superposition, validation."""
from __future__ import annotations

import numpy as np
import pytest

from hpsim.config import validate
from hpsim.errors import UserInputError
from terrain import RoadSpec, build_road
from terrain.events import BumpCosine, BumpTrapezoid, Pothole, Ramp, Step, Washboard
from tests.helpers import REPO

S = np.linspace(0.0, 30.0, 300001)  # 0.1 mm grid for areas
DX = S[1] - S[0]


def _ev(cls, **kw):
    return cls.model_validate(kw)


def test_cosine_bump():
    ev = _ev(BumpCosine, type="bump_cosine", position="10 m", length="2 m", height="80 mm")
    z = ev.shape(S)
    assert z[S < 10].max() == 0 and z[S > 12].max() == 0
    assert ev.shape(np.array([11.0]))[0] == pytest.approx(0.08)  # peak h at the middle
    assert ev.shape(np.array([10.5]))[0] == pytest.approx(0.04)  # h/2 at a quarter
    assert np.trapezoid(z, S) == pytest.approx(0.08 * 2 / 2, rel=1e-6)  # area h·L/2
    slope = np.gradient(z, DX)
    assert abs(slope[np.searchsorted(S, 10.0)]) < 1e-3 and abs(slope[np.searchsorted(S, 12.0)]) < 1e-3  # C1
    assert np.max(np.abs(slope)) == pytest.approx(0.08 * np.pi / 2, rel=1e-4)  # max slope h·π/L


def test_trapezoid_bump_and_default_ramp():
    ev = _ev(BumpTrapezoid, type="bump_trapezoid", position=5, length=4, height=0.1, ramp_length=1)
    z = ev.shape(S)
    assert np.trapezoid(z, S) == pytest.approx(0.1 * (4 - 1), rel=1e-6)  # area h·(L - r)
    top = (S >= 6) & (S <= 8)
    np.testing.assert_allclose(z[top], 0.1)
    assert ev.shape(np.array([5.5, 8.5]))[0] == pytest.approx(0.05)
    d = _ev(BumpTrapezoid, type="bump_trapezoid", position=5, length=4, height=0.1)
    assert d.ramp == pytest.approx(1.0)  # default L/4


def test_pothole_with_vertical_and_sloped_walls():
    p = _ev(Pothole, type="pothole", position=3, length="0.6 m", depth="50 mm")
    z = p.shape(S)
    inside = (S - 3 >= 0) & (S - 3 <= 0.6)  # u = s - position in [0, L]
    np.testing.assert_array_equal(z[inside], -0.05)
    np.testing.assert_array_equal(z[~inside], 0.0)
    q = _ev(Pothole, type="pothole", position=3, length=1.0, depth=0.05, edge_length=0.2)
    assert np.trapezoid(q.shape(S), S) == pytest.approx(-0.05 * 0.8, rel=1e-6)


def test_step_and_ramp_keep_their_level():
    st = _ev(Step, type="step", position=4, height="-30 mm")
    assert st.shape(np.array([3.999, 4.0, 25.0])).tolist() == [0.0, -0.03, -0.03]
    sm = _ev(Step, type="step", position=4, height=0.03, length=0.5)
    v = sm.shape(np.array([4.0, 4.25, 4.5, 20.0]))
    np.testing.assert_allclose(v, [0.0, 0.015, 0.03, 0.03], atol=1e-15)
    r = _ev(Ramp, type="ramp", position=2, length=10, height=0.5)
    np.testing.assert_allclose(r.shape(np.array([1.0, 2.0, 7.0, 12.0, 29.0])), [0, 0, 0.25, 0.5, 0.5])
    z = r.shape(S)
    np.testing.assert_allclose(np.gradient(z, DX)[(S > 2.1) & (S < 11.9)], 0.05, rtol=1e-9)


def test_washboard():
    w = _ev(Washboard, type="washboard", position=1, length=6, height="20 mm", wavelength="0.75 m")
    z = w.shape(S)
    inside = (S >= 1) & (S <= 7)
    assert np.trapezoid(z, S) == pytest.approx(0.01 * 6, rel=1e-6)  # mean h/2 over whole cycles
    assert z[inside].max() == pytest.approx(0.02) and z[inside].min() == pytest.approx(0.0, abs=1e-15)
    peaks = np.sum((z[1:-1] > z[:-2]) & (z[1:-1] >= z[2:]))
    assert peaks == 8  # 6 m / 0.75 m
    with pytest.raises(UserInputError, match="whole number of wavelengths"):
        validate(Washboard, dict(type="washboard", position=1, length=6.2, height=0.02, wavelength=0.75),
                 "road.yaml: events.0")


def test_validation_messages():
    with pytest.raises(UserInputError, match="ramp_length must be in"):
        validate(BumpTrapezoid, dict(type="bump_trapezoid", position=0, length=2, height=0.1, ramp_length=1.5),
                 "x")
    with pytest.raises(UserInputError, match="depth must be > 0"):
        validate(Pothole, dict(type="pothole", position=0, length=1, depth=-0.1), "x")
    with pytest.raises(UserInputError, match="position must be >= 0"):
        validate(BumpCosine, dict(type="bump_cosine", position=-1, length=1, height=0.1), "x")
    with pytest.raises(UserInputError, match=r"events\.0 \(bump_cosine\) ends at 10.5 m, beyond the road length 10 m"):
        validate(RoadSpec, dict(flat=True, length=10, events=[dict(type="bump_cosine", position=9.5, length=1,
                                                                      height=0.1)]), "road.yaml")
    with pytest.raises(UserInputError, match="does not match any of the expected tags|union_tag_invalid|tag"):
        validate(RoadSpec, dict(flat=True, length=10, events=[dict(type="speed_hump", position=1)]), "road.yaml")


def test_events_superposed_on_random_road_per_track():
    base = dict(iso_class="C", length="300 m", seed=2)
    events = [dict(type="bump_cosine", position=100, length=1.5, height=0.1, track="left"),
              dict(type="pothole", position=150, length=0.5, depth=0.08, track="right"),
              dict(type="washboard", position=200, length=3.0, height=0.02, wavelength=0.5, track="both"),
              dict(type="step", position=250, height=0.05)]
    plain = build_road(RoadSpec(**base))
    road = build_road(RoadSpec(**base, events=events))
    specs = RoadSpec(**base, events=events).events
    s = road.distance_m
    want_left = specs[0].shape(s) + specs[2].shape(s) + specs[3].shape(s)
    want_right = specs[1].shape(s) + specs[2].shape(s) + specs[3].shape(s)
    np.testing.assert_allclose(road.left_m - plain.left_m, want_left, atol=1e-15)
    np.testing.assert_allclose(road.right_m - plain.right_m, want_right, atol=1e-15)


def test_flat_road_with_events_evaluates_the_exact_shape_at_grid_points():
    road = build_road(RoadSpec(flat=True, length="50 m", spacing="10 mm",
                               events=[dict(type="bump_cosine", position=20, length=2, height=0.1)]))
    s = np.array([19.0, 20.5, 21.0, 21.5, 23.0])
    h, _ = road.evaluate(s, "left")
    np.testing.assert_allclose(h, [0, 0.05, 0.1, 0.05, 0], atol=1e-12)
    h_between, slope = road.evaluate(np.array([20.503]), 1)
    exact = 0.05 * (1 - np.cos(2 * np.pi * 0.503 / 2))
    assert h_between[0] == pytest.approx(exact, abs=1e-8)  # spline error ~ h·(2πΔ/L)^4
    assert slope[0] == pytest.approx(0.05 * np.pi * np.sin(2 * np.pi * 0.503 / 2), rel=1e-4)


def test_example_spec_file_is_valid_and_applies_its_events():
    from pathlib import Path

    from terrain import load_road_spec

    path = REPO / "terrain" / "data" / "example_road.yaml"
    spec = load_road_spec(path)
    assert len(spec.events) == 6
    with_events = build_road(spec, base_dir=path.parent)
    without = build_road(spec.model_copy(update={"events": []}))
    diff = with_events.right_m - without.right_m
    s = with_events.distance_m
    want = sum(ev.shape(s) for ev in spec.events if ev.track in ("right", "both"))
    np.testing.assert_allclose(diff, want, atol=1e-14)
