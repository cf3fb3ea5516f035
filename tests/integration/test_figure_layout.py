"""Every figure hpsim draws, rendered at several sizes: no text leaves the canvas, no legend covers plotted
data (tests/figure_checks.py). Figures of drives: tests/test_html_report.py (the dashboard, compare)."""
from __future__ import annotations

import json

import numpy as np
import yaml

from vehicle import cli

from tests.figure_checks import assert_clean, captured_figures


def test_strut_loop_figures(tmp_path, monkeypatch):
    figs = captured_figures(monkeypatch)
    csv = tmp_path / "loops.csv"
    assert cli.main(["-q", "strut", "cycle", "--strut", "apc", "--amplitude", "10mm,50mm,100mm", "--frequency", "0.1Hz",
                     "--mean", "115mm", "--cycles", "2", "--plot", str(tmp_path / "l.png"), "--csv", str(csv)]) == 0
    assert cli.main(["-q", "strut", "cycle", "--strut", "apc", "--amplitude", "50mm", "--frequency", "0.1Hz", "--mean",
                     "115mm", "--cycles", "2", "--data", str(csv), "--plot", str(tmp_path / "o.png")]) == 0
    assert len(figs) == 2
    loops, overlay = figs
    assert any("magnified" in c.get_title() for a in loops.axes for c in a.child_axes)   # the 10 mm loop
    # the overlay's title names the measured loops' style, and the force-velocity panel shows them in it
    assert "wide light lines: measured" in overlay._suptitle.get_text()
    fv = overlay.axes[1]
    assert any(line.get_linewidth() >= 3 and line.get_alpha() < 1 for line in fv.get_lines())
    for f in figs:
        assert_clean(f)


def test_road_figures(tmp_path, monkeypatch):
    figs = captured_figures(monkeypatch)
    road = tmp_path / "road.csv"
    assert cli.main(["-q", "road", "generate", "--class", "D", "--length", "5km", "--seed", "7", "-o", str(road)]) == 0
    assert cli.main(["-q", "road", "plot", str(road), "-o", str(tmp_path / "r.png")]) == 0
    fig = figs[-1]
    psd_ax = fig.axes[-1]
    lo, hi = psd_ax.get_xlim()
    lines = [ln for ln in psd_ax.get_lines() if "Welch" in str(ln.get_label())]
    f = np.asarray(lines[0].get_xdata())
    assert lo >= f[0] / 1.5 and hi <= 4 * f[-1]        # the x-axis within the data
    assert_clean(fig)


def test_road_psd_and_strut_characteristic_figures(tmp_path, monkeypatch):
    figs = captured_figures(monkeypatch)
    assert cli.main(["-q", "road", "psd", "--class", "D", "--length", "2km", "--plot", str(tmp_path / "p.png")]) == 0
    assert cli.main(["-q", "strut", "characteristic", "--strut", "apc", "--plot", str(tmp_path / "c.png")]) == 0
    assert len(figs) == 2
    for f in figs:
        assert_clean(f)


def test_vehicle_response_figure(tmp_path, monkeypatch):
    figs = captured_figures(monkeypatch)
    assert cli.main(["-q", "vehicle", "response", "--plot", str(tmp_path / "r.png")]) == 0
    fig = figs[-1]
    styles = {ln.get_linestyle() for a in fig.axes for ln in a.get_lines() if "axle" in str(ln.get_label())}
    assert len(styles) >= 4 and len(fig.legends) == 1
    assert_clean(fig)


def test_uq_figures(tmp_path, monkeypatch):
    from hpsim.priors import collect_priors
    from vehicle.presentation.uq_plots import study_plots
    from vehicle.studies import uq

    priors = yaml.safe_load("a: {value: 1, prior: {uniform: [0, 2]}}\nb: {value: 1, prior: {uniform: [0, 2]}}")
    params = uq.parameters_from(collect_priors(priors, "toy.yaml"))

    def runner(case, v):
        return {"axle1.rise_K": 3 * v["a"] + 0.1 * v["b"], "axle2.rise_K": v["b"] ** 2, "load_shift_pct": v["a"]}

    s = uq.run_study(tmp_path / "s", params, runner, method="sobol", samples=8, seed=1, workers=1)
    figs = captured_figures(monkeypatch)
    study_plots(json.loads(json.dumps(s)), tmp_path / "s")
    assert len(figs) == 2
    sobol = figs[1]
    bars = sobol.axes[0]
    lo, hi = bars.get_xlim()
    for c in bars.containers:               # every whisker inside the panel
        err = getattr(c, "errorbar", None)
        if err is not None:
            for seg in err.lines[2][0].get_segments():
                assert lo <= seg[:, 0].min() and seg[:, 0].max() <= hi
    cbar = [a for a in sobol.axes if a.get_ylabel() == "ST"]
    assert cbar and cbar[0].get_window_extent().height > 0.5 * sobol.axes[1].get_window_extent().height
    for f in figs:
        assert_clean(f)
