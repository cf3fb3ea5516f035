"""The comparison figure (`hpsim compare --plot`, a sweep's compare.png, the HTML report) at few and many runs: few
runs as grouped bars per axle, many runs at a bounded size with the runs along the x axis, every legend off the data
(tests/figure_checks.py)."""
from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from tests.figure_checks import assert_clean, captured_figures

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture
def runs(tmp_path, monkeypatch):
    """make(n): n copies of the stored results file whose per-axle changes differ run by run (the report of copy i
    has its load and height changes scaled by 1 + i/10), so that the runs' markers and bars do not coincide."""
    from vehicle.analysis import summary

    full_report = summary.report

    def report(path, *args, **kwargs):
        rep = full_report(path, *args, **kwargs)
        scale = 1 + int(Path(path).stem.split("_")[1]) / 10
        axles = [{**a, **{k: a[k] * scale for k in ("dN_pct", "dh_mm") if a.get(k) is not None}} for a in rep["axles"]]
        return {**rep, "axles": axles}

    monkeypatch.setattr(summary, "report", report)

    def make(n):
        paths = []
        for i in range(n):
            paths.append(tmp_path / f"case_{i:02d}.h5")
            shutil.copy(ROOT / "tests" / "data" / "results_v1.h5", paths[-1])
        return paths

    return make


def _bottom_panels(fig):
    return [a for a in fig.axes if a.get_title() in ("load redistribution (after vs before)",
                                                     "height change (after vs before)",
                                                     "temperature rise over the drive")]


def test_many_runs_make_a_bounded_figure_with_runs_along_x(runs, tmp_path, monkeypatch):
    """40 runs: the PNG stays under 2500 px wide (it grew by 1.2 in per axle and run), each per-axle panel has one
    line per axle through all 40 runs, the legend names the axles, the histories' colour bar is labelled 'run',
    and nothing overlaps or leaves the canvas at three sizes."""
    from PIL import Image

    from vehicle.presentation.plots import compare_plot

    paths = runs(40)
    figs = captured_figures(monkeypatch)
    out = compare_plot(paths, tmp_path / "compare.png")
    fig = figs[-1]
    width, height = Image.open(out).size
    assert width <= 2500 and height <= 1400
    panels = _bottom_panels(fig)
    assert len(panels) == 3
    n_axles = len(panels[0].get_lines()) - 1                   # the axhline at 0 aside
    assert n_axles >= 2
    loads = panels[0]
    for line in loads.get_lines():
        if line.get_label().startswith("axle"):
            x, y = np.asarray(line.get_xdata()), np.asarray(line.get_ydata())
            assert list(x) == list(range(40))
            assert abs(y[-1] - 4.9 * y[0]) <= 1e-9 * max(1.0, abs(y[0]))      # copy 39 scaled by 1 + 39/10
    assert [t.get_text() for t in fig.legends[0].get_texts()] == [f"axle {k + 1}" for k in range(n_axles)]
    labels = [t.get_text() for t in loads.get_xticklabels()]
    assert labels[0] == "case_00" and labels[-1] == "case_39" and len(labels) <= 25
    assert any(a.get_ylabel() == "run" for a in fig.axes)             # the colour bar of the histories
    assert not any(a.get_legend() for a in fig.axes)
    assert_clean(fig)


def test_few_runs_keep_grouped_bars(runs, tmp_path, monkeypatch):
    """3 runs: as before, a bar per run and axle, a legend entry per run, 3 + 1.2 in per run and axle wide."""
    from vehicle.presentation.plots import compare_plot

    figs = captured_figures(monkeypatch)
    compare_plot(runs(3), tmp_path / "compare.png")
    fig = figs[-1]
    panels = _bottom_panels(fig)
    n_axles = len(panels[0].get_xticks())
    assert all(len(p.patches) == 3 * n_axles for p in panels)
    assert [t.get_text() for t in fig.legends[0].get_texts()] == ["case_00", "case_01", "case_02"]
    assert fig.get_size_inches()[0] == pytest.approx(max(13, 3 + 1.2 * n_axles * 3))
    assert_clean(fig)
