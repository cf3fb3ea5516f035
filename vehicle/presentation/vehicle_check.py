"""The text of `hpsim vehicle check` (the numbers: vehicle.physics.vehicle_check)."""
from __future__ import annotations

from hpsim.tables import format_table


def _defaults_text(defaults: list[dict]) -> list[str]:
    if not defaults:
        return ["keys left out: none (every key given)"]
    lines = [f"keys left out, with the default each took ({len(defaults)}):"]
    for d in defaults:
        unit = f" {d['unit']}" if d.get("unit") else ""
        value = f"{d['value']:.6g}" if isinstance(d["value"], float) else str(d["value"])
        line = f"  {d['key']} = {value}{unit}"
        if "shipped" in d:
            line += f"   <- differs from {d['shipped']['vehicle']}'s {d['shipped']['value']:.6g}"
        lines.append(line)
    return lines


def _standing_text(cases: list[dict]) -> list[str]:
    lines = []
    for case in cases:
        head = f"standing at {case['temperature_degC']:.1f} degC ({case['case']})"
        if not case["stands"]:
            lines.append(f"{head}: does not stand (see the findings)")
            continue
        rows = [[r["station"], r["strut"], f"{r['wheel_load_N'] / 10:.0f}", f"{r['deflection_mm']:.1f}",
                 f"{r['margin_extension_mm']:.1f}", f"{r['margin_bump_mm']:.1f}", f"{r['pressure_rest_MPa']:.2f}",
                 f"{r['pressure_full_bump_MPa']:.1f}"] for r in case["stations"]]
        lines += [head + ":", format_table(["station", "strut", "load [daN]", "deflection [mm]", "to extension [mm]",
                                            "to bump [mm]", "p rest [MPa]", "p full bump [MPa]"], rows)]
    return lines


def format_check(rep: dict) -> str:
    """The report of `hpsim vehicle check` as text (rep: CheckReport.as_dict())."""
    m = rep["mass"]
    lines = [f"{rep['vehicle']} ({rep['source']}): {'OK' if rep['ok'] else 'ERRORS'}, "
             f"{len(rep['errors'])} error(s), {len(rep['warnings'])} warning(s)"]
    if m:
        lines.append(f"mass: {m['wheel_loads_total_kg']:.6g} kg from the wheel loads, {m['sprung_kg']:.6g} kg sprung "
                     f"({'given' if m['hull_mass_given'] else 'derived from the loads'}), CG {m['sprung_cg_x_m']:.4g} m "
                     f"behind axle 1 ({'given' if m['hull_cg_x_given'] else 'derived'}), "
                     f"{m['unsprung_total_kg']:.6g} kg unsprung")
    lines += _defaults_text(rep["defaults"])
    lines += _standing_text(rep["standing"])
    roll = rep.get("roll_stability")
    if roll:
        lines.append(f"roll stability (standing, charging temperature): roll stiffness {roll['roll_stiffness_kNm_per_rad']:.4g} "
                     f"kN m/rad against m g h = {roll['overturning_kNm_per_rad']:.4g} kN m/rad "
                     f"({roll['roll_stiffness_margin']:.2f} x), static stability factor {roll['static_stability_factor']:.2f} "
                     f"(tip-over angle {roll['tip_over_angle_deg']:.1f} deg), rollover threshold "
                     f"{roll['rollover_threshold_g']:.2f} g")
    if rep["modes"]:
        s = rep["mode_summary"]
        rows = [[name, f"{s[name]['frequency_hz']:.3f}", f"{s[name]['damping_ratio']:.3f}"]
                for name in ("bounce", "pitch", "roll") if name in s]
        if "wheel_hop_range_hz" in s:
            lo, hi = s["wheel_hop_range_hz"]
            rows.append(["wheel hop/tramp", f"{lo:.2f}-{hi:.2f}", f"{s['wheel_hop_highest']['damping_ratio']:.3f}"])
        lines += ["modes:", format_table(["mode", "frequency [Hz]", "damping ratio"], rows)]
    for note in rep["notes"]:
        lines.append(f"note: {note}")
    for f in rep["warnings"]:
        lines.append(f"warning: {f['key']}: {f['message']}")
    for f in rep["errors"]:
        lines.append(f"error: {f['key']}: {f['message']}")
    return "\n".join(lines)
