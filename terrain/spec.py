"""`RoadSpec` (what road to build, from YAML or the command line) and `build_road`.

Exactly one source of the profile:

- `iso_class: D` — ISO 8608 class A..H, Gd(n0) = the class's geometric mean (iso8608 table);
- `gd_n0: 1.2e-3` (or "1200e-6 m**3") — a custom Gd(n0), with `waviness` w;
- `csv: measured.csv` — a measured profile (relative paths resolved against `base_dir`);
- `crg: surface.crg` — an OpenCRG surface: its tracks at `lateral_offset` +- track_width/2 across the
  reference line (v positive to the left; `terrain.crg`);
- `flat: true` — a perfectly flat road (events only).

Random roads are generated on a grid of `spacing` over `length` (n = floor(length/spacing) + 1
points; the road ends at the last grid point). For `csv`, `spacing` resamples the file only if
given explicitly (else the file's own spacing is kept) and `length` keeps the first metres of it.
`events` are added on top of any source, and so are the events of random `populations` (potholes
or bumps with a density per km and distributions of size, `terrain.events.EventPopulation`).
`passes` give the surface the 2nd, 3rd, ... wheel over the same ground meets (a factor and a
smoothing length each, `terrain.passes`; default: the same surface for every pass). Long-wave
content: `waviness` (w in Gd(n) ~ n^-w, 0.5..4) and `band` (its lower edge sets the longest
wavelength, 1/n_min) reach every random road.
"""
from __future__ import annotations

from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import field_validator, model_validator
from pydantic_core.core_schema import ValidationInfo

from hpsim.config import Model, Quantity, load_yaml, validate
from hpsim.errors import UserInputError

from . import iso8608
from .coherence import coherence_model
from .events import LEVEL_EVENTS, EventPopulation, EventSpec, apply_events, population_rng
from .passes import PassSpec
from .plausibility import check_plausible_tracks
from .road import Road, check_road_points
from .store import key_of, stored_arrays

MAX_LENGTH_M = 5.0e6  # 5000 km: beyond this the arrays no longer fit comfortably in memory
# Work size of a road: generating takes about 50 bytes per grid point at its peak (measured: 20 M
# points, 1.1 GB), so 25 M points (1250 km at the default 50 mm) bound it to about 1.3 GB.
MAX_TRACK_WIDTH_M = 10.0
WAVINESS_RANGE = (0.5, 4.0)  # generous around the ISO 8608 typical 1.5..3.5
MAX_GD_N0_M3 = 1.0  # ~4x the ISO class H geometric mean


class RoadSpec(Model):
    iso_class: str | None = None
    gd_n0: Quantity("m**3") | None = None
    waviness: float = iso8608.WAVINESS_ISO
    csv: str | None = None
    crg: str | None = None           # an OpenCRG surface: its tracks at lateral_offset +-track_width/2 (terrain.crg)
    lateral_offset: Quantity("m") = 0.0   # crg: the v of the vehicle's centre line, + left of the reference line
    flat: bool = False
    band: tuple[float, float] = iso8608.DEFAULT_BAND_CYCLE_PER_M  # cycle/m
    length: Quantity("m") | None = None
    spacing: Quantity("m") = 0.05
    seed: int = 0
    track_width: Quantity("m") = 2.5
    coherence: Literal["isotropic", "independent", "identical"] = "isotropic"
    events: list[EventSpec] = []
    populations: list[EventPopulation] = []
    passes: list[PassSpec] = []

    @field_validator("iso_class", mode="before")
    @classmethod
    def _class(cls, v):
        if v is None:
            return v
        name = str(v).strip().upper()
        if name not in iso8608.ISO_CLASSES:
            raise ValueError(f"{v!r} is not an ISO 8608 class; allowed "
                             f"{', '.join(iso8608.ISO_CLASSES)}")
        return name

    @field_validator("gd_n0")
    @classmethod
    def _gd(cls, v):
        if v is not None and not (0 < v <= MAX_GD_N0_M3):
            raise ValueError(f"Gd(n0) must be in (0, {MAX_GD_N0_M3}] m³ (class D is 1.024e-3 m³)")
        return v

    @field_validator("waviness")
    @classmethod
    def _w(cls, v):
        if not (WAVINESS_RANGE[0] <= v <= WAVINESS_RANGE[1]):
            raise ValueError(f"waviness must be in [{WAVINESS_RANGE[0]}, {WAVINESS_RANGE[1]}] (ISO 8608: 2)")
        return v

    @field_validator("band")
    @classmethod
    def _band(cls, v):
        lo, hi = v
        if not (0 < lo < hi):
            raise ValueError("band must be [n_min, n_max] in cycle/m with 0 < n_min < n_max "
                             f"(ISO 8608: {list(iso8608.DEFAULT_BAND_CYCLE_PER_M)})")
        return v

    @field_validator("length")
    @classmethod
    def _length(cls, v):
        if v is not None and not (0 < v <= MAX_LENGTH_M):
            raise ValueError(f"length must be in (0, {MAX_LENGTH_M / 1000:.0f} km]")
        return v

    @field_validator("spacing")
    @classmethod
    def _spacing(cls, v, info: ValidationInfo):
        if not v > 0:
            raise ValueError("spacing must be > 0 m")
        data = info.data
        random_road = data.get("csv") is None and data.get("crg") is None and not data.get("flat")
        band = data.get("band")
        if random_road and band is not None:
            limit = 0.5 / band[1]
            if v > limit * (1 + 1e-9):
                raise ValueError(f"spacing {v:g} m is too coarse for the shortest wavelength "
                                 f"1/{band[1]:g} = {1 / band[1]:.4g} m; at most {limit:.4g} m "
                                 f"(two samples per wavelength)")
        length = data.get("length")
        if length is not None and v * 2 > length:
            raise ValueError(f"spacing {v:g} m leaves fewer than 3 points over the length {length:g} m")
        if length is not None:
            try:
                check_road_points(length, v)
            except UserInputError as exc:
                raise ValueError(str(exc)) from None
        return v

    @field_validator("seed")
    @classmethod
    def _seed(cls, v):
        if v < 0:
            raise ValueError("seed must be an integer >= 0")
        return v

    @field_validator("track_width")
    @classmethod
    def _track(cls, v):
        if not (0 < v <= MAX_TRACK_WIDTH_M):
            raise ValueError(f"track_width must be in (0, {MAX_TRACK_WIDTH_M}] m")
        return v

    @model_validator(mode="after")
    def _source(self):
        given = [name for name, on in (("iso_class", self.iso_class is not None),
                                       ("gd_n0", self.gd_n0 is not None),
                                       ("csv", self.csv is not None), ("crg", self.crg is not None),
                                       ("flat", self.flat)) if on]
        if len(given) != 1:
            raise ValueError("give exactly one road source: iso_class (A-H), gd_n0 (custom Gd(n0)), "
                             f"csv (measured profile), crg (OpenCRG surface) or flat: true (got {', '.join(given) or 'none'})")
        if self.lateral_offset != 0 and self.crg is None:
            raise ValueError("lateral_offset places the tracks on an OpenCRG surface: give it with crg only")
        if self.csv is None and self.crg is None and self.length is None:
            raise ValueError("length is required for a random or flat road (e.g. length: 20 km)")
        if self.length is not None:
            for i, ev in enumerate(self.events):
                if ev.end > self.length * (1 + 1e-12):
                    raise ValueError(f"events.{i} ({ev.type}) ends at {ev.end:g} m, beyond the road "
                                     f"length {self.length:g} m")
        return self

    @property
    def gd_n0_m3(self) -> float | None:
        """Gd(n0) [m³] used for a random road (custom value or the class's geometric mean)."""
        if self.gd_n0 is not None:
            return self.gd_n0
        if self.iso_class is not None:
            return iso8608.ISO_CLASS_GD_N0_M3[self.iso_class]
        return None


def load_road_spec(path: str | Path) -> RoadSpec:
    """Read a RoadSpec from YAML (errors name the file and key)."""
    return validate(RoadSpec, load_yaml(path), str(path))


def build_road(spec: RoadSpec, base_dir: Path | None = None) -> Road:
    """Build the Road described by `spec` (a relative `csv` path is taken from `base_dir`, default cwd). A random
    road is read from the road store when it was built before (`terrain.store`: the same arrays, memory-mapped).

    Every road, events included, is checked to be one a vehicle can drive on before it is returned
    (`terrain.plausibility`: UserInputError naming the source, the track and the distance)."""
    # a road off an OpenCRG surface only has a lateral offset: the others keep the store keys they had without it
    info = {"spec": spec.model_dump(mode="json", exclude=None if spec.crg is not None else {"lateral_offset"})}
    if spec.csv is not None or spec.crg is not None:
        path = Path(spec.csv if spec.csv is not None else spec.crg)
        if not path.is_absolute():
            path = Path(base_dir or Path.cwd()) / path
        spacing = spec.spacing if "spacing" in spec.model_fields_set else None
        if spec.crg is not None:
            road = Road.from_crg(path, spec.track_width, spacing_m=spacing, length_m=spec.length,
                                 lateral_offset_m=spec.lateral_offset)
        else:
            road = Road.from_csv(path, spacing_m=spacing, length_m=spec.length)
        if not spec.events and not spec.populations:
            return Road(road.spacing_m, road.left_m, road.right_m, info={**info, **road.info}, copy=False,
                        passes=spec.passes)
        info.update(road.info)
        step, profile, key = road.spacing_m, lambda: (road.left_m.copy(), road.right_m.copy()), None
        road_length = road.length_m
    else:
        step = spec.spacing
        n = int(np.floor(spec.length / step + 1e-9)) + 1
        profile, key = (lambda: _random_tracks(spec, step, n)), key_of("road", info["spec"])
        if not spec.flat:
            info["gd_n0_m3"] = spec.gd_n0_m3
        road_length = (n - 1) * step
    events = _events(spec, road_length, info)
    # steps and ramps change the level for good: the passes compact the roughness, not the grade
    level_events = [ev for ev in events if isinstance(ev, LEVEL_EVENTS)] \
        if any(not p.identity for p in spec.passes) else []

    def tracks():
        left, right = profile()
        apply_events(step, left, right, events)
        check_plausible_tracks(_source_name(spec), step, left, right)
        if not level_events:
            return left, right
        level = (np.zeros_like(left), np.zeros_like(right))
        apply_events(step, level[0], level[1], level_events)
        return left, right, *level

    names = ("left", "right") + (("level_left", "level_right") if level_events else ())
    arrays = stored_arrays(key, names, tracks)
    return Road(step, arrays[0], arrays[1], info=info, copy=False, passes=spec.passes,
                level_m=tuple(arrays[2:]) or None, key=key)


def _events(spec: RoadSpec, road_length: float, info: dict) -> list:
    """The road's events: the listed ones (each checked to lie on the road) and those its populations draw (their
    counts into `info`)."""
    for i, ev in enumerate(spec.events):
        if ev.position > road_length:
            raise UserInputError(f"events.{i}: {ev.type} at {ev.position:g} m is beyond the road "
                                 f"length {road_length:g} m")
    events = list(spec.events)
    counts = []
    for j, pop in enumerate(spec.populations):
        drawn = pop.realise(road_length, population_rng(spec.seed, j, pop.seed))
        counts.append(len(drawn))
        events += drawn
    if counts:
        info["population_counts"] = counts
    return events


def _source_name(spec: RoadSpec) -> str:
    """The road source as a refusal names it: the file, or what the generated road was built from."""
    if spec.csv is not None or spec.crg is not None:
        return f"{spec.csv or spec.crg} with its events"
    if spec.flat:
        return "the flat road with its events"
    what = f"ISO 8608 class {spec.iso_class}" if spec.iso_class else f"Gd(n0) = {spec.gd_n0_m3:.4g} m³"
    return f"the generated road ({what}, seed {spec.seed}, with its events)"


def _random_tracks(spec: RoadSpec, step: float, n: int) -> tuple[np.ndarray, np.ndarray]:
    """The left and right tracks of a random (or flat) road, before its events."""
    if spec.flat:
        return np.zeros(n), np.zeros(n)
    if spec.coherence == "isotropic":
        mode, fn = "model", (lambda nn: coherence_model("isotropic", nn, spec.track_width, spec.waviness))
    else:
        mode, fn = spec.coherence, None
    return iso8608.generate_tracks(spec.gd_n0_m3, spec.waviness, step, n, spec.seed, tuple(spec.band), mode, fn)
