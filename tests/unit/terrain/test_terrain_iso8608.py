"""ISO 8608 random roads: class table, PSD level and slope per class, RMS, determinism."""
from __future__ import annotations

import hashlib
import subprocess
import sys

import numpy as np
import pytest

from terrain import RoadSpec, build_road, road_statistics
from terrain import iso8608
from terrain.stats import _window_correlations, band_average, octave_bands

LENGTH = "20 km"


def _digest(road) -> str:
    return hashlib.sha256(road.left_m.tobytes() + road.right_m.tobytes()).hexdigest()


def test_class_table_is_geometric_means_with_half_double_limits():
    """ISO 8608 Table 1 / REFERENCE §5: classes a factor 4 apart, limits at half and double."""
    names = list(iso8608.ISO_CLASSES)
    assert names == list("ABCDEFGH")
    g = np.array([iso8608.ISO_CLASS_GD_N0_M3[c] for c in names])
    np.testing.assert_allclose(g[1:] / g[:-1], 4.0)
    assert g[0] == pytest.approx(16e-6)  # class A geometric mean, REFERENCE §5
    for a, b in zip(names[:-1], names[1:]):
        assert iso8608.class_limits(a)[1] == pytest.approx(iso8608.class_limits(b)[0])
    for c in names:
        lo, hi = iso8608.class_limits(c)
        assert np.sqrt(lo * hi) == pytest.approx(iso8608.ISO_CLASS_GD_N0_M3[c])
        assert iso8608.class_of_gd(iso8608.ISO_CLASS_GD_N0_M3[c]) == c
        assert iso8608.class_of_gd(hi * 0.999) == c
    # the upper limit of D is already class E: using class limits as class values is the classic mistake
    assert iso8608.class_of_gd(iso8608.class_limits("D")[1]) == "E"
    assert iso8608.class_of_gd(0.0) is None


def test_band_variance_matches_numerical_integral():
    n = np.geomspace(0.011, 2.83, 200001)
    for w in (1.5, 2.0, 3.0):
        num = np.trapezoid(iso8608.displacement_psd(n, 1e-3, w), n)
        assert iso8608.band_variance(1e-3, w, (0.011, 2.83)) == pytest.approx(num, rel=1e-6)


@pytest.mark.parametrize("iso_class, seed", [("A", 11), ("D", 7), ("H", 3)])
def test_psd_matches_class_within_statistical_tolerance(iso_class, seed):
    """Welch PSD of a 20 km two-track road against Gd(n) = Gd(n0)·(n/n0)^-2 of the class.

    Tolerance (derived, not tuned): Welch with Hann segments of 819.2 m at 50 % overlap gives
    K = 47 segments over 20 km, K_eff = K/(1 + 2·(1/6)²) ≈ 44.6 independent averages, so one
    Welch bin has relative variance 1/K_eff. A 1/3-octave band of m bins (Hann bins correlate
    with r = 4/9, 1/36 at distance 1, 2) has relative variance
    Σ_jk P_j P_k r_|j-k| / (Σ P_j)² / K_eff ≈ 1.94/(m·K_eff); averaging the two tracks divides it
    by 2/(1 + γ²). Gd(n0) and w are the weighted least-squares fit over 20 bands (0.02-2 cycle/m);
    their standard errors se (inverse Fisher matrix) come out as ≈ 1 % for ln Gd(n0) and ≈ 0.005
    for w; we require |ln(Gd_fit/Gd_class)| <= 4·se, |w - 2| <= 4·se_w, and each band mean within
    4.5 of its own standard errors of the model averaged over the same bins (20 bands x 3
    classes: a false alarm has probability ~1e-4). test_terrain_stats checks by Monte Carlo
    that these standard errors are honest.
    """
    spec = RoadSpec(iso_class=iso_class, length=LENGTH, seed=seed)
    road = build_road(spec)
    st = road_statistics(road, iri=False)
    gd = iso8608.ISO_CLASS_GD_N0_M3[iso_class]
    assert st["welch_segments"] >= 40
    assert 0.003 < st["gd_n0_rel_se"] < 0.03
    assert abs(np.log(st["gd_n0_m3"] / gd)) <= 4.0 * st["gd_n0_rel_se"]
    assert abs(st["waviness"] - 2.0) <= 4.0 * st["waviness_se"]
    assert st["iso_class"] == iso_class

    # per band, each track, against the analytic PSD averaged over the same Welch bins
    f = st["frequency_cycle_per_m"]
    edges = octave_bands(*st["fit_band_cycle_per_m"])
    _, r = _window_correlations(int(round(st["segment_length_m"] / road.spacing_m)))
    for key in ("psd_left_m3", "psd_right_m3"):
        idx, mean, relvar = band_average(f, st[key], edges, st["welch_segments_effective"], r)
        model = np.array([iso8608.displacement_psd(f[j], gd).mean() for j in idx])
        z = np.log(mean / model) / np.sqrt(relvar)
        assert np.max(np.abs(z)) < 4.5, (key, z)


@pytest.mark.parametrize("iso_class, seed", [("A", 11), ("D", 7), ("H", 3)])
def test_rms_matches_band_integral(iso_class, seed):
    """Sample variance over L against σ² = ∫ Gd dn over the band.

    For a Gaussian process the sample variance over a length L has variance (1/L)·∫ G(n)² dn
    (Parseval on the autocovariance); for w = 2 this is Gd(n0)²·n0⁴·(n_min⁻³ - n_max⁻³)/(3L),
    ≈ 4 % of σ² for 20 km (the lowest frequencies dominate). Tolerance: 4 standard deviations.
    """
    road = build_road(RoadSpec(iso_class=iso_class, length=LENGTH, seed=seed))
    gd = iso8608.ISO_CLASS_GD_N0_M3[iso_class]
    n1, n2 = iso8608.DEFAULT_BAND_CYCLE_PER_M
    var = iso8608.band_variance(gd, 2.0, (n1, n2))
    sd_var = np.sqrt(gd ** 2 * 0.1 ** 4 * (n1 ** -3 - n2 ** -3) / 3.0 / road.length_m)
    for z in (road.left_m, road.right_m):
        assert abs(np.var(z) - var) <= 4.0 * sd_var


def test_custom_gd_and_waviness_and_band():
    """A custom Gd(n0) and w = 2.5 over a narrower band: the fit recovers both within 4 se."""
    road = build_road(RoadSpec(gd_n0="300e-6 m**3", waviness=2.5, band=[0.02, 2.0], length="20 km", seed=5))
    st = road_statistics(road, fit_band=(0.04, 1.6), iri=False)
    assert abs(np.log(st["gd_n0_m3"] / 300e-6)) <= 4.0 * st["gd_n0_rel_se"]
    assert abs(st["waviness"] - 2.5) <= 4.0 * st["waviness_se"]
    # nothing outside the band: the PSD above n_max is many orders of magnitude down
    f = st["frequency_cycle_per_m"]
    above = st["psd_left_m3"][(f > 2.5) & (f < 8.0)]
    assert above.max() < 1e-6 * iso8608.displacement_psd(2.0, 300e-6, 2.5)


def test_same_seed_same_road_different_seed_different_road():
    a = build_road(RoadSpec(iso_class="D", length="3 km", seed=42))
    b = build_road(RoadSpec(iso_class="D", length="3 km", seed=42))
    c = build_road(RoadSpec(iso_class="D", length="3 km", seed=43))
    assert np.array_equal(a.left_m, b.left_m) and np.array_equal(a.right_m, b.right_m)
    assert not np.allclose(a.left_m, c.left_m)
    # the tracks differ from each other (partial coherence), and the generation is zero-mean Gaussian-like
    assert not np.allclose(a.left_m, a.right_m)


def test_shorter_road_is_prefix_of_longer_one():
    """Streaming generation: same parameters and seed, the 2 km road is bit-for-bit the start of 25 km."""
    short = build_road(RoadSpec(iso_class="C", length="2 km", seed=9))
    long = build_road(RoadSpec(iso_class="C", length="25 km", seed=9))
    n = short.n_points
    assert np.array_equal(short.left_m, long.left_m[:n])
    assert np.array_equal(short.right_m, long.right_m[:n])


def test_reproducible_in_a_fresh_process():
    """Another interpreter (fresh memory layout, import order) produces the identical road."""
    road = build_road(RoadSpec(iso_class="E", length="1 km", seed=123, spacing="0.1 m"))
    code = ("import hashlib; from terrain import RoadSpec, build_road; "
            "r = build_road(RoadSpec(iso_class='E', length='1 km', seed=123, spacing='0.1 m')); "
            "print(hashlib.sha256(r.left_m.tobytes() + r.right_m.tobytes()).hexdigest())")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == _digest(road)


def test_the_two_tracks_on_two_threads_give_the_same_bits_as_one_after_the_other(monkeypatch):
    """The tracks' noise and transforms run beside each other (hpsim.threads.beside_map); the same operations one
    after the other on this thread give the same road bit for bit, its envelope and spline slopes too."""
    from terrain import iso8608, road as road_module

    spec = RoadSpec(iso_class="D", length="3 km", seed=5, coherence="isotropic")
    threaded = build_road(spec)
    threaded_env = threaded.enveloped(0.3).prepare()
    serial_map = lambda fn, items: [fn(x) for x in items]            # noqa: E731
    monkeypatch.setattr(iso8608, "beside_map", serial_map)
    monkeypatch.setattr(road_module, "beside_map", serial_map)
    serial = build_road(spec)
    serial_env = serial.enveloped(0.3)
    assert np.array_equal(threaded.left_m, serial.left_m) and np.array_equal(threaded.right_m, serial.right_m)
    for track in ("left", "right"):
        assert np.array_equal(threaded_env.heights(track), serial_env.heights(track))
        assert np.array_equal(threaded_env.knot_slopes(track), serial_env.knot_slopes(track))   # lazily, here
