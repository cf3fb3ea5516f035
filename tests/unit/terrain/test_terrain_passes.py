"""Road per pass and random event populations (issue 10 §3).

A pass factor scales the surface exactly; a smoothing length filters it with the moving-average
transfer function (the measured transfer and PSD ratio match it); persistent level changes are left
alone; random potholes/bumps have the requested density within Poisson tolerance and sizes with
the requested mean; the existing signatures keep working.
"""
import numpy as np
import pytest
from scipy.signal import csd, welch

from hpsim.config import validate
from hpsim.errors import UserInputError
from terrain import RoadSpec, build_road
from terrain.envelope import envelope_transfer
from terrain.passes import PassSpec, pass_transfer


@pytest.fixture(scope="module")
def rough():
    spec = dict(iso_class="D", length="4 km", seed=11, spacing=0.05)
    return (build_road(RoadSpec(**spec)),
            build_road(RoadSpec(**spec, passes=[{}, {"factor": 0.8}, {"factor": 1.0, "smoothing_length": "0.5 m"}])))


def test_default_pass_and_omitted_pass_index_are_the_road_as_built(rough):
    plain, passes = rough
    s = np.linspace(-5.0, 4005.0, 2001)
    for track in ("left", "right"):
        h0, d0 = plain.evaluate(s, track)
        h, d = passes.evaluate(s, track)
        assert np.array_equal(h, h0) and np.array_equal(d, d0)
        assert np.array_equal(passes.evaluate(s, track, pass_index=0)[0], h0)
        assert np.array_equal(plain.evaluate(s, track, pass_index=7)[0], h0)       # no pass list: all alike


def test_pass_factor_scales_the_surface_exactly(rough):
    _, road = rough
    s = np.linspace(0.0, 4000.0, 5001)
    h0, d0 = road.evaluate(s, "left", pass_index=0)
    h1, d1 = road.evaluate(s, "left", pass_index=1)
    assert np.allclose(h1, 0.8 * h0, rtol=0, atol=1e-15) and np.allclose(d1, 0.8 * d0, rtol=0, atol=1e-13)
    # passes beyond the list repeat its last entry
    assert np.array_equal(road.evaluate(s, "right", pass_index=9)[0], road.evaluate(s, "right", pass_index=2)[0])
    # the CasADi spline reads the same pass surface
    f = road.casadi_function("left", window_m=(1000.0, 1100.0), pass_index=1)
    x = np.linspace(1010.0, 1090.0, 7)
    assert np.allclose([float(f(v)[0]) for v in x], road.evaluate(x, "left", pass_index=1)[0], atol=1e-12)


def test_smoothing_filters_with_the_moving_average_transfer_function(rough):
    _, road = rough
    z0 = road.heights("left", 0)
    z2 = road.heights("left", 2)
    fs = 1.0 / road.spacing_m
    n, Pxy = csd(z0, z2, fs=fs, nperseg=4096)
    _, Pxx = welch(z0, fs=fs, nperseg=4096)
    _, Pyy = welch(z2, fs=fs, nperseg=4096)
    H = pass_transfer(n, PassSpec(smoothing_length=0.5), road.spacing_m)
    assert np.allclose(H, envelope_transfer(n, 0.5, road.spacing_m))
    band = (n > 0.05) & (n < 2.8) & (np.abs(H) > 0.2)
    assert np.allclose(np.real(Pxy[band] / Pxx[band]), H[band], rtol=0.02, atol=0.005)
    assert np.allclose(Pyy[band] / Pxx[band], H[band] ** 2, rtol=0.05, atol=0.005)
    # above 1/L the PSD falls (first zero of sin(pi n L)/(pi n L) at n = 1/L = 2 cycle/m)
    above = (n > 1.6) & (n < 2.4)
    assert np.all(Pyy[above] < 0.2 * Pxx[above])
    below = (n > 0.02) & (n < 0.1)
    assert np.allclose(Pyy[below] / Pxx[below], 1.0, atol=0.03)


def test_passes_leave_steps_and_ramps_but_scale_bumps():
    spec = RoadSpec(flat=True, length=100.0, spacing=0.05, passes=[{}, {"factor": 0.5}],
                    events=[{"type": "step", "position": 20.0, "height": 0.1, "length": 0.5},
                            {"type": "bump_cosine", "position": 60.0, "length": 1.0, "height": 0.08}])
    road = build_road(spec)
    s = np.array([10.0, 40.0, 60.5, 90.0])
    h0 = road.evaluate(s, "left", pass_index=0)[0]
    h1 = road.evaluate(s, "left", pass_index=1)[0]
    assert h0 == pytest.approx([0.0, 0.1, 0.18, 0.1])
    assert h1 == pytest.approx([0.0, 0.1, 0.14, 0.1])          # level kept, bump halved
    assert road.enveloped(0.35).evaluate(np.array([90.0]), "left", pass_index=1)[0] == pytest.approx([0.1])


def test_pothole_population_has_the_requested_density_and_sizes():
    length_km = 500.0
    spec = RoadSpec(flat=True, length=f"{length_km} km", spacing=1.0, seed=3,
                    populations=[{"type": "pothole", "density": "2 /km",
                                  "length": {"uniform": ["3 m", "5 m"]},
                                  "depth": {"lognormal": {"median": "5 cm", "sigma": 0.4}}},
                                 {"type": "bump_cosine", "density": "0.5 /km", "length": "4 m",
                                  "height": {"normal": {"mean": "6 cm", "sd": "1 cm"}}, "track": "both"}])
    road = build_road(spec)
    n_pot, n_bump = road.info["population_counts"]
    for n, rate in ((n_pot, 2.0), (n_bump, 0.5)):
        expected = rate * length_km
        assert abs(n - expected) < 4.0 * np.sqrt(expected)                  # Poisson: sd = sqrt(mean)
    # sizes: the deepest points of the potholes on the two tracks (random track, half each)
    from terrain.events import population_rng

    events = spec.populations[0].realise(length_km * 1e3, population_rng(3, 0, None))
    depths = np.array([e.depth for e in events])
    mean = spec.populations[0].depth.mean()                                 # 5 cm * exp(0.4^2 / 2)
    assert depths.mean() == pytest.approx(mean, abs=4 * depths.std() / np.sqrt(depths.size))
    left = sum(e.track == "left" for e in events)
    assert abs(left - 0.5 * len(events)) < 4 * np.sqrt(0.25 * len(events))
    assert road.left_m.min() == pytest.approx(-max(e.depth for e in events if e.track == "left"))
    assert road.right_m.max() > 0.03                                          # bumps on both tracks


def test_a_population_does_not_change_the_random_road_beneath():
    base = dict(iso_class="C", length="1 km", seed=4)
    plain = build_road(RoadSpec(**base))
    with_pop = build_road(RoadSpec(**base, populations=[{"type": "pothole", "density": "10 /km", "length": "1 m",
                                                         "depth": "4 cm", "track": "left"}]))
    diff = with_pop.left_m - plain.left_m
    assert np.array_equal(with_pop.right_m, plain.right_m)
    assert np.sum(diff < 0) > 0 and np.all(diff <= 0)
    assert np.array_equal(build_road(RoadSpec(**base, populations=[{"type": "pothole", "density": "10 /km",
                                                                    "length": "1 m", "depth": "4 cm",
                                                                    "track": "left"}])).left_m, with_pop.left_m)


@pytest.mark.parametrize("data,needle", [
    ({"passes": [{"factor": 3}]}, "passes.0: factor must be in [0, 2]"),
    ({"passes": [{"smoothing_length": "-1 m"}]}, "passes.0: smoothing_length must be in [0, 100] m"),
    ({"populations": [{"type": "pothole", "density": "2 /km", "length": "1 m"}]}, "needs `depth`"),
    ({"populations": [{"type": "bump_cosine", "density": "2 /km", "length": {"gamma": 1}, "height": "5 cm"}]},
     "populations.0.length"),
    ({"populations": [{"type": "pothole", "density": "5000 /km", "length": "1 m", "depth": "5 cm"}]},
     "density must be in [0, 1000] /km"),
])
def test_bad_pass_and_population_settings_name_the_key(data, needle):
    with pytest.raises(UserInputError) as exc:
        validate(RoadSpec, dict(flat=True, length=100.0, **data), "road.yaml")
    assert needle in str(exc.value) and "road.yaml" in str(exc.value)


def test_long_wave_content_is_reachable_from_the_spec():
    spec = RoadSpec(iso_class="D", waviness=1.5, band=[0.004, 2.83], length="2 km")
    assert spec.waviness == 1.5 and spec.band[0] == 0.004 and spec.gd_n0_m3 == pytest.approx(1024e-6)
