"""Left/right coherence: the isotropic formula against the 2-D spectrum, generated roads against the model."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import quad
from scipy.special import kv

from terrain import RoadSpec, build_road, road_statistics
from terrain.coherence import coherence_model, isotropic_coherence
from terrain.stats import octave_bands


def _coherence_from_2d_spectrum(n, track, w):
    """γ(n) of an isotropic surface from first principles: the 2-D spectrum ∝ |k|^-(w+1) integrated
    across the lateral wavenumber m, with and without the lateral phase cos(2π·m·B)."""
    p = (w + 1.0) / 2.0
    # the tail beyond m = 1e4·n holds < 1e-12 of the integral for w >= 2
    num = quad(lambda m: (n * n + m * m) ** -p, 0, 1e4 * n, weight="cos", wvar=2 * np.pi * track,
               limit=500)[0]
    den = quad(lambda m: (n * n + m * m) ** -p, 0, np.inf)[0]
    return num / den


@pytest.mark.parametrize("w", [2.0, 2.5, 3.0])
def test_isotropic_formula_matches_2d_spectrum(w):
    for n in (0.01, 0.05, 0.1, 0.3):
        assert isotropic_coherence(n, 2.5, w) == pytest.approx(_coherence_from_2d_spectrum(n, 2.5, w),
                                                               rel=1e-6, abs=1e-9)


def test_isotropic_w2_is_rho_k1_rho():
    """REFERENCE §5: for w = 2, γ = ρ·K1(ρ), ρ = 2π·n·track; → 1 for long waves."""
    n = np.array([1e-4, 0.02, 0.1, 0.5])
    rho = 2 * np.pi * n * 2.5
    np.testing.assert_allclose(isotropic_coherence(n, 2.5), rho * kv(1, rho), rtol=1e-12)
    assert isotropic_coherence(0.0, 2.5) == 1.0
    assert isotropic_coherence(1e-5, 2.5) == pytest.approx(1.0, abs=1e-3)
    np.testing.assert_array_equal(coherence_model("independent", n, 2.5), 0.0)
    np.testing.assert_array_equal(coherence_model("identical", n, 2.5), 1.0)


def _band_model(st, gamma_fn):
    """The model coherence averaged like the estimate: Σ γ(n_j)·G(n_j) / Σ G(n_j) over each band's bins."""
    f = st["frequency_cycle_per_m"]
    edges = octave_bands(*st["fit_band_cycle_per_m"])
    out = []
    for a, b in zip(edges[:-1], edges[1:]):
        j = (f >= a) & (f < b)
        if j.any():
            g = f[j] ** -2.0
            out.append(np.sum(gamma_fn(f[j]) * g) / np.sum(g))
    return np.array(out)


@pytest.mark.parametrize("track, seed", [(2.5, 21), (1.2, 22)])
def test_generated_isotropic_coherence_follows_model(track, seed):
    """Band-averaged normalised co-spectrum Re G_LR/sqrt(G_LL·G_RR) in 1/3-octave bands against ρ·K1(ρ).

    Tolerance: the estimate behaves like a correlation coefficient from 2·n_eff real pairs, with
    n_eff = K_eff·m/1.94 independent complex Welch samples in a band of m bins (K_eff ≈ 44.6 over
    20 km; 1.94 from the Hann bin correlation), so se ≈ (1 - γ²)/sqrt(2·n_eff) (Fisher), 0.01-0.03
    here; we allow 4.5 se in each of the 20 bands.
    """
    road = build_road(RoadSpec(iso_class="D", length="20 km", seed=seed, track_width=track))
    st = road_statistics(road, iri=False)
    model = _band_model(st, lambda n: isotropic_coherence(n, track))
    est, se = st["bands"]["coherence"], st["bands"]["coherence_se"]
    assert model.size == est.size >= 15
    assert np.all(np.abs(est - model) <= 4.5 * se), np.c_[est, model, se]
    g01 = isotropic_coherence(0.1, track)
    assert abs(st["coherence_at_0p1_cycle_per_m"] - g01) < 0.12
    # a wider track is less coherent at every frequency (model property the estimate must show)
    assert est[0] > est[len(est) // 2]


def test_independent_tracks_have_zero_coherence():
    road = build_road(RoadSpec(iso_class="D", length="20 km", seed=31, coherence="independent"))
    st = road_statistics(road, iri=False)
    est, se = st["bands"]["coherence"], st["bands"]["coherence_se"]
    assert np.all(np.abs(est) <= 4.5 * se)


def test_identical_tracks_are_equal():
    road = build_road(RoadSpec(iso_class="D", length="5 km", seed=32, coherence="identical"))
    np.testing.assert_array_equal(road.left_m, road.right_m)
    st = road_statistics(road, iri=False)
    assert st["coherence_at_0p1_cycle_per_m"] == pytest.approx(1.0, abs=1e-12)


def test_left_track_does_not_depend_on_the_coherence_model():
    """The left track is the same noise through the same filter for every model (only right changes)."""
    roads = [build_road(RoadSpec(iso_class="D", length="2 km", seed=5, coherence=c))
             for c in ("isotropic", "independent", "identical")]
    for r in roads[1:]:
        np.testing.assert_array_equal(r.left_m, roads[0].left_m)
