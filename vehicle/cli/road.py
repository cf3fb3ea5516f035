"""`hpsim road ...` sub-commands: generate, psd, plot.

    hpsim road generate --class D --length 20km --seed 7 [--spacing 50mm] [--track 2.5m]
                        [--coherence isotropic|independent|identical] -o road.csv [--json]
    hpsim road psd road.csv [--json] [--plot psd.png]
    hpsim road psd --class D --length 20km --seed 7 [--json]
    hpsim road plot road.csv -o road.png
    hpsim road import track.crg -o road.csv [--track 2.5m] [--spacing 50mm] [--lateral-offset 1.5m]

A road comes either from a CSV file (distance_m,left_m,right_m), an OpenCRG file (*.crg: its tracks at
lateral offset +-track/2 across the reference line, v positive to the left; needs the extra crg) or from a
spec: --class / --gd-n0 options, or --spec road.yaml (a RoadSpec, with events; options given on the command
line override its keys). Bad input raises UserInputError naming the argument, file or line (exit code 2).
"""
from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from pydantic import ValidationError

from hpsim.tables import format_table, print_json
from hpsim.config import load_yaml, short_repr
from hpsim.errors import UserInputError
from hpsim.outputs import atomic_output, check_figure_file, check_output_file

from terrain.coherence import COHERENCE_MODELS, coherence_model
from terrain.crg import is_crg

from .options import add_overwrite

if TYPE_CHECKING:
    from terrain.road import Road
    from terrain.spec import RoadSpec

# RoadSpec field -> command-line option (for error messages)
_OPTIONS = {
    "iso_class": "--class", "gd_n0": "--gd-n0", "waviness": "--waviness", "length": "--length",
    "spacing": "--spacing", "seed": "--seed", "band": "--band", "track_width": "--track",
    "coherence": "--coherence", "lateral_offset": "--lateral-offset",
}
_JSON_ARRAYS = ("frequency_cycle_per_m", "psd_left_m3", "psd_right_m3", "coherence")


def register(sub):
    p = sub.add_parser("road", help="generate, analyse and plot road profiles (ISO 8608, events, CSV)",
                       description=__doc__.splitlines()[0])
    rs = p.add_subparsers(dest="road_command", required=True, parser_class=type(p))

    g = rs.add_parser("generate", help="generate a road and write it as CSV")
    _spec_options(g)
    g.add_argument("-o", "--output", required=True, help="CSV file to write (distance_m,left_m,right_m)")
    g.add_argument("--json", action="store_true", help="print only JSON on stdout")
    add_overwrite(g)
    g.set_defaults(func=cmd_generate)

    q = rs.add_parser("psd", help="PSD, fitted Gd(n0) and w, ISO class, RMS, coherence, IRI")
    q.add_argument("csv", nargs="?", help="road CSV (distance_m,left_m,right_m) or OpenCRG file (*.crg); or give a spec")
    _spec_options(q)
    q.add_argument("--json", action="store_true", help="print only JSON on stdout")
    q.add_argument("--plot", metavar="PNG", help="also save the PSD figure")
    add_overwrite(q)
    q.set_defaults(func=cmd_psd)

    im = rs.add_parser("import", help="the left/right tracks of an OpenCRG road surface as a road CSV")
    im.add_argument("crg", help="OpenCRG file (*.crg)")
    im.add_argument("-o", "--output", required=True, help="CSV file to write (distance_m,left_m,right_m)")
    im.add_argument("--track", default="2.5m", help="track width: the tracks lie at +-track/2 of the reference "
                                                     "line (default 2.5m, the apc_8x8)")
    im.add_argument("--spacing", default=None, help="grid spacing (default: the file's u increment)")
    im.add_argument("--lateral-offset", dest="lateral_offset", default=None, metavar="Q",
                    help="v of the vehicle's centre line across the reference line, positive to the left (default "
                         "0m: centred on it; a file covering v from 0 to 3 m needs 1.5m)")
    im.add_argument("--json", action="store_true", help="print only JSON on stdout")
    add_overwrite(im)
    im.set_defaults(func=cmd_import)

    pl = rs.add_parser("plot", help="plot the profile and its PSD against the ISO class bands")
    pl.add_argument("csv", nargs="?", help="road CSV (distance_m,left_m,right_m) or OpenCRG file (*.crg); or give a spec")
    _spec_options(pl)
    pl.add_argument("-o", "--output", required=True, help="PNG file to write")
    add_overwrite(pl)
    pl.set_defaults(func=cmd_plot)


def _spec_options(p):
    s = p.add_argument_group("road spec (instead of a CSV file)")
    s.add_argument("--spec", metavar="YAML", help="RoadSpec YAML file (events, measured csv, ...)")
    s.add_argument("--class", dest="iso_class", metavar="A-H", help="ISO 8608 class (geometric-mean Gd(n0))")
    s.add_argument("--gd-n0", dest="gd_n0", metavar="Q", help="custom Gd(n0), e.g. '1.5e-3 m**3' (bare: m³)")
    s.add_argument("--waviness", metavar="W", help="PSD exponent w (default 2)")
    s.add_argument("--length", metavar="Q", help="road length, e.g. 20km")
    s.add_argument("--spacing", metavar="Q", help="grid spacing (default 50mm)")
    s.add_argument("--seed", metavar="INT", help="random seed (default 0)")
    s.add_argument("--band", metavar="NMIN,NMAX", help="spatial band in cycle/m (default 0.011,2.83)")
    s.add_argument("--track", dest="track_width", metavar="Q", help="track width (default 2.5m)")
    s.add_argument("--coherence", metavar="|".join(COHERENCE_MODELS),
                   help="left/right coherence model (default isotropic)")
    s.add_argument("--lateral-offset", dest="lateral_offset", metavar="Q",
                   help="OpenCRG file: v of the vehicle's centre line, positive left of the reference line "
                        "(default 0m)")


def _spec_given(args) -> bool:
    return args.spec is not None or any(getattr(args, k) is not None for k in _OPTIONS)


def spec_from_args(args) -> tuple[RoadSpec, Path | None]:
    """RoadSpec from --spec and/or options; errors name the option (or the YAML file and key)."""
    from terrain.spec import RoadSpec

    data: dict = {}
    base_dir = None
    source = "command line"
    if args.spec is not None:
        loaded = load_yaml(args.spec)
        if not isinstance(loaded, dict):
            raise UserInputError(f"{args.spec}: expected a mapping of RoadSpec keys, got {type(loaded).__name__}")
        data.update(loaded)
        base_dir = Path(args.spec).resolve().parent
        source = str(args.spec)
    from_cli = set()
    for key in _OPTIONS:
        value = getattr(args, key)
        if value is None:
            continue
        if key == "band":
            value = [v.strip() for v in value.split(",")]
            if len(value) != 2:
                raise UserInputError(f"--band: expected NMIN,NMAX in cycle/m (e.g. 0.011,2.83), got {args.band!r}")
        data[key] = value
        from_cli.add(key)
    if args.iso_class is not None or args.gd_n0 is not None:  # command line source replaces the file's
        for other in ("iso_class", "gd_n0", "csv", "flat"):
            if other not in from_cli:
                data.pop(other, None)
    try:
        return RoadSpec.model_validate(data), base_dir
    except ValidationError as exc:
        raise UserInputError(_format_errors(exc, from_cli, source)) from None


def _format_errors(exc: ValidationError, from_cli: set, source: str) -> str:
    parts = []
    for err in exc.errors():
        loc = err["loc"]
        msg = err["msg"].removeprefix("Value error, ")
        if err["type"] == "extra_forbidden":
            msg = "unknown key (check the spelling)"
        if loc and loc[0] in from_cli:
            where = _OPTIONS[loc[0]]
        elif loc:
            where = f"{source}: " + ".".join(str(p) for p in loc)
        else:
            where = source if source != "command line" else "arguments"
            msg = (msg.replace("iso_class (A-H)", "--class A-H").replace("gd_n0 (custom Gd(n0))", "--gd-n0")
                   .replace("length is required", "--length is required"))
            for field in from_cli:
                msg = msg.replace(field, _OPTIONS[field])
        value = err.get("input")
        shown = "" if err["type"] in ("missing", "extra_forbidden") or isinstance(value, dict) or not loc \
            else f" (got {short_repr(value)})"
        parts.append(f"{where}: {msg}{shown}")
    return "; ".join(parts)


def _load_road(args) -> tuple[Road, RoadSpec | None]:
    from terrain.road import Road
    from terrain.spec import build_road

    if args.csv is not None and _spec_given(args):
        if args.spec is not None or args.iso_class is not None or args.gd_n0 is not None:
            raise UserInputError(f"{args.csv}: give either a CSV file or a road spec (--class/--gd-n0/--spec), "
                                 "not both")
    if args.csv is not None:
        spacing = None
        if args.spacing is not None:
            from hpsim.units import parse_quantity

            spacing = parse_quantity(args.spacing, "m", where="--spacing")
            if not spacing > 0:
                raise UserInputError(f"--spacing: must be > 0 m (got {args.spacing!r})")
        if is_crg(args.csv):
            return Road.from_crg(args.csv, _track(args.track_width), spacing_m=spacing,
                                 lateral_offset_m=_lateral_offset(args.lateral_offset)), None
        if args.lateral_offset is not None:
            raise UserInputError(f"--lateral-offset: places the tracks on an OpenCRG file (*.crg); {args.csv} is not "
                                 "one")
        return Road.from_csv(args.csv, spacing_m=spacing), None
    if not _spec_given(args):
        raise UserInputError("give a road CSV file, or a spec: --class A-H (or --gd-n0) --length ..., "
                             "or --spec road.yaml")
    spec, base_dir = spec_from_args(args)
    return build_road(spec, base_dir), spec


def _track(text) -> float:
    """--track [m] (default: RoadSpec's 2.5 m)."""
    from hpsim.units import parse_quantity
    from terrain.spec import MAX_TRACK_WIDTH_M, RoadSpec

    if text is None:
        return float(RoadSpec.model_fields["track_width"].default)
    w = parse_quantity(text, "m", where="--track")
    if not 0 < w <= MAX_TRACK_WIDTH_M:
        raise UserInputError(f"--track: must be in (0, {MAX_TRACK_WIDTH_M}] m, got {text!r}")
    return w


def _lateral_offset(text) -> float:
    """--lateral-offset [m] (default 0: the vehicle centred on the reference line)."""
    from hpsim.units import parse_quantity

    return 0.0 if text is None else parse_quantity(text, "m", where="--lateral-offset")


def cmd_import(args) -> int:
    from hpsim.units import parse_quantity
    from terrain.road import Road

    check_output_file(args.output, "-o/--output", inputs=[args.crg], overwrite=args.overwrite)
    spacing = None if args.spacing is None else parse_quantity(args.spacing, "m", where="--spacing")
    if spacing is not None and not spacing > 0:
        raise UserInputError(f"--spacing: must be > 0 m (got {args.spacing!r})")
    road = Road.from_crg(args.crg, _track(args.track), spacing_m=spacing,
                         lateral_offset_m=_lateral_offset(args.lateral_offset))
    with atomic_output(args.output) as tmp:
        road.to_csv(tmp)
    summary = {"output": str(args.output), "length_m": road.length_m, "spacing_m": road.spacing_m,
               "points": road.n_points, **road.info,
               "rms_left_m": float(np.std(road.left_m)), "rms_right_m": float(np.std(road.right_m))}
    if args.json:
        print_json(summary)
    elif getattr(args, "verbosity", 0) < 0:
        print(args.output)
    else:
        v_left = summary["lateral_offset_m"] + summary["track_width_m"] / 2
        v_right = summary["lateral_offset_m"] - summary["track_width_m"] / 2
        print(f"wrote {args.output}: {road.length_m:.6g} m at {road.spacing_m * 1e3:.4g} mm, tracks at v = "
              f"{v_right:g} and {v_left:g} m across the reference line of {args.crg}")
    return 0


def _spec_summary(spec: RoadSpec | None) -> dict:
    from terrain import iso8608

    if spec is None:
        return {}
    out = {"seed": spec.seed, "coherence_model": spec.coherence, "track_width_m": spec.track_width}
    if spec.gd_n0_m3 is not None:
        out["target_gd_n0_m3"] = spec.gd_n0_m3
        out["target_waviness"] = spec.waviness
        out["target_iso_class"] = iso8608.class_of_gd(spec.gd_n0_m3)
        out["target_rms_m"] = float(np.sqrt(iso8608.band_variance(spec.gd_n0_m3, spec.waviness,
                                                                   tuple(spec.band))))
        out["coherence_model_at_0p1_cycle_per_m"] = float(
            coherence_model(spec.coherence, iso8608.N0_CYCLE_PER_M, spec.track_width, spec.waviness))
    if spec.events:
        out["events"] = len(spec.events)
    return out


def cmd_generate(args) -> int:
    if not _spec_given(args):
        raise UserInputError("give --class A-H (or --gd-n0) and --length, or --spec road.yaml")
    check_output_file(args.output, "-o/--output", inputs=[args.spec], overwrite=args.overwrite)
    from terrain.spec import build_road

    spec, base_dir = spec_from_args(args)
    road = build_road(spec, base_dir)
    with atomic_output(args.output) as tmp:
        road.to_csv(tmp)
    summary = {"output": str(args.output), "length_m": road.length_m, "spacing_m": road.spacing_m,
               "points": road.n_points, **_spec_summary(spec),
               "rms_left_m": float(np.std(road.left_m)), "rms_right_m": float(np.std(road.right_m))}
    if args.json:
        print_json(summary)
    elif getattr(args, "verbosity", 0) < 0:          # -q: only the path written, as `hpsim run -q`
        print(args.output)
    else:
        print(_table(summary))
    return 0


def _statistics(road):
    from terrain.stats import road_statistics

    return road_statistics(road)


def cmd_psd(args) -> int:
    if args.plot:
        check_figure_file(args.plot, "--plot", inputs=[args.csv, args.spec], overwrite=args.overwrite)
    road, spec = _load_road(args)
    stats = _statistics(road)
    if args.plot:
        from terrain.plots import save_psd_plot

        with atomic_output(args.plot) as tmp:
            save_psd_plot(stats, tmp, title=_title(args, spec))
    out = {k: v for k, v in stats.items() if k not in _JSON_ARRAYS}
    out.update(_spec_summary(spec))
    if args.json:
        print_json(out)
    else:
        print(_psd_table(out))
    return 0


def cmd_plot(args) -> int:
    from terrain.plots import save_road_plot

    check_figure_file(args.output, "-o/--output", inputs=[args.csv, args.spec], overwrite=args.overwrite)
    road, spec = _load_road(args)
    stats = _statistics(road)
    with atomic_output(args.output) as tmp:
        save_road_plot(road, stats, tmp, title=_title(args, spec))
    print(f"wrote {args.output}")
    return 0


def _title(args, spec) -> str:
    if args.csv:
        return f"{args.csv}"
    what = f"class {spec.iso_class}" if spec.iso_class else (f"Gd(n0) = {spec.gd_n0:.4g} m³" if spec.gd_n0
                                                              else "road spec")
    return f"{what}, seed {spec.seed}, {spec.coherence} tracks"


def _table(d: dict) -> str:
    rows = [(k, v) for k, v in d.items() if not isinstance(v, (dict, list, np.ndarray))]
    return format_table(("quantity", "value"), rows, floatfmt=".6g")


def _fmt_se(value, rel=None, absolute=None):
    if value is None:
        return "-"
    if rel is not None:
        return f"{value:.4g} (±{100 * rel:.1f} %)"
    if absolute is not None:
        return f"{value:.4g} (±{absolute:.3f})"
    return f"{value:.4g}"


def _psd_table(s: dict) -> str:
    rows = [
        ("Gd(n0) fitted [m³]", _fmt_se(s["gd_n0_m3"], rel=s["gd_n0_rel_se"])),
        ("waviness w", _fmt_se(s["waviness"], absolute=s["waviness_se"])),
        ("ISO 8608 class", s["iso_class"] or "-"),
        ("RMS height [m]", _fmt_se(s["rms_m"])),
        ("coherence at 0.1 cycle/m", _fmt_se(s["coherence_at_0p1_cycle_per_m"])),
        ("IRI [m/km]", _fmt_se(s["iri_m_per_km"])),
        ("fit band [cycle/m]", "{:.3g}-{:.3g}".format(*s["fit_band_cycle_per_m"])),
        ("Welch segments", f"{s['welch_segments']} x {s['segment_length_m']:.4g} m"),
        ("length [m]", f"{s['length_m']:.6g}"),
    ]
    for key, label in (("target_gd_n0_m3", "target Gd(n0) [m³]"), ("target_iso_class", "target class"),
                       ("target_rms_m", "target RMS [m]"),
                       ("coherence_model_at_0p1_cycle_per_m", "model coherence at 0.1")):
        if key in s:
            rows.append((label, _fmt_se(s[key]) if not isinstance(s[key], str) else s[key]))
    return format_table(("quantity", "value"), rows)
