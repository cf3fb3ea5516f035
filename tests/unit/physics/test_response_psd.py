"""Response PSDs from stored series (vehicle.analysis.psd, `hpsim report --psd`): a known signal's PSD peaks
at its frequency and integrates to its variance (Parseval); series too sparse for the modes are refused
with the interval to use."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from hpsim.errors import UserInputError
from vehicle.analysis.psd import response_psd
from tests.helpers import REPO


class SeriesView:
    name = "<synthetic>"

    def __init__(self, fs, duration, seed=0):
        t = np.arange(0.0, duration, 1.0 / fs)
        rng = np.random.default_rng(seed)
        self.data = {"time": t,
                     "heave_acceleration": 0.8 * np.sin(2 * np.pi * 1.6 * t) + 0.05 * rng.standard_normal(t.size),
                     "pitch_acceleration": 0.3 * np.sin(2 * np.pi * 0.9 * t),
                     "roll_acceleration": 0.2 * np.sin(2 * np.pi * 2.4 * t),
                     "strut_force": 3e4 + np.stack([2e3 * np.sin(2 * np.pi * (1 + k) * t) for k in range(4)], 1)}

    def series(self, name):
        return self.data.get(name)


def test_psd_peaks_at_the_signal_frequency_and_integrates_to_its_variance():
    view = SeriesView(fs=100.0, duration=200.0)
    out = response_psd(view)
    f, df = out["f_hz"], out["f_hz"][1] - out["f_hz"][0]
    assert out["fs_hz"] == pytest.approx(100.0)
    assert out["peaks"]["heave_acceleration"][0] == pytest.approx(1.6, abs=df)
    assert out["peaks"]["pitch_acceleration"][0] == pytest.approx(0.9, abs=df)
    np.testing.assert_allclose(out["peaks"]["strut_force"], [1, 2, 3, 4], atol=df)
    keep = view.data["time"] >= 5.0
    for name in ("heave_acceleration", "roll_acceleration"):
        var = np.var(view.data[name][keep])
        assert np.sum(out["psd"][name]) * df == pytest.approx(var, rel=0.03)        # Parseval (Hann window)
        assert out["rms"][name][0] == pytest.approx(np.sqrt(var), rel=1e-9)
    var_F = np.var(view.data["strut_force"][keep], axis=0)
    np.testing.assert_allclose(out["psd"]["strut_force"].sum(axis=1) * df, var_F, rtol=0.03)


def test_series_too_sparse_for_the_modes_are_refused():
    with pytest.raises(UserInputError, match="output.interval"):
        response_psd(SeriesView(fs=1.0, duration=600.0))
    with pytest.raises(UserInputError, match="too short"):
        response_psd(SeriesView(fs=100.0, duration=8.0))


def test_dashboard_shows_the_spectrum_panel_only_for_dense_series(monkeypatch, tmp_path):
    """A drive stored at 50 Hz gets the hull-acceleration PSD panel;
    the default 1 s interval gets none (its Nyquist frequency is below every mode)."""
    import matplotlib.pyplot as plt

    import vehicle

    figures = []
    close = plt.close
    monkeypatch.setattr(plt, "close", lambda fig=None: (figures.append(fig), close(fig)))
    quick = REPO / "scenarios" / "quick_demo.yaml"
    titles = {}
    for interval in ("0.02 s", "1 s"):
        res = vehicle.Simulation(quick, overrides={"distance": "300 m", "output.interval": interval,
                                                   "output.stats_interval": "100 m"}).run()
        res.plot(tmp_path / f"d{interval}.png")
        titles[interval] = [a.get_title() for a in figures[-1].axes]
    assert any("response PSD" in t for t in titles["0.02 s"])
    assert not any("response PSD" in t for t in titles["1 s"])
