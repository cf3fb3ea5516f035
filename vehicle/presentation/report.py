"""Text tables of drive summaries: `hpsim report` and `hpsim compare` (data from vehicle.analysis.summary)."""
from __future__ import annotations

from pathlib import Path

from hpsim.tables import format_table

from vehicle.results.validity import format_warnings as lines
from vehicle.analysis.ride_metrics import axle_rows
from vehicle.analysis.summary import axle_value, compare, open_results, report, report_from  # noqa: F401  (re-exported)


def format_report(rep: dict) -> str:
    head = (f"{rep['file']}: {rep['status']}, {rep['distance_km']:.3f} of {rep['planned_distance_km']:.6g} km, "
            f"simulated {rep['simulated_s'] / 3600:.3f} h (the drive {rep['wall_s']:.1f} s wall), "
            f"compensation {'on' if rep['compensation'] else 'off'}")
    # T end: the outer surface (pyrometer); oil and gas inside (the heat network, vehicle.physics.thermal)
    cols = ["axle", "T_start_C", "T_end_C", "T_oil_end_C", "T_gas_end_C", "dh_mm", "N_before_daN", "N_after_daN",
            "dN_pct", "energy_dissipated_MJ"]
    headers = ["axle", "T start [degC]", "T surface end [degC]", "T oil end", "T gas end", "dh [mm]",
               "N before [daN]", "N after [daN]", "dN [%]", "E diss axle [MJ]"]
    fmts = {"T_start_C": ".1f", "T_end_C": ".1f", "T_oil_end_C": ".1f", "T_gas_end_C": ".1f", "dh_mm": ".2f",
            "N_before_daN": ".0f", "N_after_daN": ".0f", "dN_pct": "+.2f", "energy_dissipated_MJ": ".3f"}

    def cell(r, c):
        v = r.get(c)
        if v is None:
            return "-"
        return format(v, fmts[c]) if c in fmts else str(v)

    table = format_table(headers, [[cell(r, c) for c in cols] for r in rep["axles"]])
    tail = []
    if rep.get("load_shift_pct") is not None:
        tail.append(f"load shift {rep['load_shift_pct']:.2f} % (sum |dN| / sum N), max |dN| {rep['max_abs_dN_pct']:.2f} %; "
                    f"against the charged loads {rep['load_shift_vs_charged_pct']:.2f} %")
    if rep.get("mean_temperature_rise_K") is not None:
        tail.append(f"mean strut (surface) temperature rise {rep['mean_temperature_rise_K']:.1f} K")
    tail += _solver_mode_lines(rep)
    if rep.get("error"):
        tail.append(f"stopped: {rep['error']}")
    ride = format_ride(rep.get("ride") or {}, len(rep["axles"]))
    if ride:
        tail.append("")
        tail.append(ride)
    if rep.get("damping_over_drive"):
        tail.append("")
        tail.append(format_damping_over_drive(rep["damping_over_drive"]))
    if rep.get("warnings"):
        tail.append("")
        tail += format_warnings(rep["warnings"])
    return "\n".join([head, table] + tail)


def _solver_mode_lines(rep: dict) -> list[str]:
    """What a multiscale or time-parallel run adds: how it drove and its estimated error; [] for a full run."""
    tail = []
    est = rep.get("estimated_error")
    if rep.get("solver_mode") == "multiscale" and est:
        def worst(v):
            v = [x for x in v if x is not None]
            return max(v) if v else float("nan")
        tail.append(f"solver mode multiscale: {est['windows']} windows of {est['window_m']:.0f} m, one per "
                    f"{est['spacing_m'] / 1e3:.3g} km ({est['covered_km']:.3g} km driven with the full model"
                    + (f"; {est['paired']} of the windows from a predicted start, beside the one before"
                       if est.get("paired") else "") + "); "
                    f"estimated error (95 %, {est['sigmas']:.2g} sigma, road sampling"
                    f"{', with the control variate on the ' + est.get('proxy', 'road_rate').replace('_', '-') + ' proxy' if est.get('control_variate') else ''}): T surface end "
                    + ", ".join("-" if x is None else f"{x:.2f}" for x in est["T_end_K"]) + " K, dN "
                    + ", ".join("-" if x is None else f"{x:.3f}" for x in est["dN_pct"])
                    + f" pp per axle (up to {worst(est['T_end_K']):.2f} K, {worst(est['dN_pct']):.3f} pp); it covers "
                    "the surface temperature and dN only, not the oil and gas end temperatures (the gas's "
                    "last-interval mean follows the last window's road: 1.1-1.4 K off a full run, docs/validation.md)")
    if rep.get("solver_mode") == "time_parallel" and est:
        lanes = est.get("lanes", 1)
        how = (f" ({lanes} per process in lockstep on the lane library)" if lanes > 1 else "")
        tail.append(f"solver mode time_parallel: {est['segments']} segments in parallel processes{how}, slow states "
                    f"corrected at the joins (coarse prediction off by up to {est['coarse_mismatch_K']:.3f} K); "
                    "estimated error of the correction: T end "
                    + ", ".join("-" if x is None else f"{x:.3f}" for x in est["T_end_K"]) + " K, dN "
                    + ", ".join("-" if x is None else f"{x:.4f}" for x in est["dN_pct"]) + " pp per axle")
    return tail


def format_damping_over_drive(rows) -> str:
    """The struts' equivalent damping and mapped friction in the first and last statistics interval
    (vehicle.analysis.internal_drift)."""
    def pair(r, key, fmt):
        a, b = r.get(f"{key}_first{fmt[0]}"), r.get(f"{key}_last{fmt[0]}")
        return "-" if a is None or b is None else f"{a:{fmt[1]}} -> {b:{fmt[1]}}"
    body = [[r["axle"], pair(r, "T_oil", ("_C", ".1f")), pair(r, "c_valve", ("_kNs_m", ".2f")),
             pair(r, "c_friction", ("_kNs_m", ".2f")), pair(r, "coulomb_compression", ("_N", ".0f")),
             pair(r, "coulomb_rebound", ("_N", ".0f"))] for r in rows]
    out = ("damping and friction over the drive (first -> last statistics interval; c = P / v_rms^2 at the strut)\n"
           + format_table(["axle", "T oil [degC]", "c valve [kN s/m]", "c friction [kN s/m]",
                           "Coulomb comp [N]", "Coulomb reb [N]"], body))
    outside = [r for r in rows if r.get("maps_range_C") and any(
        not r["maps_range_C"][0] <= r.get(f"T_oil_{t}_C", 0.0) <= r["maps_range_C"][1] for t in ("first", "last"))]
    if outside:
        lo, hi = outside[0]["maps_range_C"]
        out += (f"\nnote: oil temperature outside the struts' internal maps ({lo:.0f}-{hi:.0f} degC, seed 001's tests) at "
                f"axle {', '.join(str(r['axle']) for r in outside)}: the maps' edge values are used there")
    return out


def format_warnings(warnings) -> list[str]:
    return lines(warnings)


# (key, header, scale, format) of the ride tables; a column shows when any row has the key
SEAT_COLUMNS = (("weighted_rms_acceleration_m_s2", "a_w Wk [m/s^2]", 1.0, ".3f"),
                ("comfort", "ISO 2631-1 Annex C", None, "s"),
                ("weighted_rms_lateral_acceleration_m_s2", "a_w Wd lat. [m/s^2]", 1.0, ".3f"),
                ("vdv_m_s175", "VDV [m/s^1.75]", 1.0, ".3g"),
                ("absorbed_power_W", "abs. power [W]", 1.0, ".3g"),
                ("crest_factor", "crest factor", 1.0, ".2f"),
                ("mtvv_m_s2", "MTVV [m/s^2]", 1.0, ".3f"),
                ("sed_MPa", "Sed drive [MPa]", 1.0, ".3f"),
                ("daily_sed_MPa", "Sed daily [MPa]", 1.0, ".3f"))
AXLE_COLUMNS = (("dynamic_load_coefficient", "DLC", 1.0, ".3f"),
                ("lift_off_share", "lift-off [%]", 100.0, ".2f"),
                ("end_stop_time_s", "on stops [s]", 1.0, ".3g"),
                ("end_stop_energy_J", "stop energy [kJ]", 1e-3, ".3g"),
                ("strut_travel_min_m", "travel bin lo [mm]", 1e3, ".1f"),
                ("strut_travel_max_m", "travel bin hi [mm]", 1e3, ".1f"),
                ("strut_travel_p1_m", "p1 [mm]", 1e3, ".1f"),
                ("strut_travel_p99_m", "p99 [mm]", 1e3, ".1f"),
                ("rms_strut_velocity_m_per_s", "RMS v [mm/s]", 1e3, ".0f"))


TRAVEL_NOTE = ("travel bin lo/hi: edges of the lowest and highest strut-travel bins (equal bins over the stroke) "
               "the strut spent time in, not measured extremes: the smallest and largest deflections lie within "
               "one bin inside them; p1/p99 interpolated within the bins")


def _ride_table(rows, columns, first):
    cols = [c for c in columns if any(r.get(c[0]) is not None for r in rows)]
    if not cols:
        return ""

    def cell(v, scale, fmt):
        if v is None:
            return "-"
        return str(v) if scale is None else format(v * scale, fmt)

    return format_table([first[1]] + [c[1] for c in cols],
                        [[r[first[0]]] + [cell(r.get(k), sc, f) for k, _, sc, f in cols] for r in rows])


def format_ride(ride: dict, n_axles: int) -> str:
    """The ride (per seat) and road-holding (per axle, worst of left and right) tables of a drive."""
    parts = []
    if ride.get("seats"):
        parts.append("ride comfort over the drive (ISO 2631-1 weighted RMS, VDV; absorbed power)")
        parts.append(_ride_table(ride["seats"], SEAT_COLUMNS, ("seat", "seat")))
        parts += shock_notes(ride["seats"])
    rows = axle_rows(ride, [None] * n_axles)
    table = _ride_table(rows, AXLE_COLUMNS, ("axle", "axle")) if rows else ""
    if table:
        parts.append("road holding and strut travel (worst of left and right)")
        parts.append(table)
        if "travel bin lo" in table:
            parts.append(TRAVEL_NOTE)
    hull = ride.get("hull")
    if hull:
        parts.append(f"hull RMS acceleration: heave {hull['rms_heave_acceleration_m_s2']:.3g} m/s^2, "
                     f"pitch {hull['rms_pitch_acceleration_rad_s2']:.3g} rad/s^2, "
                     f"roll {hull['rms_roll_acceleration_rad_s2']:.3g} rad/s^2")
    return "\n".join(parts)


def shock_notes(seats) -> list[str]:
    """Lines on the seats' shocks: ISO 2631-1's warning when a_w understates them, ISO 2631-5's reading of Sed."""
    lines = []
    for s in seats:
        if s.get("a_w_unreliable"):
            lines.append(f"note: {s['seat']}: {', '.join(s['a_w_unreliable'])}: a_w understates the shocks "
                         "(ISO 2631-1 §6.2.1, §6.3.3); judge by VDV and MTVV")
        if s.get("daily_sed_MPa") is not None:
            lines.append(f"{s['seat']}: ISO 2631-5 Sed {s['daily_sed_MPa']:.3f} MPa for "
                         f"{s['daily_exposure_s'] / 3600:.3g} h a day of this driving: {s['sed_assessment']} "
                         "(hull at the seat point, no cushion)")
    return lines


def format_psd(psd: dict) -> str:
    """Peak frequency and RMS of each response PSD (`hpsim report --psd`); strut forces: the range over the
    stations."""
    rows = []
    for name, peaks in psd["peaks_hz"].items():
        rms = psd["rms"][name]
        unit = psd["signal_units"][name]
        if len(peaks) == 1:
            rows.append([name.replace("_", " "), f"{peaks[0]:.2f}", f"{rms[0]:.3g} {unit}"])
        else:
            rows.append([f"{name.replace('_', ' ')} ({len(peaks)} struts)", f"{min(peaks):.2f}-{max(peaks):.2f}",
                         f"{min(rms):.3g}-{max(rms):.3g} {unit}"])
    head = (f"response PSDs (Welch, {psd['duration_s']:.0f} s at {psd['fs_hz']:.0f} Hz): {psd['figure']}")
    return head + "\n" + format_table(["signal", "peak [Hz]", "RMS"], rows)


def format_compare(cmp: dict, labels=None) -> str:
    runs = cmp["runs"]
    labels = labels or [Path(r["file"]).stem for r in runs]
    blocks = []
    for key, title, fmt in (("dN_pct", "wheel load change dN [%] (after vs before)", "+.2f"),
                            ("dh_mm", "height change dh [mm]", "+.2f"),
                            ("T_end_C", "strut surface temperature at the end [degC]", ".1f")):
        rows = []
        for k in range(cmp["n_axles"]):
            rows.append([k + 1] + ["-" if axle_value(r, k, key) is None else format(axle_value(r, k, key), fmt)
                                   for r in runs])
        blocks.append(title + "\n" + format_table(["axle"] + labels, rows))
    rows = [["load shift [%]"] + ["-" if r["load_shift_pct"] is None else f"{r['load_shift_pct']:.2f}" for r in runs],
            ["vs charged [%]"] + ["-" if r["load_shift_vs_charged_pct"] is None
                                  else f"{r['load_shift_vs_charged_pct']:.2f}" for r in runs],
            ["mean T rise [K]"] + ["-" if r["mean_temperature_rise_K"] is None else f"{r['mean_temperature_rise_K']:.1f}"
                                   for r in runs],
            ["distance [km]"] + [f"{r['distance_km']:.3f}" for r in runs],
            ["compensation"] + ["on" if r["compensation"] else "off" for r in runs]]
    seats = {s["seat"] for r in runs for s in (r.get("ride") or {}).get("seats", [])}
    for seat in sorted(seats):
        vals = []
        for r in runs:
            found = [s for s in (r.get("ride") or {}).get("seats", []) if s["seat"] == seat]
            a = found[0].get("weighted_rms_acceleration_m_s2") if found else None
            vals.append("-" if a is None else f"{a:.3f}")
        rows.append([f"a_w {seat} [m/s^2]"] + vals)
    rows.append(["warnings"] + [str(len(r.get("warnings") or [])) for r in runs])
    blocks.append(format_table([""] + labels, rows))
    notes = [f"{lab}: {w['severity']}: {w['message']}" for lab, r in zip(labels, runs) for w in r.get("warnings") or []]
    if notes:
        blocks.append("\n".join(notes))
    return "\n\n".join(blocks)


def format_summary(result: dict) -> str:
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
