"""`hpsim vehicle check`: is a vehicle file consistent, can the vehicle stand, what are its ride modes.

`check_vehicle(params)` looks at a validated vehicle (`vehicle.physics.params.VehicleParams`; schema errors
are the loader's, exit code 2) the way a suspension engineer would before a drive (docs/vehicles.md
"Checking a vehicle"):

- keys left out and the default each took (`defaults_left_out`), marked where the default differs from
  the value the shipped apc_8x8 file gives (calibrated or sourced there);
- masses against the wheel loads: a hull mass or CG that contradicts `charging.wheel_loads` is an error
  naming the key (the charged pose would not be an equilibrium: vehicle.physics.equilibrium);
- the standing vehicle at the charging temperature, at -30 degC and hot (+60 K): per wheel station the
  static load, the strut deflection and its margins to both end stops, the gas pressure at rest and at
  full bump (compressed from rest to the end of the stroke by the strut's polytropic law, seed 000 eq. 5),
  judged against the strut file's `limits.rated_static_pressure` / `rated_peak_pressure`;
- the standing vehicle's roll stability at the charging temperature: its roll stiffness against the
  overturning moment of its sprung weight, the static stability factor and the rollover threshold
  (`roll_stability`);
- the linearised modes (vehicle.physics.linear, seal friction equivalent linear at 100 mm/s): bounce,
  pitch, roll and wheel hop with frequency and damping ratio;
- warnings at the thresholds of `THRESHOLDS`, each naming the key to look at.

Errors mean the vehicle cannot be driven as written (the drive is refused); warnings mean a drive runs
but an engineer would look twice. `pre_drive_check` is the quiet version run before every drive (no
modes: the statics take 0.03 s of CPU for the apc_8x8, the linearisation 0.3 s more, and the modes'
findings are design remarks, not reasons to stop a drive or to repeat at every drive of a sweep).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from pydantic import BaseModel

from hpsim.errors import UserInputError

from vehicle.physics import linear
from vehicle.physics.equilibrium import charge_gas_masses, equilibrium_solver
from vehicle.physics.model import VehicleModel
from vehicle.physics.params import GRAVITY, VehicleParams, load_vehicle, vehicle_file

# Warning thresholds (docs/vehicles.md "Checking a vehicle"; what a suspension engineer flags):
THRESHOLDS = {
    # a standing strut this close (share of its stroke) to an end stop tops or bottoms out on ordinary bumps
    "stop_margin_fraction": 0.15,
    # body modes below 0.7 Hz make people seasick (ISO 2631-1 motion sickness band 0.1-0.5 Hz reaches up)
    # and need a very long travel; road vehicles sit at 0.8-1.5 Hz (Gillespie 1992 §6)
    "min_mode_hz": 0.7,
    # bounce and pitch closer than 10 %: any coupling (CG off the elastic centre) mixes them into one motion;
    # on purpose in a flat-ride design (Olley's dynamic index k^2/(a b) near 1, Gillespie 1992 §6), else a
    # sign of a guessed pitch inertia
    "bounce_pitch_separation": 0.10,
    # wheel hop above 15 Hz: a tyre far stiffer than a pneumatic tyre (usual 8-12 Hz), check the tyre data
    "max_wheel_hop_hz": 15.0,
    # motion ratio (strut travel / wheel travel) outside 0.4-1.2: implausible linkage, or a typo
    "motion_ratio": (0.4, 1.2),
    # masses against wheel loads: the tolerance of the charged pose's equilibrium (vehicle.physics.equilibrium)
    "mass_tolerance": 5e-3,
    # quasi-static rollover threshold [g] below which a vehicle tips on a steady turn or a side slope: the
    # static rollover threshold a heavy vehicle must hold (0.35 g, Australian Performance-Based Standards,
    # NTC 2008); laden heavy trucks lie at 0.35-0.5 g (Winkler and Ervin 1999, UMTRI-99-19)
    "min_rollover_threshold_g": 0.35,
}
COLD_K = 273.15 - 30.0       # the cold case: -30 degC (the usual low limit of NBR seals, struts/data/*.yaml)
HOT_RISE_K = 60.0            # the hot case: +60 K (the mileage test's struts rose 54 K: docs/validation.md)
FRICTION_VELOCITY_M_S = 0.1  # equivalent-linear seal friction of the modes (as `hpsim vehicle response`)
# the hull outline when the vehicle file gives none (docs/vehicles.md "hull"): over the wheels fore and aft,
# as wide as the wheel track, the roof twice the CG height (a body of uniform density stands on its wheels)
OUTLINE_DEFAULTS = {"front_overhang": "the tyre radius", "rear_overhang": "the tyre radius",
                    "width": "the track", "height": "2 x hull.cg_height"}


@dataclass
class Finding:
    level: str          # "error" or "warning"
    key: str            # the vehicle-file key to look at
    message: str
    drive: bool = True  # repeated before every drive (False: a design remark of `hpsim vehicle check` only)

    def as_dict(self) -> dict:
        return {"level": self.level, "key": self.key, "message": self.message}

    def __str__(self) -> str:
        return f"{self.key}: {self.message}"


@dataclass
class CheckReport:
    vehicle: str
    source: str
    findings: list[Finding] = field(default_factory=list)
    defaults: list[dict] = field(default_factory=list)
    mass: dict = field(default_factory=dict)
    cases: list[dict] = field(default_factory=list)       # standing vehicle per temperature case
    modes: list[dict] = field(default_factory=list)
    mode_summary: dict = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    roll: dict = field(default_factory=dict)              # static roll stability (roll_stability)

    @property
    def errors(self) -> list[Finding]:
        return [f for f in self.findings if f.level == "error"]

    @property
    def warnings(self) -> list[Finding]:
        return [f for f in self.findings if f.level == "warning"]

    @property
    def ok(self) -> bool:
        return not self.errors

    def add(self, level: str, key: str, message: str, drive: bool = True) -> None:
        self.findings.append(Finding(level, key, message, drive))

    def as_dict(self) -> dict:
        return {"vehicle": self.vehicle, "source": self.source, "ok": self.ok,
                "errors": [f.as_dict() for f in self.errors], "warnings": [f.as_dict() for f in self.warnings],
                "defaults": self.defaults, "mass": self.mass, "standing": self.cases, "roll_stability": self.roll,
                "modes": self.modes,
                "mode_summary": self.mode_summary, "notes": self.notes, "thresholds": THRESHOLDS}


# --- keys left out -----------------------------------------------------------------------------------
def _field_unit(model_cls, name: str) -> str:
    """The SI unit a field is declared in (hpsim.config.Quantity), "" for plain numbers and text."""
    for meta in model_cls.model_fields[name].metadata:
        fn = getattr(meta, "func", None)
        if fn is not None and fn.__closure__:
            cells = dict(zip(fn.__code__.co_freevars, (c.cell_contents for c in fn.__closure__)))
            if isinstance(cells.get("unit"), str):
                return cells["unit"]
    return ""


def defaults_left_out(model: BaseModel, path: str = "") -> list[dict]:
    """Every key of `model` the file left out that took a default (not None), with its value and unit; nested
    blocks left out entirely are listed key by key."""
    out = []
    cls = type(model)
    for name, info in cls.model_fields.items():
        value = getattr(model, name)
        key = f"{path}.{name}" if path else name
        if name not in model.model_fields_set:
            if isinstance(value, BaseModel):
                out += _all_fields(value, key)
            elif value is not None and not info.is_required() and value not in ({}, [], ""):
                out.append({"key": key, "value": value, "unit": _field_unit(cls, name)})
            continue
        if isinstance(value, BaseModel):
            out += defaults_left_out(value, key)
        elif isinstance(value, list):
            for k, item in enumerate(value):
                if isinstance(item, BaseModel):
                    out += defaults_left_out(item, f"{key}.{k}")
    return out


def _all_fields(model: BaseModel, path: str) -> list[dict]:
    cls = type(model)
    out = []
    for name in cls.model_fields:
        value = getattr(model, name)
        if isinstance(value, BaseModel):
            out += _all_fields(value, f"{path}.{name}")
        elif value is not None and value not in ({}, [], ""):
            out.append({"key": f"{path}.{name}", "value": value, "unit": _field_unit(cls, name)})
    return out


def _value_at(model, dotted: str):
    obj = model
    for part in dotted.split("."):
        if part.isdigit():
            items = obj if isinstance(obj, list) else []
            if int(part) >= len(items):
                return None
            obj = items[int(part)]
        elif isinstance(obj, BaseModel) and part in type(obj).model_fields:
            if part not in obj.model_fields_set:
                return None
            obj = getattr(obj, part)
        else:
            return None
    return obj


def mark_shipped_differences(defaults: list[dict], shipped: VehicleParams) -> None:
    """Mark each default that differs from the value the shipped vehicle's file gives for the same key."""
    for d in defaults:
        given = _value_at(shipped, d["key"])
        if isinstance(given, (int, float)) and isinstance(d["value"], (int, float)) and \
                not math.isclose(float(given), float(d["value"]), rel_tol=1e-9):
            d["shipped"] = {"vehicle": shipped.name, "value": given}


# --- masses ------------------------------------------------------------------------------------------
def check_masses(P: VehicleParams, rep: CheckReport) -> None:
    """Hull mass and CG against the charging wheel loads (weight and moment balance of the charged pose)."""
    tol = THRESHOLDS["mass_tolerance"]
    loads = np.repeat(np.asarray(P.charging.wheel_loads, float), 2)
    W_loads = float(loads.sum())
    m_u = P.unsprung_mass_total()
    sprung_from_loads = W_loads / GRAVITY - m_u
    x = np.repeat([a.position for a in P.axles], 2)
    y = np.array([P.station_y(i) for i in range(P.n_stations)])
    Fs = loads - np.repeat([a.unsprung_mass for a in P.axles], 2) * GRAVITY     # sprung load per station
    cg_x_loads = float(Fs @ x / Fs.sum()) if Fs.sum() > 0 else float("nan")
    cg_y_loads = float(Fs @ y / Fs.sum()) if Fs.sum() > 0 else float("nan")
    rep.mass = {"wheel_loads_total_kg": W_loads / GRAVITY, "unsprung_total_kg": m_u,
                "sprung_from_loads_kg": sprung_from_loads, "cg_x_from_loads_m": cg_x_loads,
                "sprung_kg": P.sprung_mass(), "sprung_cg_x_m": P.sprung_cg_x(),
                "hull_mass_given": P.hull.mass is not None, "hull_cg_x_given": P.hull.cg_x is not None}
    if sprung_from_loads <= 0:
        rep.add("error", "charging.wheel_loads", f"the wheel loads ({W_loads / GRAVITY:.6g} kg in all) do not even "
                f"carry the unsprung masses ({m_u:.6g} kg)")
        return
    if P.hull.mass is not None and abs(P.hull.mass - sprung_from_loads) > tol * W_loads / GRAVITY:
        total = P.hull.mass + m_u
        rep.add("error", "hull.mass", f"{P.hull.mass:.6g} kg sprung + {m_u:.6g} kg unsprung = {total:.6g} kg, but "
                f"charging.wheel_loads add up to {W_loads / GRAVITY:.6g} kg ({100 * (total * GRAVITY / W_loads - 1):+.2f} %, "
                f"allowed {100 * tol:.1f} %): give loads that match, or leave hull.mass out to derive it "
                f"({sprung_from_loads:.6g} kg)")
    if P.hull.cg_x is not None and abs(P.hull.cg_x - cg_x_loads) * P.sprung_mass() * GRAVITY > tol * W_loads * 1.0:
        rep.add("error", "hull.cg_x", f"{P.hull.cg_x:.4g} m behind axle 1, but charging.wheel_loads put the sprung CG "
                f"at {cg_x_loads:.4g} m: give loads that match, or leave hull.cg_x out to derive it")
    if abs(P.hull.cg_y - cg_y_loads) * P.sprung_mass() * GRAVITY > tol * W_loads * 1.0:
        rep.add("error", "hull.cg_y", f"{P.hull.cg_y:.4g} m left of the centre line, but the wheel loads (left = "
                f"right) put it at {cg_y_loads:.4g} m")


# --- geometry ----------------------------------------------------------------------------------------
def hull_outline(P: VehicleParams) -> dict:
    """The hull's outline [m]: x from axle 1 (+ rearward), y from the centre line, z above the ground; the
    vehicle file's hull.front_overhang / rear_overhang / width / height or the OUTLINE_DEFAULTS."""
    H = P.hull
    R = max(float(P.axle_tyre(k).radius) for k in range(P.n_axles))
    front = H.front_overhang if H.front_overhang is not None else R
    rear = H.rear_overhang if H.rear_overhang is not None else R
    width = H.width if H.width is not None else P.track
    height = H.height if H.height is not None else 2.0 * H.cg_height
    return {"x_min": -front, "x_max": P.axles[-1].position + rear, "half_width": 0.5 * width, "height": height,
            "defaulted": [k for k in OUTLINE_DEFAULTS if getattr(H, k) is None]}


def check_geometry(P: VehicleParams, rep: CheckReport) -> None:
    lo, hi = THRESHOLDS["motion_ratio"]
    for k, axle in enumerate(P.axles):
        if not lo <= axle.motion_ratio <= hi:
            rep.add("warning", f"axles.{k}.motion_ratio", f"{axle.motion_ratio:g} is outside {lo:g}-{hi:g} "
                    "(strut travel per wheel travel): an unusual linkage, or a typo")
    box = hull_outline(P)
    cg_x = P.sprung_cg_x()
    for j, seat in enumerate(P.seats):
        x, y, z = cg_x + seat.x_from_cg, P.hull.cg_y + seat.y_from_cg, P.hull.cg_height + seat.z_from_cg
        where = []
        if not box["x_min"] <= x <= box["x_max"]:
            where.append(f"x {x:+.3g} m from axle 1 (hull {box['x_min']:+.3g} to {box['x_max']:+.3g} m)")
        if abs(y) > box["half_width"]:
            where.append(f"y {y:+.3g} m (hull +-{box['half_width']:.3g} m)")
        if not 0.0 < z <= box["height"]:
            where.append(f"z {z:.3g} m above the ground (hull up to {box['height']:.3g} m)")
        if where:
            rep.add("warning", f"seats.{j}", f"seat {seat.name!r} lies outside the hull: {', '.join(where)}"
                    + (f" (outline from defaults: {', '.join('hull.' + k for k in box['defaulted'])})"
                       if box["defaulted"] else ""))


# --- the standing vehicle --------------------------------------------------------------------------
def temperature_cases(P: VehicleParams) -> list[tuple[str, float]]:
    """(name, strut temperature [K]) of the standing cases: at charging, cold (-30 degC), hot (+60 K)."""
    T0 = P.charging.temperature
    return [("charging", T0), ("cold", COLD_K), ("hot", T0 + HOT_RISE_K)]


def full_bump_pressure(strut, x_rest_m: float, p_rest_Pa: float, T_K: float) -> float:
    """Gas pressure [Pa] with the strut compressed from rest (x_rest, p_rest) to the end of its stroke by its
    polytropic law p V^n = const (seed 000 eq. 5; n = gas.polytropic_exponent): a quick full bump."""
    V_rest = float(strut.gas_volume(x_rest_m, T_K))
    V_bump = float(strut.gas_volume(strut.p.geometry.stroke, T_K))
    if V_bump <= 0.0:
        return float("inf")
    return p_rest_Pa * (V_rest / V_bump) ** strut.p.gas.polytropic_exponent


def _station_rows(model: VehicleModel, eq, T_K: float) -> list[dict]:
    rows = []
    for i in range(model.n):
        strut = model.struts[i]
        stroke = float(strut.p.geometry.stroke)
        x = float(eq.strut_deflections_m[i])
        p = float(eq.gas_pressures_Pa[i])
        rows.append({"station": model.station_names[i], "axle": i // 2 + 1, "strut": strut.p.name,
                     "wheel_load_N": float(eq.wheel_loads_N[i]), "deflection_mm": 1e3 * x,
                     "stroke_mm": 1e3 * stroke, "margin_extension_mm": 1e3 * x,
                     "margin_bump_mm": 1e3 * (stroke - x), "pressure_rest_MPa": p / 1e6,
                     "pressure_full_bump_MPa": full_bump_pressure(strut, x, p, T_K) / 1e6})
    return rows


# --- static roll stability ----------------------------------------------------------------------------
def wheel_rate_N_m(strut_rate_N_m, motion_ratio, tyre_rate_N_m):
    """Vertical rate of a wheel station on the ground [N/m]: the strut's rate seen at the wheel (k r^2, r strut
    travel per wheel travel, by virtual work) in series with the tyre (Gillespie 1992 §5, ride rate)."""
    k_w = strut_rate_N_m * motion_ratio ** 2
    return k_w * tyre_rate_N_m / (k_w + tyre_rate_N_m)


def roll_stiffness_N_m_per_rad(wheel_rates_N_m, lateral_positions_m) -> float:
    """Roll stiffness of the standing vehicle [N m/rad]: sum_i k_i y_i^2 over the wheel stations (springs at
    their lateral positions y_i, small roll angles; Gillespie 1992 §7, roll rate)."""
    k, y = np.asarray(wheel_rates_N_m, float), np.asarray(lateral_positions_m, float)
    return float(np.sum(k * y ** 2))


def rollover_threshold_g(track_m: float, cg_height_m: float, roll_stiffness: float, mass_kg: float) -> float:
    """Quasi-static rollover threshold [g] of a vehicle rolling on its suspension about an axis at the ground.

    It is the static stability factor t / (2 h) times (1 - m g h / K_phi), the CG's lateral shift as the body rolls
    (moment balance about the outer wheels: a_y h = g (t/2 - h phi), phi = m a_y h / (K_phi - m g h);
    Gillespie 1992 §9). Zero or less: the vehicle cannot stand upright on its springs."""
    return track_m / (2.0 * cg_height_m) * (1.0 - mass_kg * GRAVITY * cg_height_m / roll_stiffness)


def strut_rate_N_m(strut, x_m: float, T_K: float, gas_mass_kg: float, step_m: float = 1e-4) -> float:
    """Standing rate of a strut [N/m] at deflection x_m: the slope of its standing gas force (the strut
    file's static gas law) by a central difference of step_m."""
    F = lambda x: float(strut.static_gas_force(x, T_K, gas_mass_kg))   # noqa: E731
    return (F(x_m + step_m) - F(x_m - step_m)) / (2.0 * step_m)


def check_roll_stability(P: VehicleParams, model: VehicleModel, eq, masses, rep: CheckReport) -> None:
    """The standing vehicle at the charging temperature in roll (the functions above): an error when its roll
    stiffness does not exceed the overturning moment of its sprung weight (m g h per radian of roll, the roll
    axis at the ground), a warning when the rollover threshold lies below THRESHOLDS' minimum."""
    T = P.charging.temperature
    k_wheel = [wheel_rate_N_m(strut_rate_N_m(model.struts[i], float(eq.strut_deflections_m[i]), T, float(masses[i])),
                              P.axles[i // 2].motion_ratio, P.axle_tyre(i // 2).stiffness) for i in range(model.n)]
    K = roll_stiffness_N_m_per_rad(k_wheel, [P.station_y(i) for i in range(model.n)])
    m, h = P.sprung_mass(), P.hull.cg_height
    overturning = m * GRAVITY * h
    ssf = P.track / (2.0 * h)
    threshold = rollover_threshold_g(P.track, h, K, m)
    rep.roll = {"roll_stiffness_kNm_per_rad": K / 1e3, "overturning_kNm_per_rad": overturning / 1e3,
                "roll_stiffness_margin": K / overturning, "static_stability_factor": ssf,
                "tip_over_angle_deg": math.degrees(math.atan(ssf)), "rollover_threshold_g": threshold}
    if K <= overturning:
        rep.add("error", "track", f"the standing vehicle falls over on its springs: its roll stiffness "
                f"{K / 1e3:.4g} kN m/rad (wheel rates at +-track/2 = {P.track / 2:.3g} m) does not exceed the "
                f"overturning moment of its sprung weight at hull.cg_height, m g h = {overturning / 1e3:.4g} kN m/rad; "
                "a wider track, stiffer struts or a lower CG")
        return
    lowest = THRESHOLDS["min_rollover_threshold_g"]
    if threshold < lowest:
        rep.add("warning", "track", f"rollover threshold {threshold:.2f} g (static stability factor t/2h = {ssf:.2f}, "
                f"less {100 * overturning / K:.0f} % for the body's roll on its springs), below {lowest:g} g: the "
                "vehicle tips on a steady turn or a side slope a heavy vehicle must hold (track, hull.cg_height)")


def check_standing(P: VehicleParams, rep: CheckReport, model: VehicleModel | None = None) -> VehicleModel | None:
    """Charge the struts and stand the vehicle at the three temperature cases (see the module doc)."""
    try:
        model = model or VehicleModel(P)
        masses = charge_gas_masses(model)
    except UserInputError as exc:
        rep.add("error", "charging", str(exc))
        return None
    solver = equilibrium_solver(model)
    margin = THRESHOLDS["stop_margin_fraction"]
    for name, T in temperature_cases(P):
        try:
            eq = solver.solve(T, masses)
        except UserInputError as exc:
            level = "error" if name == "charging" else "warning"
            rep.add(level, "charging.strut_deflection", f"at {T - 273.15:.1f} degC ({name}): {exc}")
            rep.cases.append({"case": name, "temperature_degC": T - 273.15, "stands": False, "stations": []})
            continue
        rows = _station_rows(model, eq, T)
        if name == "charging":
            check_roll_stability(P, model, eq, masses, rep)
        rep.cases.append({"case": name, "temperature_degC": T - 273.15, "stands": True,
                          "axle_height_change_mm": (1e3 * eq.axle_height_change_m).tolist(), "stations": rows})
        for k in range(P.n_axles):
            for row in rows[2 * k: 2 * k + 2]:
                low = min(row["margin_extension_mm"], row["margin_bump_mm"])
                if low < margin * row["stroke_mm"]:
                    stop = "full extension" if row["margin_extension_mm"] < row["margin_bump_mm"] else "the bump stop"
                    where = f"stands {low:.3g} mm from {stop}" if low > 0 else f"sits on {stop} ({-low:.3g} mm into it)"
                    rep.add("warning", "charging.strut_deflection" if name == "charging" else "charging.temperature",
                            f"{row['station']} ({row['strut']}) {where} at {T - 273.15:.1f} degC ({name}): less than "
                            f"{100 * margin:.0f} % of its {row['stroke_mm']:.4g} mm stroke")
                    break
    _check_pressures(P, model, rep)
    return model


def _check_pressures(P: VehicleParams, model: VehicleModel, rep: CheckReport) -> None:
    """Static and full-bump pressures at the charging temperature, and the full-bump pressures of the cold and
    hot cases (a hot strut's oil has expanded into its gas volume), against the strut file's ratings."""
    unrated = set()
    for case in (c for c in rep.cases if c["stands"]):
        charging = case["case"] == "charging"
        over = []                     # (axle, full-bump pressure, rated peak) above the rating in this case
        for k in range(P.n_axles):
            rows = case["stations"][2 * k: 2 * k + 2]
            limits = model.struts[2 * k].p.limits
            name = model.struts[2 * k].p.name
            p_rest = max(r["pressure_rest_MPa"] for r in rows) * 1e6
            p_bump = max(r["pressure_full_bump_MPa"] for r in rows) * 1e6
            if limits.rated_static_pressure is None and limits.rated_peak_pressure is None:
                unrated.add(name)
                continue
            peak, static = limits.rated_peak_pressure, limits.rated_static_pressure
            if charging and peak is not None and p_rest > peak:
                rep.add("error", f"axles.{k}.strut", f"strut {name} is too small for axle {k + 1}: it stands at "
                        f"{p_rest / 1e6:.3g} MPa, above even its rated peak {peak / 1e6:.3g} MPa "
                        "(limits.rated_peak_pressure); a larger strut or a larger motion ratio")
                continue
            if charging and static is not None and p_rest > static:
                rep.add("warning", f"axles.{k}.strut", f"strut {name} on axle {k + 1} stands at {p_rest / 1e6:.3g} "
                        f"MPa, above its rated static pressure {static / 1e6:.3g} MPa (limits.rated_static_pressure)")
            if peak is not None and p_bump > peak:
                over.append((k, p_bump, peak))
        if charging:
            for k, p_bump, peak in over:
                rep.add("warning", f"axles.{k}.strut", f"strut {model.struts[2 * k].p.name} on axle {k + 1} reaches "
                        f"{p_bump / 1e6:.3g} MPa at full bump at {case['temperature_degC']:.1f} degC, above its rated "
                        f"peak {peak / 1e6:.3g} MPa (limits.rated_peak_pressure)")
        elif over:
            worst = max(over, key=lambda o: o[1] / o[2])
            rep.add("warning", "charging.temperature",
                    f"at {case['temperature_degC']:.1f} degC ({case['case']}) the struts of axle(s) "
                    f"{', '.join(str(k + 1) for k, _, _ in over)} reach up to {worst[1] / 1e6:.3g} MPa at full bump, "
                    f"above their rated peak {worst[2] / 1e6:.3g} MPa (limits.rated_peak_pressure): "
                    + ("the oil's expansion has taken gas volume, so a full bump compresses the gas further; "
                       "levelling (compensation) or a lower charge keeps a hot strut off its end stop"
                       if case["temperature_degC"] > case_temperature(rep, "charging") else
                       "the cold gas stands lower in the stroke"), drive=False)
    for name in sorted(unrated):
        rep.notes.append(f"strut {name}: no limits.rated_static_pressure / rated_peak_pressure in its file: "
                         "pressures reported, not judged")


def case_temperature(rep: CheckReport, name: str) -> float:
    """The strut temperature [degC] of a standing case of the report."""
    return next(c["temperature_degC"] for c in rep.cases if c["case"] == name)


# --- modes -----------------------------------------------------------------------------------------
def check_modes(P: VehicleParams, rep: CheckReport) -> None:
    """Linearised modes at the charging temperature (seal friction equivalent linear at 100 mm/s)."""
    try:
        lin = linear.linearise(P, friction_velocity_m_s=FRICTION_VELOCITY_M_S)
    except UserInputError as exc:
        rep.add("error", "charging", f"linearisation: {exc}")
        return
    found = linear.modes(lin)
    rep.modes = [{"name": md.name, "frequency_hz": md.frequency_hz, "damping_ratio": md.damping_ratio}
                 for md in found]
    summary = linear.mode_summary(found)
    rep.mode_summary = {k: ({"frequency_hz": v.frequency_hz, "damping_ratio": v.damping_ratio}
                            if hasattr(v, "frequency_hz") else list(v)) for k, v in summary.items()}
    wheel = [md for md in found if md.name.startswith("wheel")]
    if wheel:
        hop = max(wheel, key=lambda md: md.frequency_hz)
        rep.mode_summary["wheel_hop_highest"] = {"frequency_hz": hop.frequency_hz, "damping_ratio": hop.damping_ratio,
                                         "name": hop.name}
    rep.notes.append(f"modes: linearised at the charging temperature, seal friction equivalent linear at "
                     f"{FRICTION_VELOCITY_M_S * 1e3:.0f} mm/s (hpsim vehicle response for the responses)")
    f_min = THRESHOLDS["min_mode_hz"]
    for md in found:
        if md.frequency_hz < f_min:
            rep.add("warning", _mode_key(md.name), f"the {md.name} mode is at {md.frequency_hz:.3g} Hz, below "
                    f"{f_min:g} Hz: a very soft suspension (motion sickness, long travel)")
    b, p = summary.get("bounce"), summary.get("pitch")
    sep = THRESHOLDS["bounce_pitch_separation"]
    if b is not None and p is not None:
        gap = abs(b.frequency_hz - p.frequency_hz) / max(b.frequency_hz, p.frequency_hz)
        if gap < sep:
            rep.add("warning", "hull.pitch_inertia", f"bounce ({b.frequency_hz:.3g} Hz) and pitch "
                    f"({p.frequency_hz:.3g} Hz) are {100 * gap:.1f} % apart (less than {100 * sep:.0f} %): any coupling "
                    "mixes them into one motion that one damper setting cannot suit (intended for a flat ride with a "
                    "dynamic index near 1; otherwise look at hull.pitch_inertia, the axle positions and the CG)")
    f_hop = THRESHOLDS["max_wheel_hop_hz"]
    if wheel and max(md.frequency_hz for md in wheel) > f_hop:
        top = max(wheel, key=lambda md: md.frequency_hz)
        rep.add("warning", "tyre.stiffness", f"{top.name} at {top.frequency_hz:.3g} Hz, above {f_hop:g} Hz with the "
                "tyre as given: a pneumatic tyre on its unsprung mass is usually 8-12 Hz (tyre.stiffness, "
                "axles[k].unsprung_mass)")


def _mode_key(name: str) -> str:
    return {"bounce": "charging.strut_deflection", "pitch": "hull.pitch_inertia",
            "roll": "hull.roll_inertia"}.get(name, "tyre.stiffness")


# --- the whole check -------------------------------------------------------------------------------
def check_vehicle(P: VehicleParams, source: str = "", modes: bool = True, model: VehicleModel | None = None,
                  shipped: str | None = "apc_8x8") -> CheckReport:
    """Everything of the module doc for a validated vehicle; `modes=False` skips the linearisation.

    shipped: the shipped vehicle whose given values mark the defaults that differ from them (None: none)."""
    rep = CheckReport(vehicle=P.name, source=source)
    rep.defaults = defaults_left_out(P)
    if shipped:
        mark_shipped_differences(rep.defaults, load_vehicle(shipped))
    check_masses(P, rep)
    check_geometry(P, rep)
    if rep.ok:
        model = check_standing(P, rep, model)
    if modes and rep.ok:
        check_modes(P, rep)
    return rep


def check_file(path, modes: bool = True) -> CheckReport:
    """Load (schema errors raise UserInputError: exit code 2) and check a vehicle file or a built-in name."""
    return check_vehicle(load_vehicle(path), str(vehicle_file(path)), modes=modes)


def pre_drive_check(P: VehicleParams, model: VehicleModel | None = None, log=None, source: str = "") -> CheckReport:
    """The quiet check before a drive (no modes): warnings to `log` (a logging function), errors raised as one
    UserInputError (the drive is refused, exit code 2)."""
    rep = check_vehicle(P, source, modes=False, model=model, shipped=None)
    if rep.errors:
        raise UserInputError(f"vehicle check: {'; '.join(str(f) for f in rep.errors)} (hpsim vehicle check FILE "
                             "tells more)")
    if log is not None:
        for f in rep.warnings:
            if f.drive:
                log(f"vehicle check: {f}")
    return rep
