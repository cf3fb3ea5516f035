"""Predictions against measurements (`hpsim validate`, docs/measurements.md).

PREDICTION is a results file (one drive: the nominal prediction) or the folder of an `hpsim uq` study (every
finished case's results file: the median and the 5-95 % band of the prediction over the priors). For each point
of a measurement file (vehicle.analysis.measurements):

  predicted   the model's value of the compared quantity (a change after - before when the file gives both
              readings, else the reading): nominal drive, and over a study the 5/50/95 % percentiles
  band        [5 %, 95 %] of what the instrument would read (vehicle.analysis.instruments: the prediction of
              every drive read through the measurement model's priors and the instrument's noise)
  measured    the measured value with its standard uncertainty; difference = measured - predicted (nominal)
  inside      band[0] <= measured <= band[1] (the edges count as inside)

Coverage: how many points lie inside their 90 % band, and the band widths (relative to the measured value, for
a temperature reading its excess over the ambient, and its uncertainty, so that a band wide enough to hold
anything shows as such). Series (logs over time or distance): the nominal prediction (and the study's 5-95 % band) at the measured x, and the RMS error.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from hpsim.errors import UserInputError
from hpsim.tables import format_table
from hpsim.units import registry

from vehicle.results.reader import open_results
from vehicle.analysis import instruments as inst
from vehicle.analysis.measurements import (QUANTITIES, Instrument, MeasurementFile, Point, Series, read_measurements,
                                           uncertainty_value)
from vehicle.analysis.summary import report_from
from vehicle.studies.uq_files import read_records

BAND = (5.0, 95.0)
MIN_DRAWS_PER_CASE = 64          # measurement-model draws per drive (a study: at least this many per case)
TOTAL_DRAWS = 4000               # ... and about this many over all drives
# the x units a log is tried in when its x does not overlap the drive (a unit mix-up is then named)
X_UNIT_CANDIDATES = {"distance": ("m", "km", "mm"), "time": ("s", "ms", "min", "h")}
SERIES_VARIABLES = {"surface_temperature": ("strut_temperature", "station"),
                    "oil_temperature": ("oil_temperature", "station"),
                    "height": ("axle_height_change", "axle")}


# --- what one drive predicts -----------------------------------------------------------------------------
@dataclass
class DriveState:
    """The numbers of one results file that the measurement models read (per station unless noted)."""

    name: str
    n_axles: int
    T_start: np.ndarray            # K, standing before the drive (every node alike)
    T_oil: np.ndarray              # K, at the end of the drive
    T_wall: np.ndarray
    T_surface: np.ndarray
    N_before: np.ndarray           # N, standing equilibria
    N_after: np.ndarray
    h_before: np.ndarray           # m, per axle, against the charged pose
    h_after: np.ndarray
    heights_charged: np.ndarray    # m, per axle (the charging heights of the vehicle file)
    tyre_stiffness: np.ndarray     # N/m per station
    ambient_K: float
    dh_band_m: list                # per axle [low, high] or None
    dN_band_frac: list             # per axle [low, high] (fraction of N_before) or None
    network: inst.StandingNetwork
    series: dict = field(default_factory=dict)   # variable -> (time s, distance m, values)

    @property
    def per_axle(self) -> int:
        return len(self.T_start) // self.n_axles


def _station_mean(a, axle: int, side: str | None, per_axle: int) -> np.ndarray:
    """Values of one axle's stations (a side: one station), averaged over the last axis of stations."""
    a = np.asarray(a, float)
    i0 = (axle - 1) * per_axle
    idx = [i0 + (0 if side == "L" else per_axle - 1)] if side else list(range(i0, i0 + per_axle))
    return a[..., idx].mean(axis=-1)


def _end(r, final: dict, name: str) -> np.ndarray:
    v = final.get(name)
    if v is None:
        s = r.series(name)
        if s is None or len(s) == 0:
            raise UserInputError(f"{r.path}: no {name} at the end of the drive (a results file of an older hpsim?)")
        v = s[-1]
    return np.asarray(v, float)


def _tyre_stiffness(veh: dict, axle: int) -> float:
    """The tyre stiffness [N/m] of an axle: its own tyre's (axles[k].tyre), else the vehicle's."""
    own = veh["axles"][axle].get("tyre") or {}
    return float(own.get("stiffness") if own.get("stiffness") is not None else veh["tyre"]["stiffness"])


def read_drive(path: str | Path) -> DriveState:
    """The state a measurement model needs from one results file (complete drives only)."""
    with open_results(path) as r:
        rep = report_from(r, str(path))
        if not rep["complete"]:
            raise UserInputError(f"{path}: the drive is not complete (status {rep['status']}); finish it first")
        res = json.loads(r.scenario_attrs["resolved_json"])
        before, after = r.equilibrium("before"), r.equilibrium("after")
        final = r.summary_values()
        T_oil, T_wall, T_surf = (_end(r, final, n) for n in ("oil_temperature", "wall_temperature", "strut_temperature"))
        n_st = len(r.stations)
        veh = res["vehicle"]
        k_t = np.array([_tyre_stiffness(veh, i * len(veh["axles"]) // n_st) for i in range(n_st)], float)
        t, s = r.series("time"), r.series("distance")
        series = {}
        for var, _ in SERIES_VARIABLES.values():
            v = r.series(var)
            if v is not None and t is not None:
                series[var] = (np.asarray(t, float), np.asarray(s, float), np.asarray(v, float))
        state = DriveState(
            name=str(path), n_axles=len(r.axles), T_start=np.asarray(before["oil_temperature"], float),
            T_oil=T_oil, T_wall=T_wall, T_surface=T_surf,
            N_before=np.asarray(before["wheel_load"], float), N_after=np.asarray(after["wheel_load"], float),
            h_before=np.asarray(before["axle_height_change"], float), h_after=np.asarray(after["axle_height_change"], float),
            heights_charged=np.asarray(veh["charging"].get("heights") or [np.nan] * len(r.axles), float),
            tyre_stiffness=k_t, ambient_K=float(res["scenario"]["ambient_temperature"]),
            dh_band_m=[None if b is None or None in b else [b[0] / 1e3, b[1] / 1e3] for b in
                       (a["dh_band_mm"] for a in rep["axles"])],
            dN_band_frac=[None if b is None or None in b else [b[0] / 100, b[1] / 100] for b in
                          (a["dN_band_pct"] for a in rep["axles"])],
            network=inst.StandingNetwork.from_resolved(res, n_st), series=series)
    return state


def true_value(d: DriveState, p: Point) -> float:
    """What the model predicts for a point's compared quantity [SI] (no measurement model)."""
    m = lambda a: float(_station_mean(a, p.axle, p.side, d.per_axle))  # noqa: E731
    k = p.axle - 1
    values = {
        "surface_temperature": (m(d.T_start), m(d.T_surface)),
        "oil_temperature": (m(d.T_start), m(d.T_oil)),
        "height": (d.heights_charged[k] + d.h_before[k], d.heights_charged[k] + d.h_after[k]),
        "wheel_load": (m(d.N_before), m(d.N_after)),
    }[p.quantity]
    return {"change": values[1] - values[0], "before": values[0], "after": values[1]}[p.compared]


def readings(d: DriveState, points: list[Point], rng: np.random.Generator, n: int) -> np.ndarray:
    """n draws of what each point's instrument would read for this drive [SI], shape (points, n)."""
    delay = inst.draw("delay", rng, n)
    random_delay = d.network.cool(d.T_oil, d.T_wall, d.T_surface, delay)      # (3, stations, n)
    fixed = {f: d.network.cool(d.T_oil, d.T_wall, d.T_surface, [f]) for f in
             {p.instrument.delay_s for p in points if p.instrument.delay_s is not None}}
    out = np.empty((len(points), n))
    grow = dict(rise=inst.draw("tyre.air_temperature_rise", rng, n), p=inst.draw("tyre.inflation_pressure", rng, n),
                c=inst.draw("tyre.carcass_pressure_fraction", rng, n))
    for j, p in enumerate(points):
        nodes = random_delay if p.instrument.delay_s is None else fixed[p.instrument.delay_s]
        T_oil_r, T_surf_r = nodes[0], nodes[2]           # (stations, n or 1)
        out[j] = _reading(d, p, rng, n, T_oil_r, T_surf_r, grow)
        out[j] += inst.noise(p.uncertainty, rng, n, 2 if p.compared == "change" else 1)
    return out


def _reading(d: DriveState, p: Point, rng, n, T_oil_r, T_surf_r, grow) -> np.ndarray:
    """One point's reading without noise (instruments module docstring)."""
    k, per = p.axle - 1, d.per_axle
    stations = [k * per + (0 if p.side == "L" else per - 1)] if p.side else list(range(k * per, (k + 1) * per))
    before_T = float(np.mean(d.T_start[stations]))
    if p.quantity in ("surface_temperature", "oil_temperature"):
        if p.quantity == "surface_temperature" and p.instrument.type == "pyrometer":
            spots = [inst.PyrometerSpot.draw(rng, n) for _ in stations]
            read = lambda T_oil, T_surf: np.mean([   # noqa: E731
                inst.pyrometer_reading_K(T_oil[i], T_surf[i], d.ambient_K, spot, p.instrument.emissivity_setting)
                for i, spot in zip(stations, spots)], axis=0)
            after, before = read(T_oil_r, T_surf_r), read(d.T_start, d.T_start)
        else:
            T = T_surf_r if p.quantity == "surface_temperature" else T_oil_r
            after = np.broadcast_to(np.mean(T[stations], axis=0), n).astype(float)
            before = np.full(n, before_T)
        return {"change": after - before, "after": after, "before": before}[p.compared]
    if p.quantity == "height":
        dh = d.h_after[k] - d.h_before[k]
        band = d.dh_band_m[k]
        base = inst.uniform_in_band(band[0], band[1], rng, n) if band is not None and p.compared == "change" \
            else np.full(n, dh)
        defl = np.mean(d.N_before[stations] / d.tyre_stiffness[stations])
        lift = inst.tyre_lift_m(defl, grow["rise"], before_T, grow["p"], grow["c"])
        T_oil_end = float(np.mean(d.T_oil[stations]))
        T_oil_now = np.mean(T_oil_r[stations], axis=0)
        cool = dh * (T_oil_now - T_oil_end) / (T_oil_end - before_T) if abs(T_oil_end - before_T) > 1e-6 else 0.0
        after = base + lift + cool
        if p.compared == "change":
            return after
        h0 = d.heights_charged[k]
        return {"after": h0 + d.h_before[k] + after, "before": np.full(n, h0 + d.h_before[k])}[p.compared]
    # wheel load
    N0, N1 = float(np.mean(d.N_before[stations])), float(np.mean(d.N_after[stations]))
    band = d.dN_band_frac[k]
    if p.compared == "change":
        if band is None:
            return np.full(n, N1 - N0)
        return inst.uniform_in_band(band[0] * N0, band[1] * N0, rng, n)
    return np.full(n, N1 if p.compared == "after" else N0)


# --- the prediction: one drive or a study --------------------------------------------------------------
def prediction_files(path: str | Path) -> tuple[str, Path | None, list[Path]]:
    """(kind, nominal file, all drive files) of a PREDICTION: a results file ('drive') or an hpsim uq study
    folder ('study': cases/<case>.h5 of every finished case in cases.jsonl; the nominal case when done)."""
    path = Path(path)
    if path.is_file():
        return "drive", path, [path]
    if not path.is_dir():
        raise UserInputError(f"{path}: not found; PREDICTION is a results file (.h5) or an hpsim uq study folder")
    records = path / "cases.jsonl"
    if not (path / "samples.csv").is_file() or not records.is_file():
        raise UserInputError(f"{path}: not an hpsim uq study folder (no samples.csv and cases.jsonl); give a "
                             "results file or the folder of `hpsim uq ... -o DIR`")
    done = []
    for line in records.read_text().splitlines():
        try:
            rec = json.loads(line)
        except json.JSONDecodeError:
            continue
        if isinstance(rec, dict) and rec.get("status") == "done":
            f = path / "cases" / f"{rec['case']}.h5"
            if f.is_file() and f not in done:
                done.append(f)
    nominal = path / "cases" / "nominal.h5"
    nominal = nominal if nominal in done else None
    design = [f for f in done if f != nominal]
    if not design and nominal is None:
        raise UserInputError(f"{path}: no finished case in cases.jsonl; run the study first")
    return "study", nominal, design or [nominal]


def failed_cases(path: str | Path) -> list[str]:
    """The cases of an hpsim uq study folder whose last record in cases.jsonl is not 'done' (a failed or interrupted
    draw: not in the bands); [] for a results file."""
    records = Path(path) / "cases.jsonl"
    if not records.is_file():
        return []
    return [str(case) for case, rec in read_records(records).items() if rec.get("status") != "done"]


def _excluded_note(v: dict) -> list[str]:
    failed = v.get("excluded_cases") or []
    if not failed:
        return []
    names = ", ".join(failed[:5]) + (" ..." if len(failed) > 5 else "")
    return [f"note: the bands are of the {v['drives']} finished drive(s); {len(failed)} failed draw(s) are excluded "
            f"({names}), so the bands may be narrower than the priors imply"]


def _pct(a) -> list[float]:
    return [float(x) for x in np.percentile(np.asarray(a, float), [BAND[0], 50.0, BAND[1]])]


def _shown(quantity: str, unit: str, compared: str):
    """SI -> the file's unit; a temperature change is a difference (degC readings -> K)."""
    Q = registry().Quantity
    si = QUANTITIES[quantity].si
    if si == "K" and compared == "change":
        return (lambda v: None if v is None else float(v)), "K"
    return (lambda v: None if v is None else float(Q(v, si).to(unit).magnitude)), unit


def predict_points(points: list[Point], drives: list[DriveState], nominal: DriveState | None,
                   seed: int = 0) -> list[dict]:
    """Per point the model's prediction (nominal; over a study the 5/50/95 % percentiles) and the 5/50/95 %
    of what its instrument would read, in the point's unit (no measured value needed)."""
    rng = np.random.default_rng(seed)
    n = max(MIN_DRAWS_PER_CASE, TOTAL_DRAWS // max(len(drives), 1))
    R = np.concatenate([readings(d, points, rng, n) for d in drives], axis=1)       # (points, drives * n)
    truth = np.array([[true_value(d, p) for d in drives] for p in points])           # (points, drives)
    out = []
    for j, p in enumerate(points):
        conv, unit = _shown(p.quantity, p.unit, p.compared)
        nom = true_value(nominal, p) if nominal is not None else None
        lo, med, hi = _pct(R[j])
        pl, pm, ph = _pct(truth[j])
        out.append({
            "quantity": p.quantity, "axle": p.axle, "wheel": f"{p.axle}{p.side}" if p.side else None,
            "compared": p.compared, "unit": unit, "instrument": p.instrument.name,
            "predicted": conv(nom if nom is not None else pm), "nominal": conv(nom),
            "predicted_median": conv(pm), "predicted_band": [conv(pl), conv(ph)],
            "band": [conv(lo), conv(hi)], "reading_median": conv(med), "band_width": _delta(p, hi - lo, unit),
            "drives": len(drives), "_si": (lo, hi, nom if nom is not None else pm)})
    return out


def compare_points(points: list[Point], drives: list[DriveState], nominal: DriveState | None, seed: int = 0) -> list[dict]:
    """`predict_points` with the measured value, its uncertainty, the difference and whether it lies inside."""
    out = predict_points(points, drives, nominal, seed)
    ambient_K = (nominal or drives[0]).ambient_K
    for p, row in zip(points, out):
        lo, hi, ref = row.pop("_si")
        conv, unit = _shown(p.quantity, p.unit, p.compared)
        measured = p.measured
        row.update({"measured": conv(measured), "uncertainty": _delta(p, p.measured_uncertainty, unit),
                    "difference": _delta(p, measured - ref, unit), "inside": bool(lo <= measured <= hi),
                    "relative_width": float((hi - lo) / max(abs(measured - _width_origin(p, ambient_K)),
                                                            p.measured_uncertainty)),
                    "source": p.source, "where": p.where})
    return out


def _width_origin(p: Point, ambient_K: float) -> float:
    """What a band width is measured against [SI]: a temperature reading's excess over the ambient (a fraction
    of the absolute temperature in kelvin says nothing), any other reading or change from zero."""
    return ambient_K if QUANTITIES[p.quantity].si == "K" and p.compared != "change" else 0.0


def _delta(p: Point, v_si: float, unit: str) -> float:
    """A difference [SI] in the shown unit (temperature differences: K)."""
    si = QUANTITIES[p.quantity].si
    if si == "K":
        return float(v_si)
    return float(registry().Quantity(v_si, si).to(unit).magnitude)


# --- series ------------------------------------------------------------------------------------------------
def compare_series(s: Series, drives: list[DriveState], nominal: DriveState | None) -> dict:
    """The prediction at the measured x (nominal; a study's 5-95 % band over its drives) and the RMS error.
    No measurement model on series: a logged sensor reads the state continuously (its noise: the uncertainty)."""
    var, dim = SERIES_VARIABLES[s.quantity]

    def at(d: DriveState):
        if var not in d.series:
            raise UserInputError(f"{d.name}: no stored {var} series for {s.where} (output.store of the scenario)")
        t, dist, v = d.series[var]
        x = t if s.x_kind == "time" else dist
        y = _station_mean(v, s.axle, s.side, d.per_axle) if dim == "station" else v[:, s.axle - 1]
        if s.quantity == "height":
            y = y + d.heights_charged[s.axle - 1]
        inside = (s.x >= x[0]) & (s.x <= x[-1])
        return np.interp(s.x, x, y), inside, (x[0], x[-1])

    ref = nominal or drives[0]
    y_nom, covered, span = at(ref)
    if not np.any(covered):
        u = "s" if s.x_kind == "time" else "m"
        raise UserInputError(f"{s.where}: the measured {s.x_kind} {s.x[0]:.6g} .. {s.x[-1]:.6g} {u} does not "
                             f"overlap the drive's {span[0]:.6g} .. {span[1]:.6g} {u}" + _unit_hint(s, span))
    Y = np.array([at(d)[0] for d in drives])
    lo, hi = np.percentile(Y, BAND, axis=0) if len(drives) > 1 else (y_nom, y_nom)
    err = s.y[covered] - y_nom[covered]
    si = QUANTITIES[s.quantity].si
    Q = registry().Quantity
    shown = s.unit if si != "K" or "deg" in s.unit or s.unit == "K" else s.unit
    conv = lambda a: np.asarray(Q(np.asarray(a, float), si).to(shown).magnitude, float)  # noqa: E731
    dconv = (lambda a: np.asarray(a, float)) if si == "K" else conv
    inside = (s.y[covered] >= lo[covered]) & (s.y[covered] <= hi[covered])
    return {"quantity": s.quantity, "axle": s.axle, "wheel": f"{s.axle}{s.side}" if s.side else None,
            "file": s.file, "x_kind": s.x_kind, "unit": shown, "samples": int(covered.sum()),
            "rms_error": float(dconv(np.sqrt(np.mean(err ** 2)))), "mean_error": float(dconv(np.mean(err))),
            "inside_share": float(np.mean(inside)) if len(drives) > 1 else None,
            "x": s.x[covered].tolist(), "measured": conv(s.y[covered]).tolist(),
            "predicted": conv(y_nom[covered]).tolist(), "band": [conv(lo[covered]).tolist(), conv(hi[covered]).tolist()],
            "uncertainty": float(dconv(s.uncertainty)), "where": s.where}


def _unit_hint(s: Series, span: tuple[float, float]) -> str:
    """'; read in km it would: ...' when another unit of the same kind makes the measured x overlap the drive
    (a column in km declared as m, in minutes declared as s, ...); else ''."""
    Q = registry().Quantity
    si = "s" if s.x_kind == "time" else "m"
    declared = s.x_unit or si
    try:
        scale = float(Q(1.0, declared).to(si).magnitude)
    except Exception:
        return ""
    for unit in X_UNIT_CANDIDATES[s.x_kind]:
        f = float(Q(1.0, unit).to(si).magnitude) / scale
        lo, hi = s.x[0] * f, s.x[-1] * f
        overlap = min(hi, span[1]) - max(lo, span[0])
        if unit != declared and overlap > 0.5 * min(hi - lo, span[1] - span[0]):
            return f"; read in {unit} (not {declared}) it would: check the unit of x in the measurement file"
    return ""


# --- the whole comparison ----------------------------------------------------------------------------------
def coverage(points: list[dict]) -> dict:
    """How many points lie inside their 90 % band; band widths per quantity (median, relative to |measured|)."""
    by_q: dict[str, list[dict]] = {}
    for p in points:
        by_q.setdefault(p["quantity"], []).append(p)
    out = {"inside": sum(p["inside"] for p in points), "points": len(points),
           "expected_share": (BAND[1] - BAND[0]) / 100.0, "by_quantity": {}}
    for q, ps in by_q.items():
        out["by_quantity"][q] = {"inside": sum(p["inside"] for p in ps), "points": len(ps), "unit": ps[0]["unit"],
                                 "median_band_width": float(np.median([p["band_width"] for p in ps])),
                                 "median_relative_width": float(np.median([p["relative_width"] for p in ps])),
                                 "relative_to": "|measured - ambient| (readings), |measured| (changes)"
                                 if QUANTITIES[q].si == "K" and any(p["compared"] != "change" for p in ps)
                                 else "|measured|"}
    return out


def check_layout(m: MeasurementFile, d: DriveState) -> None:
    for item in [*m.points, *m.series]:
        if item.axle > d.n_axles:
            raise UserInputError(f"{m.path}: {item.where}: axle {item.axle}: the prediction has axles 1-{d.n_axles}")
        if item.side and d.per_axle != 2:
            raise UserInputError(f"{m.path}: {item.where}: wheel {item.axle}{item.side}: the vehicle has "
                                 f"{d.per_axle} station(s) per axle")


def validate(prediction: str | Path, measured: str | Path, *, seed: int = 0, log=None) -> dict:
    log = log or (lambda msg: None)
    m = read_measurements(measured)
    kind, nominal_path, files = prediction_files(prediction)
    log(f"{prediction}: {kind}, {len(files)} drive(s)" + (" + nominal" if kind == "study" and nominal_path else ""))
    drives = [read_drive(f) for f in files]
    nominal = read_drive(nominal_path) if nominal_path is not None and nominal_path not in files else \
        (drives[files.index(nominal_path)] if nominal_path is not None else None)
    check_layout(m, drives[0])
    points = compare_points(m.points, drives, nominal, seed) if m.points else []
    series = [compare_series(s, drives, nominal) for s in m.series]
    return {"prediction": str(prediction), "kind": kind, "drives": len(drives),
            "excluded_cases": failed_cases(prediction) if kind == "study" else [],
            "nominal": str(nominal_path) if nominal_path else None, "measurements": str(measured),
            "description": m.description, "source": m.source, "band_percentiles": list(BAND),
            "points": points, "coverage": coverage(points) if points else None, "series": series,
            "measurement_model_priors": inst.priors_table()}


def standard_points(n_axles: int) -> list[Point]:
    """Per axle the after-minus-before reading of the usual instruments (instruments.STANDARD_INSTRUMENTS)."""
    out = []
    for q, (name, u, source) in inst.STANDARD_INSTRUMENTS.items():
        kind = QUANTITIES[q]
        u_si = uncertainty_value(u, kind.si, kind.uncertainty_max, name)
        device = Instrument(name=name, type=name, uncertainty=u_si, unit=u.split()[-1], source=source)
        for a in range(1, n_axles + 1):
            out.append(Point(where=f"{name} axle {a}", quantity=q, axle=a, side=None, before=0.0, after=0.0,
                             unit=kind.shown, instrument=device, uncertainty=u_si, source=source))
    return out


def instrument_readings(prediction: str | Path, *, seed: int = 0) -> dict:
    """Without measurements: per axle the prediction and the 5/50/95 % of what the usual instruments would read
    after minus before the drive (pyrometer rise, photogrammetric height change, scale load change, also in %)."""
    kind, nominal_path, files = prediction_files(prediction)
    drives = [read_drive(f) for f in files]
    nominal = read_drive(nominal_path) if nominal_path is not None and nominal_path not in files else \
        (drives[files.index(nominal_path)] if nominal_path is not None else None)
    points = standard_points(drives[0].n_axles)
    rows = predict_points(points, drives, nominal, seed)
    ref = nominal or drives[0]
    for p, row in zip(points, rows):
        row.pop("_si")
        row["source"] = p.source
        if p.quantity == "wheel_load":
            N0 = float(np.mean(_station_mean(ref.N_before, p.axle, None, ref.per_axle))) / 10.0     # daN
            row["percent_of_before"] = {k: [100.0 * x / N0 for x in row[k]] if isinstance(row[k], list) else
                                        (None if row[k] is None else 100.0 * row[k] / N0)
                                        for k in ("predicted", "predicted_median", "predicted_band", "band",
                                                  "reading_median")}
    return {"prediction": str(prediction), "kind": kind, "drives": len(drives),
            "excluded_cases": failed_cases(prediction) if kind == "study" else [],
            "nominal": str(nominal_path) if nominal_path else None, "measurements": None,
            "description": "predicted readings of the usual instruments", "band_percentiles": list(BAND),
            "points": rows, "coverage": None, "series": [], "measurement_model_priors": inst.priors_table(),
            "instruments": {q: {"instrument": i, "uncertainty": u, "source": s}
                            for q, (i, u, s) in inst.STANDARD_INSTRUMENTS.items()}}


def format_readings(v: dict) -> str:
    """The table of `instrument_readings`: per axle and instrument the prediction and the reading's 5/50/95 %."""
    study = v["kind"] == "study"
    rows = []
    for p in v["points"]:
        pct = p.get("percent_of_before")
        f = (lambda x, k: f"{x:+.3g}" + (f" ({pct[k]:+.2f} %)" if pct and not isinstance(pct[k], list) else "")) \
            if p["quantity"] == "wheel_load" else (lambda x, k: f"{x:+.4g}")
        band = lambda b, k: f"[{b[0]:+.4g}, {b[1]:+.4g}]" + (  # noqa: E731
            f" ([{pct[k][0]:+.2f}, {pct[k][1]:+.2f}] %)" if pct else "")
        rows.append([p["instrument"], p["axle"], p["unit"], f(p["predicted"], "predicted"),
                     band(p["predicted_band"], "predicted_band") if study else "-",
                     f(p["reading_median"], "reading_median"), band(p["band"], "band")])
    head = [f"{v['prediction']} ({v['kind']}: {v['drives']} drive(s)): what the instruments would read, after minus "
            "before the drive"]
    head.append(format_table(["instrument", "axle", "unit", "nominal" if v["nominal"] else "median",
                              "model 5-95 %", "reading 50 %", "reading 5-95 %"], rows))
    for q, i in v["instruments"].items():
        head.append(f"{i['instrument']}: {i['uncertainty']} per reading ({i['source']})")
    return "\n".join(head + _excluded_note(v))


def format_validation(v: dict) -> str:
    lines = [f"{v['measurements']} ({v['description'] or 'no description'}) against {v['prediction']} "
             f"({v['kind']}: {v['drives']} drive(s))"]
    if v["points"]:
        f = lambda x: "-" if x is None else f"{x:.4g}"  # noqa: E731
        rows = [[p["quantity"], p["wheel"] or p["axle"], p["compared"], p["unit"], f(p["predicted"]),
                 f"[{f(p['predicted_band'][0])}, {f(p['predicted_band'][1])}]" if v["kind"] == "study" else "-",
                 f"[{f(p['band'][0])}, {f(p['band'][1])}]", f"{f(p['measured'])} ± {f(p['uncertainty'])}",
                 f"{p['difference']:+.3g}", "yes" if p["inside"] else "NO"] for p in v["points"]]
        lines.append(format_table(["quantity", "axle", "compared", "unit", "predicted", "prediction 5-95 %",
                                   "instrument 5-95 %", "measured ± u", "difference", "inside"], rows))
        c = v["coverage"]
        lines.append(f"coverage: {c['inside']} of {c['points']} measurements inside the instrument's 90 % band "
                     f"(expected about {c['expected_share']:.0%} if the bands are right)")
        for q, b in c["by_quantity"].items():
            lines.append(f"  {q}: {b['inside']}/{b['points']} inside; median band width {b['median_band_width']:.3g} "
                         f"{b['unit']} = {b['median_relative_width']:.2g} x {b['relative_to']}"
                         + ("  (wide: the band would hold almost any reading)" if b["median_relative_width"] > 2 else ""))
    for s in v["series"]:
        share = "" if s["inside_share"] is None else f", {s['inside_share']:.0%} of samples inside the 5-95 % band"
        lines.append(f"series {s['quantity']} axle {s['wheel'] or s['axle']} ({Path(s['file']).name}, "
                     f"{s['samples']} samples): RMS error {s['rms_error']:.3g} {s['unit'] if s['unit'] != 'degC' else 'K'}, "
                     f"mean error {s['mean_error']:+.3g}{share}")
    return "\n".join(lines + _excluded_note(v))
