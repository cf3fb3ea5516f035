"""Reports people can share: one self-contained HTML file (`hpsim report RESULTS --html report.html`, figures
embedded as base64 PNG, no external references) or a PDF (`--pdf`, matplotlib's multi-page output), of one
drive or of a study folder (a sweep: its summary.csv and case files; a UQ study: its summary.json).

Both formats render the same document: a title, paragraphs, sections of paragraphs, tables and figures, and
the provenance (hpsim version of the run and of the report, scenario hash, dates, machine). The HTML goes
through the jinja2 template templates/report.html.j2 (extra `report`); the PDF needs nothing beyond
matplotlib."""
from __future__ import annotations

import base64
import csv
import datetime as _dt
import hashlib
import io
import json
import os
import platform
from dataclasses import dataclass, field
from pathlib import Path

from hpsim.errors import UserInputError
from hpsim.outputs import atomic_output
from hpsim.extras import install_hint

from vehicle.results.reader import open_results
from vehicle.analysis.ride_metrics import axle_rows
from vehicle.analysis.summary import axle_value, compare, report_from
from vehicle.presentation.plots import compare_plot, dashboard_figure, pyplot
from vehicle.presentation.report import AXLE_COLUMNS as RIDE_AXLE, SEAT_COLUMNS, format_warnings, shock_notes
from vehicle.presentation.uq_plots import bands_plot, sensitivity_plot

TEMPLATE = "report.html.j2"
DPI = 100


@dataclass
class Table:
    headers: list
    rows: list
    caption: str = ""
    text_columns: tuple = ()


@dataclass
class Figure:
    fig: object                 # a matplotlib figure (closed after rendering)
    caption: str
    png_base64: str = ""


@dataclass
class Section:
    title: str
    paragraphs: list = field(default_factory=list)     # (css class, text)
    tables: list = field(default_factory=list)
    figures: list = field(default_factory=list)


@dataclass
class Document:
    title: str
    intro: list
    sections: list
    provenance: list


def _fmt(v, spec=".2f") -> str:
    if v is None:
        return "-"
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_fmt(x, spec) for x in v) + "]"
    if isinstance(v, bool) or isinstance(v, str):
        return str(v)
    return format(float(v), spec)


# --- one drive -----------------------------------------------------------------------------------
AXLE_COLUMNS = (("axle", "axle", "d"), ("T_start_C", "T start [degC]", ".2f"),
                ("T_end_C", "T surface end [degC]", ".2f"), ("T_oil_end_C", "T oil end [degC]", ".2f"),
                ("T_gas_end_C", "T gas end [degC]", ".2f"), ("dh_mm", "dh [mm]", ".2f"),
                ("dh_band_mm", "dh weighing band [mm]", ".2f"), ("N_before_daN", "N before [daN]", ".2f"),
                ("N_after_daN", "N after [daN]", ".2f"), ("dN_pct", "dN [%]", ".2f"),
                ("dN_band_pct", "dN weighing band [%]", ".2f"), ("N_charged_daN", "N charged [daN]", ".2f"),
                ("dN_charged_pct", "dN vs charged [%]", ".2f"), ("energy_dissipated_MJ", "E dissipated, both struts [MJ]", ".4f"))


def scenario_words(resolved: dict, rep: dict) -> str:
    """The scenario in a sentence or three."""
    S = resolved["scenario"]
    road = S.get("road") or {}
    if road.get("crg"):
        road_text = f"the OpenCRG road {road['crg']}"
    elif road.get("csv"):
        road_text = f"the road profile {road['csv']}"
    elif road.get("flat"):
        road_text = "a flat road"
    else:
        road_text = f"an ISO 8608 class {road.get('iso_class', '?')} road (seed {road.get('seed', 0)})"
    speed = S.get("speed")
    speed_text = f"{float(speed) * 3.6:.1f} km/h" if isinstance(speed, (int, float)) else "a speed profile"
    T0 = resolved.get("initial_temperatures_K")
    start = ""
    if T0:
        vals = sorted({round(float(t) - 273.15, 1) for t in T0})
        start = (f" The struts started at {vals[0]:g} degC." if len(vals) == 1 else
                 f" The struts started at {vals[0]:g} to {vals[-1]:g} degC.")
    solver = S.get("solver") or {}
    dt = solver.get("dt")
    return (f"{resolved['vehicle'].get('name', 'The vehicle')} drove {rep['distance_km']:.3f} km of the planned "
            f"{rep['planned_distance_km']:.6g} km at {speed_text} over {road_text}, ambient {rep['ambient_C']:.1f} degC, "
            f"pressure compensation {'on' if rep['compensation'] else 'off'}.{start} The run is {rep['status']}; "
            f"solver mode {rep.get('solver_mode', 'full')}" + (f", step {float(dt) * 1e3:.4g} ms." if dt else "."))


def _axle_section(rep: dict) -> Section:
    sec = Section("Per-axle results")
    sec.tables.append(Table([h for _, h, _ in AXLE_COLUMNS],
                            [[_fmt(r.get(k), f) if k != "axle" else str(r["axle"]) for k, _, f in AXLE_COLUMNS]
                             for r in rep["axles"]],
                            "Temperatures: mean of left and right; dN and dh between the standing equilibria before "
                            "and after the drive; the weighing bands are what two weighings with seal friction can "
                            "give (vehicle.physics.weighing)."))
    lines = []
    if rep.get("load_shift_pct") is not None:
        lines.append(f"Load shift {rep['load_shift_pct']:.2f} % (sum |dN| / sum N), max |dN| "
                     f"{rep['max_abs_dN_pct']:.2f} %; against the charged loads {rep['load_shift_vs_charged_pct']:.2f} %.")
    if rep.get("mean_temperature_rise_K") is not None:
        lines.append(f"Mean strut (surface) temperature rise {rep['mean_temperature_rise_K']:.2f} K; "
                     f"energy dissipated {_fmt(rep.get('energy_dissipated_MJ'), '.3f')} MJ.")
    sec.paragraphs += [("", t) for t in lines]
    return sec


def _warnings_section(rep: dict) -> Section:
    sec = Section("Validity warnings")
    ws = rep.get("warnings") or []
    if not ws:
        sec.paragraphs.append(("", "None: every checked quantity stayed within the range of its model and data."))
    for line in format_warnings(ws):
        sec.paragraphs.append(("warning" if line.startswith("warning") else "note", line))
    if rep.get("error"):
        sec.paragraphs.append(("error", f"stopped: {rep['error']}"))
    return sec


def _ride_section(rep: dict) -> Section | None:
    ride = rep.get("ride") or {}
    if not ride:
        return None
    sec = Section("Ride and road holding")
    for rows, columns, first, caption in (
            (ride.get("seats") or [], SEAT_COLUMNS, "seat", "At the seats: ISO 2631-1 weighted RMS (a_w), VDV, absorbed "
             "power; with series stored at 30 Hz or more also crest factor, MTVV and the ISO 2631-5 spinal dose Sed (drive, "
             "and per day of the same driving; hull at the seat point, no cushion)."),
            (axle_rows(ride, [None] * len(rep["axles"])), RIDE_AXLE, "axle", "Per axle, worst of left and right.")):
        cols = [c for c in columns if any(r.get(c[0]) is not None for r in rows)]
        if rows and cols:
            sec.tables.append(Table([first] + [c[1] for c in cols],
                                    [[str(r[first])] + ["-" if r.get(k) is None else
                                                        (str(r[k]) if sc is None else format(r[k] * sc, f))
                                                        for k, _, sc, f in cols] for r in rows], caption,
                                    tuple(i + 1 for i, c in enumerate(cols) if c[2] is None)))
    sec.paragraphs += [("note" if t.startswith("note") else "", t) for t in shock_notes(ride.get("seats") or [])]
    hull = ride.get("hull")
    if hull:
        sec.paragraphs.append(("", f"Hull RMS acceleration: heave {hull['rms_heave_acceleration_m_s2']:.3g} m/s^2, "
                                   f"pitch {hull['rms_pitch_acceleration_rad_s2']:.3g} rad/s^2, "
                                   f"roll {hull['rms_roll_acceleration_rad_s2']:.3g} rad/s^2."))
    return sec


def _solver_section(rep: dict, summ: dict) -> Section:
    sec = Section("Solver and error estimate")
    rows = [["mode", rep.get("solver_mode", "full")],
            ["simulated", f"{rep['simulated_s']:.1f} s ({rep['simulated_s'] / 3600:.3f} h)"],
            ["wall time", f"{rep['wall_s']:.1f} s"]]
    for key, label, unit in (("build_s", "model build", "s"), ("integration_s", "integration", "s")):
        if key in summ:
            rows.append([label, f"{float(summ[key]):.2f} {unit}"])
    if rep.get("solver_error_estimate") is not None:
        rows.append(["step-error estimate", f"{rep['solver_error_estimate']:.3g} (tolerance "
                                            f"{_fmt(rep.get('solver_tolerance'), '.3g')})"])
    if rep.get("solver_advice"):
        rows.append(["advice", rep["solver_advice"]])
    est = rep.get("estimated_error")
    if est:
        rows.append(["estimated error, T end per axle [K]", _fmt(est.get("T_end_K"), ".3f")])
        rows.append(["estimated error, dN per axle [pp]", _fmt(est.get("dN_pct"), ".4f")])
    sec.tables.append(Table(["quantity", "value"], rows, "", (1,)))
    return sec


def drive_document(path: str | Path) -> Document:
    """The report document of one results file (figures: the dashboard and, for dense series, the PSDs)."""
    path = Path(path)
    with open_results(path) as r:
        rep = report_from(r, str(path))
        resolved_json = r.scenario_attrs["resolved_json"]
        summ, root = r.summary_attrs(), r.root_attrs
        fig = dashboard_figure(r)
    resolved = json.loads(resolved_json)
    sections = [_axle_section(rep), _warnings_section(rep)]
    ride = _ride_section(rep)
    if ride:
        sections.append(ride)
    dash = Section("Dashboard")
    dash.figures.append(Figure(fig, "Dashboard (hpsim plot): temperatures, heights, load changes with weighing bands, "
                                    "dissipated power, ride, strut travel and response spectra as stored."))
    sections += [dash, _solver_section(rep, summ)]
    desc = resolved["scenario"].get("description") or ""
    intro = ([desc] if desc else []) + [scenario_words(resolved, rep)]
    return Document(f"hpsim report: {path.name}", intro, sections,
                    provenance(resolved_json, rep.get("hpsim_version") or str(root.get("source", "")),
                               str(summ.get("finished_at", "")), str(path)))


def provenance(resolved_json: str, run_version: str, run_date: str, source: str) -> list:
    from importlib.metadata import PackageNotFoundError, version

    try:
        mine = version("hpsim")
    except PackageNotFoundError:
        mine = "unknown"
    return [("source", source), ("run by", run_version or "unknown"), ("run finished", run_date or "-"),
            ("scenario hash (SHA-256 of the resolved scenario)", hashlib.sha256(resolved_json.encode()).hexdigest()[:16]),
            ("report by", f"hpsim {mine}"), ("report made", _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")),
            ("machine", f"{platform.node()} ({platform.platform()}, {os.cpu_count()} CPUs, Python {platform.python_version()})")]


# --- a study folder ------------------------------------------------------------------------------------
def _png_figure(draw, caption: str) -> Figure | None:
    """A figure drawn by a function that writes a PNG file (the study plots), read back as bytes."""
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        out = draw(Path(tmp) / "f.png")
        if out is None or not Path(out).exists():
            return None
        return Figure(None, caption, base64.b64encode(Path(out).read_bytes()).decode())


def uq_document(folder: Path) -> Document:
    summary = json.loads((folder / "summary.json").read_text())
    units = summary.get("units", {})
    bands = Section("Prediction bands", tables=[Table(
        ["output", "unit", "5 %", "median", "95 %", "nominal"],
        [[k, units.get(k, ""), _fmt(b.get("p5"), ".4g"), _fmt(b.get("p50"), ".4g"), _fmt(b.get("p95"), ".4g"),
          _fmt(summary.get("nominal", {}).get(k), ".4g")] for k, b in summary.get("bands", {}).items()],
        f"{summary.get('done')} of {summary.get('cases')} cases done ({summary.get('method')} design of "
        f"{summary.get('samples')}, seed {summary.get('seed')}).", (1,))])
    fig = _png_figure(lambda out: bands_plot(summary, out), "5-95 % bands per axle (bars), median and nominal case")
    if fig:
        bands.figures.append(fig)
    rank = Section("Sensitivity ranking")
    table = summary.get("sobol") or summary.get("ranking") or {}
    for out_name, v in table.items():
        if v.get("constant"):
            continue
        rows = sorted(v["rows"], key=lambda r: -(r.get("ST") if r.get("ST") is not None
                                                 else abs(r.get("prcc") or 0.0)))[:8]
        keys = [k for k in ("S1", "S1_conf", "ST", "ST_conf", "prcc", "spearman") if any(k in r for r in rows)]
        rank.tables.append(Table(["parameter"] + keys, [[r["parameter"]] + [_fmt(r.get(k), ".3f") for k in keys]
                                                        for r in rows], f"{out_name}: the most influential parameters"))
    if summary.get("sensitivity", {}).get("skipped"):
        rank.paragraphs.append(("note", summary["sensitivity"]["skipped"]))
    fig = _png_figure(lambda out: sensitivity_plot(summary, out), "Sobol' indices or rank correlations")
    if fig:
        rank.figures.append(fig)
    params = Section("Parameters drawn", tables=[Table(
        ["parameter", "prior"], [[p.get("name", ""), json.dumps({k: v for k, v in p.items() if k != "name"})]
                                 for p in summary.get("parameters", [])], "", (1,))])
    src = json.dumps(summary, sort_keys=True)
    return Document(f"hpsim UQ study: {folder.name}",
                    [f"Uncertainty study of {summary.get('scenario', folder)} over the priors of its parameter files."],
                    [bands, rank, params], provenance(src, "", "", str(folder)))


SWEEP_RESULT_COLUMNS = ("load_shift_pct", "load_shift_vs_charged_pct", "mean_temperature_rise_K",
                        "energy_dissipated_MJ", "warnings", "error")


def _sweep_files(folder: Path, rows: list[dict]) -> list[str]:
    """The finished cases' files (summary.csv's file column, relative to the folder when moved)."""
    out = []
    for r in rows:
        if r.get("status") not in ("done", "skipped") or not r.get("file"):
            continue
        f = Path(r["file"])
        f = f if f.exists() else folder / f.name
        if f.exists():
            out.append(str(f))
    return out


def sweep_document(folder: Path) -> Document:
    with open(folder / "summary.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    columns = list(rows[0]) if rows else []
    start = columns.index("file") + 1 if "file" in columns else 2
    stop = columns.index("distance_km") if "distance_km" in columns else len(columns)
    shown = ["case", "status"] + columns[start:stop] + [c for c in SWEEP_RESULT_COLUMNS if c in columns]

    def cell(v):
        try:
            return format(float(v), ".4g")
        except ValueError:
            return v

    sections = [Section("Cases", tables=[Table(shown, [[cell(r.get(c, "")) for c in shown] for r in rows],
                                               f"{folder / 'summary.csv'} (every column there; here the overrides "
                                               "and the whole-vehicle results)", tuple(range(1, len(shown))))])]
    files = _sweep_files(folder, rows)
    run_by = ""
    if files:
        cmp = compare(files)
        run_by = ", ".join(sorted({str(r["hpsim_version"]) for r in cmp["runs"] if r.get("hpsim_version")}))
        labels = [Path(r["file"]).stem for r in cmp["runs"]]
        per_axle = []
        for key, what, spec in (("dN_pct", "dN [%]", ".2f"), ("dN_band_pct", "dN weighing band [%]", ".1f"),
                                ("dh_mm", "dh [mm]", ".2f"), ("T_end_C", "T end [degC]", ".1f")):
            for k in range(cmp["n_axles"]):
                per_axle.append([f"axle {k + 1} {what}"] + [_fmt(axle_value(r, k, key), spec) for r in cmp["runs"]])
        seats = sorted({s["seat"] for r in cmp["runs"] for s in (r.get("ride") or {}).get("seats", [])})
        for seat in seats:
            for key, what, spec in (("weighted_rms_acceleration_m_s2", "a_w [m/s^2]", ".3f"),
                                    ("daily_sed_MPa", "Sed daily [MPa]", ".3f")):
                vals = [next((s.get(key) for s in (r.get("ride") or {}).get("seats", []) if s["seat"] == seat), None)
                        for r in cmp["runs"]]
                if any(v is not None for v in vals):
                    per_axle.append([f"{seat} {what}"] + [_fmt(v, spec) for v in vals])
        sec = Section("Comparison", tables=[Table([""] + labels, per_axle, "Per axle and seat, case by case")])
        fig = _png_figure(lambda out: compare_plot(files, out, labels=labels), "The cases compared")
        if fig:
            sec.figures.append(fig)
        sections.append(sec)
    text = (folder / "summary.csv").read_text()
    return Document(f"hpsim sweep: {folder.name}", [f"The {len(rows)} cases of the sweep in {folder}."], sections,
                    provenance(text, run_by or "no finished case to read it from", "", str(folder)))


def document(path: str | Path) -> Document:
    """The document of a results file, a UQ study folder (summary.json) or a sweep folder (summary.csv); an
    optimisation study folder's is vehicle.presentation.optimize_report.optimize_document."""
    path = Path(path)
    if path.is_dir():
        if (path / "summary.json").exists() and "bands" in json.loads((path / "summary.json").read_text()):
            return uq_document(path)
        if (path / "summary.csv").exists():
            return sweep_document(path)
        raise UserInputError(f"{path}: not a study folder (no summary.json of `hpsim uq`, no summary.csv of `hpsim sweep`, no optimize.json of `hpsim optimize`)")
    return drive_document(path)


# --- rendering -------------------------------------------------------------------------------------------
def _encode_figures(doc: Document) -> None:
    for sec in doc.sections:
        for f in sec.figures:
            if f.fig is not None and not f.png_base64:
                buf = io.BytesIO()
                f.fig.savefig(buf, format="png", dpi=DPI)
                pyplot().close(f.fig)
                f.fig = None
                f.png_base64 = base64.b64encode(buf.getvalue()).decode()


def write_html(doc: Document, out: str | Path) -> Path:
    """The document as one self-contained HTML file (jinja2; extra `report`)."""
    try:
        import jinja2
    except ImportError:
        raise UserInputError(f"hpsim report --html needs jinja2: {install_hint('report')}") from None
    _encode_figures(doc)
    env = jinja2.Environment(loader=jinja2.FileSystemLoader(Path(__file__).parent / "templates"),
                             autoescape=jinja2.select_autoescape(["html", "j2"]), keep_trailing_newline=True)
    sections = [{"title": s.title, "paragraphs": [{"cls": c, "text": t} for c, t in s.paragraphs],
                 "tables": s.tables, "figures": s.figures} for s in doc.sections]
    html = env.get_template(TEMPLATE).render(title=doc.title, intro=doc.intro, sections=sections,
                                             provenance=doc.provenance)
    out = Path(out)
    with atomic_output(out) as tmp:
        tmp.write_text(html, encoding="utf-8")
    return out


PAGE_IN = (11.69, 8.27)          # A4 landscape [inch]
LINE = 0.022                     # a text line in figure fractions of the page
HEADING_WITH_NEXT = 5 * LINE        # room a heading needs below it on its page: itself and a few lines


class _Pages:
    """Text and tables flowed down A4 pages of a PdfPages file."""

    def __init__(self, pdf, first_page_png=None):
        self.pdf, self.fig, self.y, self.png, self.n = pdf, None, 0.0, first_page_png, 0

    def _page(self):
        self.flush()
        self.fig = pyplot().figure(figsize=PAGE_IN)
        self.y = 0.95

    def flush(self):
        if self.fig is not None:
            self.pdf.savefig(self.fig)
            if self.png is not None and self.n == 0:
                self.fig.savefig(self.png, dpi=DPI)
            self.n += 1
            pyplot().close(self.fig)
            self.fig = None

    def need(self, height):
        if self.fig is None or self.y - height < 0.05:
            self._page()

    def text(self, text, size=9, weight="normal", color="k"):
        import textwrap

        lines = textwrap.wrap(text, 150 if size <= 9 else 110) or [""]
        for line in lines:
            self.need(LINE * size / 9)
            self.fig.text(0.05, self.y, line, fontsize=size, weight=weight, color=color, va="top")
            self.y -= LINE * size / 9 * 1.15

    def table(self, t: Table):
        if t.caption:
            self.text(t.caption, size=8, color="0.3")
        rows = t.rows or [["-"] * len(t.headers)]
        for start in range(0, len(rows), 30):
            chunk = rows[start:start + 30]
            h = LINE * (len(chunk) + 1.5)
            self.need(h)
            ax = self.fig.add_axes([0.05, self.y - h, 0.9, h])
            ax.axis("off")
            tab = ax.table(cellText=chunk, colLabels=t.headers, loc="upper left", cellLoc="right")
            tab.auto_set_font_size(False)
            size = 7.5
            tab.set_fontsize(size)
            tab.auto_set_column_width(list(range(len(t.headers))))
            for _ in range(4):               # too wide for the page: smaller type (the columns follow it)
                self.fig.canvas.draw()
                renderer = self.fig.canvas.get_renderer()
                width = tab.get_window_extent(renderer).width / ax.get_window_extent(renderer).width
                if width <= 1.0:
                    break
                size /= width * 1.03
                tab.set_fontsize(size)
            self.y -= h + LINE


def write_pdf(doc: Document, out: str | Path, first_page_png: str | Path | None = None) -> Path:
    """The document as a PDF (matplotlib's PdfPages): text and tables flowed over A4 pages, one page per
    figure; first_page_png: also the first page as a PNG."""
    from matplotlib.backends.backend_pdf import PdfPages

    out = Path(out)
    plt = pyplot()
    with atomic_output(out) as tmp, PdfPages(tmp) as pdf:
        pages = _Pages(pdf, first_page_png)
        pages.text(doc.title, size=14, weight="bold")
        for p in doc.intro:
            pages.text(p)
        figures = []
        for sec in doc.sections:
            figures += [(sec.title, f) for f in sec.figures]
            if not sec.tables and not sec.paragraphs:
                continue             # a section of figures only: its title heads its figure pages
            pages.need(HEADING_WITH_NEXT)        # a heading never ends a page alone
            pages.text(sec.title, size=11, weight="bold")
            for t in sec.tables:
                pages.table(t)
            for cls, t in sec.paragraphs:
                pages.text(t, color={"warning": "#8a4b00", "error": "#a00000"}.get(cls, "k"))
        pages.need(HEADING_WITH_NEXT)
        pages.text("Provenance", size=11, weight="bold")
        for k, v in doc.provenance:
            pages.text(f"{k}: {v}")
        pages.flush()
        for title, f in figures:
            if f.fig is not None:
                f.fig.suptitle(f"{title}: " + (f.fig._suptitle.get_text() if f.fig._suptitle else f.caption))
                pdf.savefig(f.fig)
                plt.close(f.fig)
                f.fig = None
            else:
                img = plt.imread(io.BytesIO(base64.b64decode(f.png_base64)), format="png")
                fig = plt.figure(figsize=PAGE_IN)
                ax = fig.add_axes([0.03, 0.08, 0.94, 0.88])
                ax.imshow(img)
                ax.axis("off")
                fig.text(0.5, 0.03, f"{title}: {f.caption}", ha="center", fontsize=9)
                pdf.savefig(fig)
                plt.close(fig)
        info = pdf.infodict()
        info["Title"] = doc.title
        info["Creator"] = dict(doc.provenance).get("report by", "hpsim")
    return out
