"""The road PSD figure draws the Welch estimate only over the ISO 8608 band, where it follows the generating PSD."""
from __future__ import annotations

import numpy as np
import pytest

from terrain import RoadSpec, build_road, iso8608, road_statistics
from terrain.plots import draw_psd, psd_drawn

# a generated road's single Welch bins scatter about the generating PSD (chi-square with about 2 x 23 segments'
# degrees of freedom, within 0.44-1.9 here); outside the band or at its edges they fall by orders of magnitude
BIN_SCATTER_FACTOR = 4.0


@pytest.fixture(scope="module")
def class_c_psd_axes():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    stats = road_statistics(build_road(RoadSpec(iso_class="C", length="10 km", seed=3)), iri=False)
    fig, ax = plt.subplots()
    draw_psd(ax, stats)
    yield ax
    plt.close(fig)


def _welch_lines(ax):
    lines = [ln for ln in ax.get_lines() if ln.get_label().startswith(("left (Welch", "right (Welch"))]
    assert len(lines) == 2
    return lines


def test_the_estimate_is_drawn_only_inside_the_iso_band(class_c_psd_axes):
    lo, hi = iso8608.DEFAULT_BAND_CYCLE_PER_M
    for line in _welch_lines(class_c_psd_axes):
        n = np.asarray(line.get_xdata())
        assert n.size > 1000 and lo <= n.min() and n.max() <= hi
        assert n.min() < 1.5 * lo and n.max() > hi / 1.05        # and over (nearly) all of it
        x0, x1 = class_c_psd_axes.get_xlim()
        assert x0 < n.min() and x1 > hi                          # none of it cut off


def test_every_drawn_bin_follows_the_generating_psd(class_c_psd_axes):
    """No tail below the band and no drop at its top edge: each drawn bin within the scatter of a Welch estimate
    of the class C road's own PSD (ISO 8608 eq. for Gd(n), w = 2)."""
    for line in _welch_lines(class_c_psd_axes):
        n, g = np.asarray(line.get_xdata()), np.asarray(line.get_ydata())
        ratio = g / iso8608.displacement_psd(n, iso8608.ISO_CLASS_GD_N0_M3["C"])
        assert 1 / BIN_SCATTER_FACTOR < ratio.min() and ratio.max() < BIN_SCATTER_FACTOR, (ratio.min(), ratio.max())


def test_bins_within_the_window_main_lobe_of_a_band_edge_are_not_drawn():
    f = 0.005 + 0.01 * np.arange(300)              # bins 0.01 cycle/m apart, between round numbers
    kept = f[psd_drawn(f, band=(0.1, 2.0))]        # two bins (0.02 cycle/m) in from each edge
    assert kept.min() == pytest.approx(0.125) and kept.max() == pytest.approx(1.975)
