"""Shareable reports (vehicle.presentation.html_report, `hpsim report --html/--pdf`): the HTML is one
self-contained file holding every per-axle number of `report --json`; the PDF has the text pages and the
figures; a sweep folder and a UQ study folder get their own reports; the ride rows carry the ISO 2631 shock
numbers of the dense series."""
from __future__ import annotations

import json
import math
import re
import shutil
import subprocess
from html import unescape as html_unescape
from html.parser import HTMLParser

import numpy as np
import pytest

from vehicle import cli
from vehicle.presentation import html_report
from vehicle.results.reader import open_results
from tests.helpers import REPO

QUICK = REPO / "scenarios" / "quick_demo.yaml"


@pytest.fixture(scope="module")
def drive(tmp_path_factory):
    """A 200 m drive stored at 50 Hz (the shock metrics and spectra need dense series)."""
    import vehicle

    out = tmp_path_factory.mktemp("drive") / "short.h5"
    vehicle.Simulation(QUICK, overrides={"distance": "200 m", "output.interval": "0.02 s",
                                         "output.stats_interval": "100 m"}).run(out=out)
    return out


class Tables(HTMLParser):
    """The cells of every table, and every src/href attribute."""

    def __init__(self):
        super().__init__()
        self.tables, self.links, self._cell = [], [], None

    def handle_starttag(self, tag, attrs):
        self.links += [v for k, v in attrs if k in ("src", "href")]
        if tag == "table":
            self.tables.append([])
        elif tag == "tr":
            self.tables[-1].append([])
        elif tag in ("td", "th"):
            self._cell = ""

    def handle_endtag(self, tag):
        if tag in ("td", "th") and self._cell is not None:
            self.tables[-1][-1].append(self._cell.strip())
            self._cell = None

    def handle_data(self, data):
        if self._cell is not None:
            self._cell += data


def _numbers(cell: str) -> list[float]:
    return [float(x) for x in re.findall(r"[-+]?\d+(?:\.\d+)?", cell)]


def test_html_is_self_contained_and_has_every_per_axle_number(drive, tmp_path, capsys):
    out = tmp_path / "report.html"
    assert cli.main(["report", str(drive), "--html", str(out), "--pdf", str(tmp_path / "report.pdf")]) == 0
    pdf = (tmp_path / "report.pdf").read_bytes()             # the same document as a PDF: text pages + figures
    assert pdf.startswith(b"%PDF") and len(re.findall(rb"/Type\s*/Page\b", pdf)) >= 2
    capsys.readouterr()
    assert cli.main(["report", str(drive), "--json"]) == 0
    rep = json.loads(capsys.readouterr().out)
    text = out.read_text()
    p = Tables()
    p.feed(text)
    # no network: every image is inline, no stylesheet, script or link elsewhere
    assert p.links and all(v.startswith("data:image/png;base64,") for v in p.links)
    assert not re.search(r"https?://|<link|<script|@import|url\(", text)
    assert "<img" in text and rep["axles"]
    # the per-axle table: one row per axle, every number of the JSON row at the displayed precision
    table = next(t for t in p.tables if t and t[0] and t[0][0] == "axle" and "T start [degC]" in t[0])
    assert len(table) == 1 + len(rep["axles"])
    for row_json, row in zip(rep["axles"], table[1:]):
        cells = dict(zip(table[0], row))
        for key, header, spec in html_report.AXLE_COLUMNS:
            v = row_json[key]
            shown = _numbers(cells[header])
            want = v if isinstance(v, list) else [v]
            assert len(shown) == len(want), (key, cells[header])
            decimals = int(spec[1:-1]) if spec.endswith("f") else 0
            for s, w in zip(shown, want):
                assert abs(s - w) <= 0.5 * 10 ** -decimals + 1e-12, (key, s, w)
    # the ride rows with the shock metrics, the validity warnings, solver facts and provenance
    for needle in ("crest factor", "MTVV", "Sed daily", "Validity warnings", "step-error estimate",
                   "scenario hash", "machine", "hpsim"):
        assert needle in text, needle
    seat = rep["ride"]["seats"][0]
    assert seat["crest_factor"] > math.sqrt(2) and seat["daily_sed_MPa"] > seat["sed_MPa"] > 0


CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
# after the page has loaded, every image's decoded size and the table cells, written into the DOM for --dump-dom
PROBE = """<script>
window.addEventListener("load", () => {
  const out = document.createElement("pre"); out.id = "probe";
  out.textContent = JSON.stringify({
    images: Array.from(document.images).map(i => [i.complete, i.naturalWidth, i.naturalHeight, i.getBoundingClientRect().width]),
    cells: Array.from(document.querySelectorAll("table")).map(t => Array.from(t.rows).map(r => Array.from(r.cells).map(c => c.innerText.trim())))});
  document.body.appendChild(out);
});
</script>"""


def _chromium(*args, cwd) -> subprocess.CompletedProcess:
    return subprocess.run([CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
                           "--disable-component-update", "--disable-sync", "--no-first-run",
                           f"--user-data-dir={cwd / 'profile'}", *args], capture_output=True, text=True, timeout=180,
                          cwd=cwd)


@pytest.mark.skipif(CHROMIUM is None, reason="chromium is not installed (Debian: apt-get install chromium): the "
                                             "HTML report is not opened in a browser here")
def test_html_report_renders_in_a_real_browser_with_every_figure_and_the_json_numbers(drive, tmp_path, capsys):
    """The report opened by headless Chromium: every <img> decodes to a picture with a size on the page, the
    per-axle table the browser shows holds the numbers of `report --json`, and a screenshot is a page with
    content (not blank)."""
    from PIL import Image

    out = tmp_path / "report.html"
    assert cli.main(["report", str(drive), "--html", str(out)]) == 0
    capsys.readouterr()
    assert cli.main(["report", str(drive), "--json"]) == 0
    rep = json.loads(capsys.readouterr().out)
    probed = tmp_path / "probed.html"
    probed.write_text(out.read_text().replace("</body>", PROBE + "</body>"))
    dom = _chromium("--virtual-time-budget=10000", "--dump-dom", probed.as_uri(), cwd=tmp_path).stdout
    probe = json.loads(html_unescape(re.search(r'<pre id="probe">(.*?)</pre>', dom, re.S).group(1)))
    n_img = out.read_text().count("<img")
    assert n_img >= 1 and len(probe["images"]) == n_img
    assert all(done and w > 100 and h > 100 and shown > 100 for done, w, h, shown in probe["images"]), probe["images"]
    table = next(t for t in probe["cells"] if t and t[0] and t[0][0] == "axle" and "T start [degC]" in t[0])
    assert len(table) == 1 + len(rep["axles"])
    for row_json, row in zip(rep["axles"], table[1:]):
        cells = dict(zip(table[0], row))
        for key, header, spec in html_report.AXLE_COLUMNS:
            want = row_json[key] if isinstance(row_json[key], list) else [row_json[key]]
            decimals = int(spec[1:-1]) if spec.endswith("f") else 0
            assert all(abs(a - b) <= 0.5 * 10 ** -decimals + 1e-12 for a, b in zip(_numbers(cells[header]), want)), key
    shot = tmp_path / "report.png"
    _chromium("--window-size=1200,3000", "--hide-scrollbars", f"--screenshot={shot}", out.as_uri(), cwd=tmp_path)
    with Image.open(shot) as im:
        gray = np.asarray(im.convert("L"), float)
    assert gray.shape == (3000, 1200) and gray.std() > 10          # text and figures, not a blank page


def test_pdf_tables_fit_the_page_and_the_first_page_is_a_png(tmp_path):
    """A table wider than the page gets smaller type until it fits; the first page also as a PNG."""
    wide = html_report.Table([f"a long column header {k}" for k in range(16)], [[f"{k}.00" for k in range(16)]] * 3)
    doc = html_report.Document("wide", ["intro"], [html_report.Section("s", [("", "text")], [wide])], [("k", "v")])
    png = tmp_path / "page1.png"
    html_report.write_pdf(doc, tmp_path / "w.pdf", png)
    assert png.stat().st_size > 5_000 and (tmp_path / "w.pdf").read_bytes().startswith(b"%PDF")
    import matplotlib.pyplot as plt

    from vehicle.presentation.plots import pyplot

    pages = html_report._Pages(None)
    pages.need(0.1)
    pages.table(wide)
    fig = pages.fig
    fig.canvas.draw()
    ax = fig.axes[-1]
    r = fig.canvas.get_renderer()
    assert ax.tables[0].get_window_extent(r).width <= ax.get_window_extent(r).width * 1.001
    pyplot().close(fig)
    plt.close("all")


def test_bad_report_targets_exit_2(drive, tmp_path, capsys, monkeypatch):
    import sys

    assert cli.main(["report", str(drive), "--html", str(tmp_path / "r.txt")]) == 2
    assert cli.main(["report", str(tmp_path), "--html", str(tmp_path / "r.html")]) == 2
    err = capsys.readouterr().err
    assert "must end in .html" in err and "not a study folder" in err
    monkeypatch.setitem(sys.modules, "jinja2", None)          # the extra not installed: one line naming it
    monkeypatch.setattr(html_report, "document", lambda path: html_report.Document("t", [], [], []))
    assert cli.main(["report", str(drive), "--html", str(tmp_path / "r.html")]) == 2
    assert 'pip install -e ".[report]"' in capsys.readouterr().err


def test_sweep_and_uq_folders_get_a_report(drive, tmp_path):
    import yaml
    from hpsim.priors import collect_priors
    from vehicle.studies import uq

    sweep = tmp_path / "sweep"
    sweep.mkdir()
    for name in ("a", "b"):
        shutil.copy(drive, sweep / f"{name}.h5")
    (sweep / "summary.csv").write_text("case,status,error,file,speed,distance_km,load_shift_pct\n"
                                       f"a,done,,{sweep / 'a.h5'},20 km/h,0.2,0.1\nb,done,,/moved/b.h5,30 km/h,0.2,0.1\n")
    html_report.write_html(html_report.document(sweep), tmp_path / "sweep.html")
    text = (tmp_path / "sweep.html").read_text()
    assert "Comparison" in text and "axle 1 dN [%]" in text and text.count("data:image/png") == 1
    assert "30 km/h" in text and "axle 1 dN weighing band [%]" in text and "driver Sed daily [MPa]" in text
    # who ran it: the hpsim version stored in the cases' files, not "unknown"
    p = Tables()
    p.feed(text)
    run_by = next(row[1] for t in p.tables for row in t if row and row[0] == "run by")
    from vehicle.results.reader import open_results as _open

    with _open(drive) as r:
        assert run_by == str(r.scenario_attrs['hpsim_version']) and "unknown" not in run_by

    priors = yaml.safe_load("a: {value: 1, prior: {uniform: [0, 2]}}\nb: {value: 1, prior: {uniform: [0, 2]}}")
    params = uq.parameters_from(collect_priors(priors, "toy.yaml"))

    def runner(case, v):        # axle 1 driven by a, axle 2 by b: Sobol' ranks them
        return {"axle1.rise_K": 3 * v["a"] + 0.1 * v["b"], "axle2.rise_K": v["b"]}

    uq.run_study(tmp_path / "study", params, runner, method="sobol", samples=16, seed=1, workers=1)
    html_report.write_html(html_report.document(tmp_path / "study"), tmp_path / "uq.html")
    p = Tables()
    p.feed((tmp_path / "uq.html").read_text())
    ranking = [t for t in p.tables if t and t[0][0] == "parameter" and "ST" in t[0]]
    assert ranking and ranking[0][1][0] == "a"             # axle1.rise_K: a first
    assert all(v.startswith("data:image/png;base64,") for v in p.links) and len(p.links) >= 2


def test_dashboard_and_compare_figures_are_clean(drive, tmp_path, monkeypatch):
    """The dashboard (strut travel per axle against the stroke, load changes with the weighing bands, every
    legend off the data) and the comparison of two identical runs (an overall title; both curves visible)."""
    from vehicle.presentation.plots import compare_plot, dashboard_figure

    from tests.figure_checks import assert_clean, captured_figures

    fig = dashboard_figure(drive)
    titles = [a.get_title() for a in fig.axes]
    assert any("strut travel" in t for t in titles) and any("static wheel loads" in t for t in titles)
    travel = next(a for a in fig.axes if "strut travel" in a.get_title())
    assert [t.get_text() for t in travel.get_xticklabels()] == ["axle1", "axle2", "axle3", "axle4"]
    loads = next(a for a in fig.axes if "static wheel loads" in a.get_title())
    assert "weighing band (seal friction)" in [t.get_text() for t in loads.get_legend().get_texts()]
    assert_clean(fig)
    figs = captured_figures(monkeypatch)
    shutil.copy(drive, tmp_path / "copy.h5")
    compare_plot([drive, tmp_path / "copy.h5"], tmp_path / "cmp.png")
    cmp = figs[-1]
    assert "identical" in cmp._suptitle.get_text()
    top = cmp.axes[0]
    styles = [(ln.get_linestyle(), ln.get_linewidth()) for ln in top.get_lines() if len(ln.get_xdata()) > 2]
    assert len(set(styles)) == 2
    assert_clean(cmp)
    from vehicle.presentation.plots import psd_plot
    from vehicle.analysis.psd import response_psd
    from vehicle.results.reader import open_results

    with open_results(drive) as r:
        psd, stations = response_psd(r), r.stations
    psd_plot(psd, tmp_path / "psd.png", stations)                 # hpsim report --psd
    assert_clean(figs[-1])


def test_animation_has_one_frame_per_frame_interval_of_a_200_m_span(drive, tmp_path, capsys):
    """`hpsim animate --from 0km --to 0.2km --fps 1`: the 200 m at 20 km/h take 36 s of driving, one frame a
    second -> 1 + floor(36 s / 1 s) frames in the GIF (frames are stored samples, every 50th of the 50 Hz
    series)."""
    from PIL import Image

    from vehicle.presentation import animation
    from vehicle.results.reader import open_results

    with open_results(drive) as r:
        t, s = r.series("time"), r.series("distance")
    span = (s >= 0.0) & (s <= 200.0)
    expected = 1 + int((t[span][-1] - t[span][0]) / 1.0 + 1e-9)
    assert expected == pytest.approx(37, abs=1)                     # 200 m at 20 km/h
    out = tmp_path / "drive.gif"
    res = animation.animate(drive, out, 0.0, 200.0, fps=1.0, dpi=30)      # small frames: the count is the test
    assert res["frames"] == expected and res["writer"] == "pillow"
    with Image.open(out) as im:
        assert im.n_frames == expected
    # played in real time: the frame durations add up to the driving time from the first frame to the last
    # and one frame interval (1 s) for the last
    assert _gif_duration_s(out) == pytest.approx(expected * 1.0, abs=0.005)
    assert cli.main(["animate", str(drive), "-o", str(tmp_path / "x.gif"), "--from", "0.1km", "--to", "0.5km"]) == 2
    if shutil.which("ffmpeg") is None:
        assert cli.main(["animate", str(drive), "-o", str(tmp_path / "x.mp4")]) == 2
        assert "needs ffmpeg" in capsys.readouterr().err


def _gif_duration_s(path) -> float:
    from PIL import Image, ImageSequence

    with Image.open(path) as im:
        return sum(frame.info["duration"] for frame in ImageSequence.Iterator(im)) / 1e3


def test_gif_frames_of_39_ms_play_in_real_time(drive, tmp_path, capsys):
    """25 frames a second of a 0.013 s series: every 3rd sample, 39 ms a frame, which a GIF cannot store (whole
    centiseconds: 3 cs played it 23 % fast); the durations, rounded from the frame times, add up to the driving
    time within 5 ms. The command line shows a progress bar of the frames on stderr."""
    from vehicle.presentation import animation

    times = np.arange(200) * 0.039
    ms = animation.gif_durations_ms(times, 0.039)
    assert sum(ms) == pytest.approx(1e3 * 200 * 0.039, abs=5) and set(ms) == {40, 30}
    out = tmp_path / "a.gif"
    assert cli.main(["animate", str(drive), "-o", str(out), "--from", "0km", "--to", "0.05km", "--fps", "25"]) == 0
    captured = capsys.readouterr()
    assert "frame" in captured.err and "100%" in captured.err
    with open_results(drive) as r:
        t, s = r.series("time"), r.series("distance")
    span = t[(s >= 0.0) & (s <= 50.0)][::2]                         # 50 Hz, 25 frames/s: every 2nd sample
    assert _gif_duration_s(out) == pytest.approx(span[-1] - span[0] + 0.04, abs=0.005)


def test_shock_numbers_are_in_the_file_the_json_and_the_api(drive):
    """hpsim run records the seats' shock numbers in /summary (seat_shocks_json); they are what the series
    give when computed afresh (vehicle.physics.shocks), and the API's ride() carries them."""
    import vehicle
    from vehicle.physics import shocks
    from vehicle.results.reader import open_results

    with open_results(drive) as r:
        stored = json.loads(str(r.summary_attrs()["seat_shocks_json"]))
        seats = json.loads(r.scenario_attrs["resolved_json"])["vehicle"]["seats"]
        fresh = shocks.drive_shocks(r, seats)
    assert set(stored) == {s["name"] for s in seats}
    for name, v in stored.items():
        for key in ("crest_factor", "mtvv_m_s2", "sed_MPa", "daily_sed_MPa"):
            assert v[key] == pytest.approx(fresh[name][key], rel=1e-12)
    ride = vehicle.open_results(drive).ride()
    assert {s["seat"]: s["daily_sed_MPa"] for s in ride["seats"]} == {k: v["daily_sed_MPa"] for k, v in stored.items()}


def test_weighted_series_reproduce_the_drives_own_a_w(drive):
    """The Wk weighting applied afterwards to the stored 50 Hz seat accelerations (vehicle.physics.shocks, the
    signal behind crest factor and MTVV) gives the a_w the model integrated during the drive (its filter states
    and quadratures, vehicle.physics.ride) over the second statistics interval (100-200 m) within 3 %: the
    difference is the 50 Hz sampling and the bilinear discretisation (measured 1.0-1.3 % on a 1 km drive)."""
    from vehicle.physics import shocks
    from vehicle.results.reader import open_results

    with open_results(drive) as r:
        seats = json.loads(r.scenario_attrs["resolved_json"])["vehicle"]["seats"]
        fs, sig = shocks.seat_signals(r, seats, skip_s=0.0)
        dist, km = r.series("distance"), r.stats_series("km")
        aw_rows = r.stats_series("weighted_rms_acceleration")
    window = (dist > km[0] * 1e3) & (dist <= km[1] * 1e3)
    for k, (az, _) in enumerate(sig.values()):
        aw = shocks.weighted_acceleration(az, fs)
        assert math.sqrt(float((aw[window] ** 2).mean())) == pytest.approx(aw_rows[1, k], rel=0.03)
