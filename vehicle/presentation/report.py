"""Text tables of drive summaries: `hpsim report` and `hpsim compare` (data from vehicle.runs.summary)."""
from __future__ import annotations

from pathlib import Path

from vehicle.runs.summary import compare, open_results, report, report_from  # noqa: F401  (re-exported)


def format_report(rep: dict) -> str:
    from hpsim.tables import format_table

    head = (f"{rep['file']}: {rep['status']}, {rep['distance_km']:.3f} of {rep['planned_distance_km']:.6g} km, "
            f"simulated {rep['simulated_s'] / 3600:.3f} h in {rep['wall_s']:.1f} s wall, "
            f"compensation {'on' if rep['compensation'] else 'off'}")
    cols = ["axle", "T_start_C", "T_end_C", "dh_mm", "N_before_daN", "N_after_daN", "dN_pct", "energy_dissipated_MJ"]
    headers = ["axle", "T start [degC]", "T end [degC]", "dh [mm]", "N before [daN]", "N after [daN]", "dN [%]",
               "E diss [MJ]"]
    fmts = {"T_start_C": ".1f", "T_end_C": ".1f", "dh_mm": ".2f", "N_before_daN": ".0f", "N_after_daN": ".0f",
            "dN_pct": "+.2f", "energy_dissipated_MJ": ".3f"}

    def cell(r, c):
        v = r[c]
        if v is None:
            return "-"
        return format(v, fmts[c]) if c in fmts else str(v)

    table = format_table(headers, [[cell(r, c) for c in cols] for r in rep["axles"]])
    tail = []
    if rep.get("load_shift_pct") is not None:
        tail.append(f"load shift {rep['load_shift_pct']:.2f} % (sum |dN| / sum N), max |dN| {rep['max_abs_dN_pct']:.2f} %; "
                    f"against the charged loads {rep['load_shift_vs_charged_pct']:.2f} %")
    if rep.get("mean_temperature_rise_K") is not None:
        tail.append(f"mean strut temperature rise {rep['mean_temperature_rise_K']:.1f} K")
    if rep.get("error"):
        tail.append(f"stopped: {rep['error']}")
    return "\n".join([head, table] + tail)


def format_compare(cmp: dict, labels=None) -> str:
    from hpsim.tables import format_table

    runs = cmp["runs"]
    labels = labels or [Path(r["file"]).stem for r in runs]
    blocks = []
    for key, title, fmt in (("dN_pct", "wheel load change dN [%] (after vs before)", "+.2f"),
                            ("dh_mm", "height change dh [mm]", "+.2f"),
                            ("T_end_C", "strut temperature at the end [degC]", ".1f")):
        rows = []
        for k in range(len(runs[0]["axles"])):
            rows.append([k + 1] + ["-" if r["axles"][k][key] is None else format(r["axles"][k][key], fmt) for r in runs])
        blocks.append(title + "\n" + format_table(["axle"] + labels, rows))
    rows = [["load shift [%]"] + ["-" if r["load_shift_pct"] is None else f"{r['load_shift_pct']:.2f}" for r in runs],
            ["vs charged [%]"] + ["-" if r["load_shift_vs_charged_pct"] is None
                                  else f"{r['load_shift_vs_charged_pct']:.2f}" for r in runs],
            ["mean T rise [K]"] + ["-" if r["mean_temperature_rise_K"] is None else f"{r['mean_temperature_rise_K']:.1f}"
                                   for r in runs],
            ["distance [km]"] + [f"{r['distance_km']:.3f}" for r in runs],
            ["compensation"] + ["on" if r["compensation"] else "off" for r in runs]]
    blocks.append(format_table([""] + labels, rows))
    return "\n\n".join(blocks)


def format_summary(result: dict) -> str:
    from hpsim.tables import format_table

    rows = []
    for r in result["cases"]:
        ls = r.get("load_shift_pct")
        lc = r.get("load_shift_vs_charged_pct")
        rows.append([r["case"], r["status"], "-" if ls in (None, "") else f"{ls:.2f}",
                     "-" if lc in (None, "") else f"{lc:.2f}",
                     "-" if r.get("mean_temperature_rise_K") in (None, "") else f"{r['mean_temperature_rise_K']:.1f}",
                     (r["error"][:100] + "...") if len(r.get("error", "")) > 100 else r.get("error", "")])
    text = format_table(["case", "status", "load shift [%]", "vs charged [%]", "mean T rise [K]", "error"], rows)
    text += f"\nsummary: {result['summary_csv']}"
    if result["plots"]:
        text += "\nplots: " + ", ".join(result["plots"])
    if result["failed"]:
        text += f"\nfailed: {', '.join(result['failed'])}"
    return text
