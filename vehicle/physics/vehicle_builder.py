"""`hpsim vehicle new`: a complete, commented vehicle file from a few numbers.

Given the axles (positions), the static loads (per axle, or the total mass and its CG), the track, the
ride height and the strut per axle, `vehicle_text(spec)` writes a vehicle file (docs/vehicles.md) that
charges every strut by `charging.method: load_and_height`. The gas mass of each strut is set so that it
carries its wheel's load at the chosen static deflection at the charging temperature
(vehicle.physics.equilibrium.charge_gas_masses), so the vehicle stands at the given heights and loads.
Every other value comes from the labelled defaults of vehicle/data/templates/new_vehicle.yaml (most of
them the shipped apc_8x8's proportions) or is copied with its source from vehicle/data/apc_8x8.yaml
(heat network, longitudinal linkage, levelling), and says so in the file.

With a total mass and CG instead of axle loads the loads are those of a rigid hull on equal springs
(statically indeterminate beyond two axles): the least-squares split F_k = W/n + W (x_cg - x_mean)
(x_k - x_mean) / sum_j (x_j - x_mean)^2, which carries the weight W and puts its resultant at x_cg.
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import yaml

from hpsim.config import load_yaml, parse_yaml, validate
from hpsim.errors import UserInputError
from hpsim.outputs import atomic_output, check_output_file
from hpsim.units import parse_quantity
from struts.params import load_strut

from vehicle.physics.params import GRAVITY, VehicleParams, check_range, vehicle_file, with_strut_paths

MAX_AXLES = 10
TEMPLATE = "new_vehicle.yaml"


@dataclass
class VehicleSpec:
    """The numbers `hpsim vehicle new` takes (SI). Lists are per axle (one value: all axles)."""

    name: str
    positions_m: list[float]                      # behind axle 1; the first is 0
    track_m: float
    ride_heights_m: list[float]                   # hull height above the ground at each axle (charging.heights)
    struts: list[str]                             # strut per axle: built-in name or path
    axle_loads_N: list[float] | None = None       # static load per axle (both wheels)
    total_mass_kg: float | None = None            # or the whole vehicle's mass ...
    cg_x_m: float | None = None                   # ... and its CG behind axle 1
    strut_deflection_m: float | None = None       # static deflection (default: deflection_fraction of the stroke)
    motion_ratios: list[float] | None = None
    unsprung_masses_kg: list[float] | None = None  # per wheel station
    tyre_radius_m: float | None = None
    cg_height_m: float | None = None
    charging_temperature_K: float | None = None
    description: str = ""


def template_defaults() -> dict:
    """The builder's labelled defaults: {key: (SI value, source)} from vehicle/data/templates/new_vehicle.yaml."""
    path = Path(str(resources.files("vehicle") / "data" / "templates" / TEMPLATE))
    units = {"charging_temperature": "K", "tyre_radius": "m", "tyre_static_deflection": "m",
             "tyre_contact_length": "m", "hull_overhang": "m", "seat_height_above_cg": "m"}
    out = {}
    for key, item in load_yaml(path).items():
        out[key] = (parse_quantity(item["value"], units.get(key, ""), where=f"{path}: {key}"), item["source"])
    return out


def per_axle(values, n: int, where: str) -> list[float]:
    v = [float(x) for x in values]
    if len(v) == 1:
        return v * n
    if len(v) != n:
        raise UserInputError(f"{where}: give one value or one per axle ({n}), got {len(v)}")
    return v


def loads_from_mass(positions_m: list[float], mass_kg: float, cg_x_m: float) -> list[float]:
    """Static axle loads [N] of a rigid hull on equal springs carrying mass_kg with its CG at cg_x_m (module doc)."""
    n = len(positions_m)
    W = mass_kg * GRAVITY
    mean = sum(positions_m) / n
    spread = sum((x - mean) ** 2 for x in positions_m)
    loads = [W / n + W * (cg_x_m - mean) * (x - mean) / spread for x in positions_m]
    if min(loads) <= 0:
        raise UserInputError(f"cg_x: {cg_x_m:.4g} m behind axle 1 leaves an axle unloaded ({min(loads) / 1e3:.4g} kN) "
                             f"on axles at {positions_m} m: the CG must lie well between the end axles")
    return loads


def _check_spec(s: VehicleSpec) -> int:
    n = len(s.positions_m)
    if not 2 <= n <= MAX_AXLES:
        raise UserInputError(f"positions: give 2 to {MAX_AXLES} axle positions, got {n}")
    if s.positions_m[0] != 0.0 or any(b <= a for a, b in zip(s.positions_m, s.positions_m[1:])):
        raise UserInputError(f"positions: the first axle at 0 m, the others behind it in increasing order, got "
                             f"{s.positions_m} m")
    try:
        check_range("axle_position", s.positions_m[-1], "m")
        check_range("track", s.track_m, "m")
        for r in s.motion_ratios or []:
            check_range("motion_ratio", r)
    except ValueError as exc:
        name, rest = str(exc).split(" ", 1)
        raise UserInputError(f"{'positions' if name == 'axle_position' else name}: {rest}") from None
    if (s.axle_loads_N is None) == (s.total_mass_kg is None) or (s.axle_loads_N is not None and s.cg_x_m is not None):
        raise UserInputError("loads: give the axle loads, or the total mass and its CG (mass, cg_x), not both")
    if s.total_mass_kg is not None and (s.cg_x_m is None or not 100.0 <= s.total_mass_kg <= 200e3):
        raise UserInputError(f"mass: must be in [100, 200000] kg with cg_x given, got {s.total_mass_kg!r} kg, "
                             f"cg_x {s.cg_x_m!r}")
    if s.axle_loads_N is not None and min(s.axle_loads_N) <= 0:
        raise UserInputError(f"axle_loads: every axle load must be > 0, got {s.axle_loads_N}")
    if any(not 0.1 <= h <= 5.0 for h in s.ride_heights_m):
        raise UserInputError(f"ride_height: must be in [0.1, 5] m, got {s.ride_heights_m}")
    return n


def _q(value: str, source: str, prior: str | None = None) -> str:
    """A quantity with its source (and prior) as a YAML flow mapping."""
    text = f'{{value: "{value}", '
    if prior:
        text += f"prior: {prior}, "
    return text + f"source: {yaml.safe_dump(source, width=100000, default_style=chr(34), allow_unicode=True).strip()}}}"


def _copied_block(shipped: dict, block: str, indent: str = "  ") -> list[str]:
    """A block of the shipped apc_8x8 file, key by key with its sources marked as copied."""
    lines = []
    for key, item in shipped[block].items():
        if isinstance(item, dict) and "source" in item:
            item = {**item, "source": f"copied from apc_8x8 (its strut and wheel bay; replace with yours): {item['source']}"}
        lines.append(indent + yaml.safe_dump({key: item}, default_flow_style=True, width=100000, allow_unicode=True,
                                             sort_keys=False).strip()[1:-1])
    return lines


def _resolved(s: VehicleSpec, n: int, D: dict) -> dict:
    """Every number of the file (SI), from the spec or the labelled defaults, and where each came from."""
    loads = per_axle(s.axle_loads_N, n, "axle_loads") if s.axle_loads_N is not None else \
        loads_from_mass(s.positions_m, s.total_mass_kg, s.cg_x_m)
    struts = s.struts if len(s.struts) == n else (list(s.struts) * n if len(s.struts) == 1 else None)
    if struts is None:
        raise UserInputError(f"struts: give one strut or one per axle ({n}), got {len(s.struts)}")
    strokes = [load_strut(name).geometry.stroke for name in struts]
    x_static = s.strut_deflection_m if s.strut_deflection_m is not None else D["deflection_fraction"][0] * min(strokes)
    if not 0.0 < x_static < min(strokes):
        raise UserInputError(f"strut_deflection: {x_static * 1e3:.4g} mm must lie inside the stroke (0, "
                             f"{min(strokes) * 1e3:.4g}) mm of every strut")
    wheel = [0.5 * L for L in loads]
    m_u = per_axle(s.unsprung_masses_kg, n, "unsprung_mass") if s.unsprung_masses_kg is not None else \
        [D["unsprung_fraction"][0] * sum(wheel) / len(wheel) / GRAVITY] * n
    if any(m * GRAVITY >= w for m, w in zip(m_u, wheel)):
        raise UserInputError(f"unsprung_mass: {m_u} kg per wheel station must weigh less than the wheel loads "
                             f"{[round(w / GRAVITY) for w in wheel]} kg")
    R = s.tyre_radius_m if s.tyre_radius_m is not None else D["tyre_radius"][0]
    k_tyre = max(wheel) / D["tyre_static_deflection"][0]
    h_cg = s.cg_height_m if s.cg_height_m is not None else D["cg_height_per_tyre_radius"][0] * R
    sprung = sum(loads) / GRAVITY - 2 * sum(m_u)
    cg_x = sum((2 * w - 2 * m * GRAVITY) * x for w, m, x in zip(wheel, m_u, s.positions_m)) / \
        sum(2 * w - 2 * m * GRAVITY for w, m in zip(wheel, m_u))
    over = D["hull_overhang"][0]
    length = s.positions_m[-1] + 2 * over
    return {"n": n, "loads": loads, "wheel": wheel, "struts": struts, "strokes": strokes, "x_static": x_static,
            "m_u": m_u, "R": R, "k_tyre": k_tyre, "c_tyre": 2 * D["tyre_damping_ratio"][0] * math.sqrt(k_tyre * max(m_u)),
            "h_cg": h_cg, "sprung": sprung, "cg_x": cg_x, "overhang": over, "length": length,
            "I_pitch": sprung * (length ** 2 + h_cg ** 2) / 12.0, "I_roll": sprung * (s.track_m ** 2 + h_cg ** 2) / 12.0,
            "r": per_axle(s.motion_ratios, n, "motion_ratio") if s.motion_ratios is not None else
            [D["motion_ratio"][0]] * n,
            "T": s.charging_temperature_K if s.charging_temperature_K is not None else D["charging_temperature"][0]}


def strut_reference_from(strut: str, folder: Path | None) -> str:
    """A strut as the vehicle file names it: a built-in name as given; a strut file by its path from `folder`
    (the vehicle file's folder, which its loader reads strut paths from), the path as given without one."""
    if not strut.endswith((".yaml", ".yml")):
        return strut
    if folder is not None:
        strut = os.path.relpath(Path(strut).expanduser().resolve(), Path(folder).resolve())
    return "{file: " + yaml.safe_dump(strut, default_style='"', width=100000).strip() + "}"


def _axle_lines(s: VehicleSpec, V: dict, D: dict, folder: Path | None) -> list[str]:
    lines = ["axles:"]
    given_r, given_mu = s.motion_ratios is not None, s.unsprung_masses_kg is not None
    for k in range(V["n"]):
        pos = _q(f"{s.positions_m[k]:.6g} m", "given (hpsim vehicle new)" if k else "axle 1: the datum of the positions")
        mu = _q(f"{V['m_u'][k]:.4g} kg", "given" if given_mu else f"default: {D['unsprung_fraction'][1]} "
                f"({D['unsprung_fraction'][0]:g} of the mean static wheel load)")
        r = f"{{value: {V['r'][k]:.4g}, source: " + yaml.safe_dump(
            "given" if given_r else f"default: {D['motion_ratio'][1]}", default_style='"', width=100000).strip() + "}"
        strut_ref = strut_reference_from(V["struts"][k], folder)
        lines += [f"  - {{position: {pos}, strut: {strut_ref},", f"     unsprung_mass: {mu}, motion_ratio: {r}}}"]
    return lines


def vehicle_text(s: VehicleSpec, folder: str | Path | None = None) -> str:
    """The vehicle file's text (YAML with comments) for the spec; see the module doc. folder: where the file
    will be written (strut files are named by their path from there); None: strut paths as given."""
    n = _check_spec(s)
    D = template_defaults()
    V = _resolved(s, n, D)
    shipped = load_yaml(vehicle_file("apc_8x8"))

    def src(given: bool, key: str, extra: str = "") -> str:
        return "given" if given else f"default: {D[key][1]}{extra}"

    wheel_daN = ", ".join('"%.6g daN"' % (w / 10) for w in V["wheel"])
    heights = ", ".join('"%.6g mm"' % (h * 1e3) for h in per_axle(s.ride_heights_m, n, "ride_height"))
    loads_src = "given (axle loads / 2)" if s.axle_loads_N is not None else \
        "given mass and CG: a rigid hull on equal springs (vehicle.physics.vehicle_builder)"
    description = s.description or f"{n}-axle vehicle written by hpsim vehicle new"
    seat = (f"{{name: driver, x_from_cg: {_q('%.4g m' % -V['cg_x'], 'default: above axle 1')}, "
            f"y_from_cg: {_q('%.4g m' % (0.25 * s.track_m), 'default: a quarter track left of the centre line')}, "
            f"z_from_cg: {_q('%.3g m' % D['seat_height_above_cg'][0], src(False, 'seat_height_above_cg'))}}}")
    lines = [
        f"# {s.name}: written by `hpsim vehicle new` (docs/vehicles.md). Every value says where it comes from:",
        "# 'given' (the command line), 'default: ...' (vehicle/data/templates/new_vehicle.yaml) or 'copied from",
        "# apc_8x8' (its strut and wheel bay). Replace the defaults with your data; `hpsim vehicle check` this file.",
        f"name: {s.name}",
        "description: " + yaml.safe_dump(description, default_style='"', width=100000).strip(),
        f"track: {_q('%.6g m' % s.track_m, 'given')}",
    ] + _axle_lines(s, V, D, None if folder is None else Path(folder)) + [
        "hull:",
        f"  # mass and cg_x left out: derived from charging.wheel_loads ({V['sprung']:.6g} kg sprung, CG "
        f"{V['cg_x']:.4g} m behind axle 1)",
        f"  cg_height: {_q('%.4g m' % V['h_cg'], src(s.cg_height_m is not None, 'cg_height_per_tyre_radius'))}",
        f"  pitch_inertia: {_q('%.4g kg*m^2' % V['I_pitch'], 'default: a uniform box of the sprung mass, hull length (wheelbase + 2 hull overhangs) x cg_height')}",
        f"  roll_inertia: {_q('%.4g kg*m^2' % V['I_roll'], 'default: a uniform box of the sprung mass, track x cg_height')}",
        f"  front_overhang: {_q('%.4g m' % V['overhang'], src(False, 'hull_overhang'))}",
        f"  rear_overhang: {_q('%.4g m' % V['overhang'], src(False, 'hull_overhang'))}",
        f"  width: {_q('%.4g m' % s.track_m, 'default: the track')}",
        f"  height: {_q('%.4g m' % (2 * V['h_cg']), 'default: twice the CG height')}",
        "tyre:",
        f"  radius: {_q('%.4g m' % V['R'], src(s.tyre_radius_m is not None, 'tyre_radius'))}",
        f"  stiffness: {_q('%.4g MN/m' % (V['k_tyre'] / 1e6), src(False, 'tyre_static_deflection', ' (%.3g mm under the heaviest wheel load)' % (D['tyre_static_deflection'][0] * 1e3)))}",
        f"  damping: {_q('%.4g kN*s/m' % (V['c_tyre'] / 1e3), src(False, 'tyre_damping_ratio', ' (%g on the heaviest unsprung mass)' % D['tyre_damping_ratio'][0]))}",
        f"  contact_length: {_q('%.3g m' % D['tyre_contact_length'][0], src(False, 'tyre_contact_length'))}",
        "heat:",
        "  # the strut heat network and the wheel-bay heat environment (docs/physics.md), copied from apc_8x8:",
        "  # its air_speed_ratio is calibrated for the seed-000 strut in an 8x8 wheel bay",
    ] + _copied_block(shipped, "heat") + ["longitudinal:"] + _copied_block(shipped, "longitudinal") + [
        "compensation:"] + _copied_block(shipped, "compensation") + [
        "charging:",
        "  # load_and_height: each strut's gas mass is set so that it carries its wheel load at strut_deflection",
        "  # at the charging temperature: the vehicle stands at these loads and heights (docs/vehicles.md)",
        '  method: {value: load_and_height, source: "hpsim vehicle new: charged to stand at the given loads and heights"}',
        f'  wheel_loads: {{value: [{wheel_daN}], source: "{loads_src}"}}',
        f'  heights: {{value: [{heights}], source: "given (ride height)"}}',
        f"  temperature: {_q('%.4g degC' % (V['T'] - 273.15), src(s.charging_temperature_K is not None, 'charging_temperature'))}",
        f"  strut_deflection: {_q('%.4g mm' % (V['x_static'] * 1e3), src(s.strut_deflection_m is not None, 'deflection_fraction', ' (%g of the shortest stroke)' % D['deflection_fraction'][0]))}",
        "seats:",
        f"  - {seat}",
    ]
    return "\n".join(lines) + "\n"


def built_vehicle(s: VehicleSpec, path: str | Path) -> tuple[str, VehicleParams]:
    """The text of the vehicle file for the spec as it will be written to `path` (.yaml), and the parameters
    its loader will read from it (strut paths from the file's folder); nothing is written."""
    p = Path(path)
    if p.suffix not in (".yaml", ".yml"):
        raise UserInputError(f"-o/--output: a vehicle file ends in .yaml, got {p}")
    text = vehicle_text(s, p.parent)
    data = parse_yaml(text, str(p))
    return text, validate(VehicleParams, with_strut_paths(data, p.parent.resolve()), str(p))


def write_text(path: str | Path, text: str, overwrite: bool = False, inputs=()) -> Path:
    """Write a vehicle file's text to `path` through hpsim.outputs: never over one of its `inputs` (its strut
    files), over an existing file only with `overwrite`, whole or not at all."""
    p = Path(path)
    check_output_file(p, "-o/--output", make_parents=True, inputs=inputs, overwrite=overwrite)
    with atomic_output(p) as tmp:
        tmp.write_text(text)
    return p


def write_vehicle(s: VehicleSpec, path: str | Path, overwrite: bool = False) -> Path:
    """Write the vehicle file for the spec to `path` (.yaml) when it passes the statics of `hpsim vehicle
    check`; a vehicle that does not (it could not be driven) is refused and nothing is written."""
    from vehicle.physics.vehicle_check import check_vehicle

    text, P = built_vehicle(s, path)
    check_output_file(Path(path), "-o/--output", make_parents=True, inputs=s.struts, overwrite=overwrite)
    rep = check_vehicle(P, str(path), modes=False, shipped=None)
    if rep.errors:
        raise UserInputError(f"{path}: not written: the vehicle fails its check: "
                             + "; ".join(str(f) for f in rep.errors))
    return write_text(path, text, overwrite, inputs=s.struts)


def _quantities(value, unit: str, where: str) -> list[float]:
    """A quantity, a list of them or a comma-separated string ("0m,3.5m") -> SI floats."""
    items = value.split(",") if isinstance(value, str) else (value if isinstance(value, (list, tuple)) else [value])
    items = [v for v in items if not (isinstance(v, str) and not v.strip())]
    if not items:
        raise UserInputError(f"{where}: expected one or more quantities in {unit or 'plain numbers'}")
    return [parse_quantity(v, unit, where=where) for v in items]


def _loads(value, where: str = "axle_loads") -> list[float]:
    """Axle loads as masses (t, kg: times standard gravity) or forces (N, kN, daN) -> N."""
    out = []
    for v in (value.split(",") if isinstance(value, str) else (value if isinstance(value, (list, tuple)) else [value])):
        try:
            out.append(parse_quantity(v, "kg", where=where) * GRAVITY)
        except UserInputError:
            out.append(parse_quantity(v, "N", where=f"{where} (a mass or a force)"))
    return out


def spec_from_values(name: str, *, positions, track, ride_height, axle_loads=None, mass=None, cg_x=None,
                     struts="apc", strut_deflection=None, motion_ratio=None, unsprung_mass=None, tyre_radius=None,
                     cg_height=None, charging_temperature=None, description: str = "") -> VehicleSpec:
    """A VehicleSpec from quantities with units (strings), SI numbers or lists/comma-separated strings of them
    (the command line's and the Python API's values; the option names of `hpsim vehicle new`)."""
    import re

    if not re.fullmatch(r"[A-Za-z0-9_.-]{1,80}", str(name)):
        raise UserInputError(f"name: letters, digits, '_', '.', '-' (1-80), got {name!r}")

    def one(value, unit, where):
        return None if value is None else parse_quantity(value, unit, where=where)

    def many(value, unit, where):
        return None if value is None else _quantities(value, unit, where)

    strut_list = [t.strip() for t in struts.split(",")] if isinstance(struts, str) else [str(t) for t in struts]
    return VehicleSpec(
        name=str(name), positions_m=_quantities(positions, "m", "positions"), track_m=one(track, "m", "track"),
        ride_heights_m=_quantities(ride_height, "m", "ride_height"), struts=[t for t in strut_list if t],
        axle_loads_N=None if axle_loads is None else _loads(axle_loads), total_mass_kg=one(mass, "kg", "mass"),
        cg_x_m=one(cg_x, "m", "cg_x"), strut_deflection_m=one(strut_deflection, "m", "strut_deflection"),
        motion_ratios=many(motion_ratio, "", "motion_ratio"), unsprung_masses_kg=many(unsprung_mass, "kg", "unsprung_mass"),
        tyre_radius_m=one(tyre_radius, "m", "tyre_radius"), cg_height_m=one(cg_height, "m", "cg_height"),
        charging_temperature_K=one(charging_temperature, "K", "charging_temperature"), description=description)
