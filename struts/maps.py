"""Internal parameters of a strut as maps over body temperature and excitation frequency (seed 001 §5.2).

Seed 001 identifies, per test (body temperature 30/40/50 degC, sinusoid 0.5-8 Hz at one peak velocity),
the gas volume fraction of the emulsion (Fig. 10a), the discharge coefficients of the bleed orifices and
check valves (Fig. 10b), and the seal friction's Coulomb level, peak (stiction) level, Stribeck coefficient
and hysteresis transition velocity per stroke direction (Fig. 11a-d). A strut file may give any of them as
a table over a (temperature, frequency) grid (`internal_maps:`); a parameter without a map keeps the file's
constant. Between grid points the value is piecewise bilinear (`hpsim.symbolic.interp_bilinear`: fmin/fmax
only, so CasADi-symbolic), outside the grid it is held at the edge (clamped); `validity_warnings` says when a
condition leaves the grid.

The frequency is the excitation measure of `struts.excitation` (an equivalent frequency from filtered mean
squares of the deflection rate and of the deflection about its moving mean), so the maps act on a vehicle's
random motion as well as on the rig's sinusoid (docs/physics.md, "Internal parameters over temperature and
frequency").
"""
from __future__ import annotations

from pydantic import model_validator

from hpsim import symbolic as sym
from hpsim.config import Model, Quantity, QuantityList

__all__ = ["InternalMaps", "MAP_UNITS", "map_value", "validity_warnings", "INTERNAL_NAMES"]

# the internal parameters a map may give, with their SI unit (the `internal` record of a rig run)
MAP_UNITS = {
    "gas_fraction": "dimensionless",
    "bleed_discharge_coefficient": "dimensionless",
    "check_discharge_coefficient": "dimensionless",
    "coulomb_compression": "N",
    "coulomb_rebound": "N",
    "peak_compression": "N",
    "peak_rebound": "N",
    "stribeck_coefficient_compression": "s/m",
    "stribeck_coefficient_rebound": "s/m",
    "transition_velocity_compression": "m/s",
    "transition_velocity_rebound": "m/s",
}
INTERNAL_NAMES = tuple(MAP_UNITS)


class _Map(Model):
    """One parameter over the grid: values[i][j] at temperatures[i], frequencies[j]; sources[i][j] says where
    each point comes from (the figure or text of seed 001, or "assumed ...")."""

    values: list[list[float]]
    sources: list[list[str]]
    legend: dict[str, str] = {}     # what each source label means (the figure, the text, or "assumed ...")
    note: str = ""

    @model_validator(mode="after")
    def _shapes(self):
        if len(self.sources) != len(self.values) or any(len(s) != len(v) for s, v in zip(self.sources, self.values)):
            raise ValueError("sources must have the shape of values (one label per point)")
        unknown = sorted({s for row in self.sources for s in row} - set(self.legend)) if self.legend else []
        if unknown:
            raise ValueError(f"source labels {unknown} are not in legend")
        return self


def _map_class(unit: str, name: str):
    # one row per temperature, each a list of quantities (numbers in SI or strings with units), one per frequency
    return type(name, (_Map,), {"__annotations__": {"values": list[QuantityList(unit)]}, "__module__": __name__})


_MapFraction = _map_class("dimensionless", "MapFraction")
_MapForce = _map_class("N", "MapForce")
_MapPerVelocity = _map_class("s/m", "MapPerVelocity")
_MapVelocity = _map_class("m/s", "MapVelocity")


class InternalMaps(Model):
    """Seed 001 §5.2 internal parameters over body temperature [K] and excitation frequency [Hz]."""

    _must_be_positive = ("excitation_time_constant", "deflection_floor")

    temperatures: QuantityList("K")
    frequencies: QuantityList("Hz")
    # the excitation measure (struts.excitation): time constant of each stage of the mean-square filters
    # (the moving mean of the deflection takes twice it) and the deflection floor that makes the measure
    # read the lowest grid frequency at rest
    excitation_time_constant: Quantity("s") = 2.0
    deflection_floor: Quantity("m") = 1e-4
    gas_fraction: _MapFraction | None = None
    bleed_discharge_coefficient: _MapFraction | None = None
    check_discharge_coefficient: _MapFraction | None = None
    coulomb_compression: _MapForce | None = None
    coulomb_rebound: _MapForce | None = None
    peak_compression: _MapForce | None = None
    peak_rebound: _MapForce | None = None
    stribeck_coefficient_compression: _MapPerVelocity | None = None
    stribeck_coefficient_rebound: _MapPerVelocity | None = None
    transition_velocity_compression: _MapVelocity | None = None
    transition_velocity_rebound: _MapVelocity | None = None

    @model_validator(mode="after")
    def _grid(self):
        for name, grid in (("temperatures", self.temperatures), ("frequencies", self.frequencies)):
            if len(grid) < 1 or any(b <= a for a, b in zip(grid, grid[1:])):
                raise ValueError(f"{name} must be strictly increasing, got {grid}")
        if self.frequencies[0] <= 0:
            raise ValueError(f"frequencies must be > 0 Hz, got {self.frequencies[0]}")
        for name in INTERNAL_NAMES:
            m = getattr(self, name)
            if m is None:
                continue
            if len(m.values) != len(self.temperatures) or any(len(r) != len(self.frequencies) for r in m.values):
                raise ValueError(f"{name}.values must have {len(self.temperatures)} rows (temperatures) of "
                                 f"{len(self.frequencies)} values (frequencies)")
            if any(v < 0 for r in m.values for v in r):
                raise ValueError(f"{name}.values must be >= 0")
        return self

    def mapped(self) -> tuple[str, ...]:
        """Names of the internal parameters this file gives as maps."""
        return tuple(n for n in INTERNAL_NAMES if getattr(self, n) is not None)

    @property
    def uses_frequency(self) -> bool:
        """True when a map varies with frequency (then the strut carries the excitation states)."""
        return len(self.frequencies) > 1 and bool(self.mapped())


def map_value(maps: InternalMaps, name: str, T_K, f_Hz):
    """The mapped parameter `name` at body temperature T_K [K] and excitation frequency f_Hz [Hz] (SI unit of
    MAP_UNITS), clamped to the grid's edges; NumPy values or CasADi symbols."""
    m = getattr(maps, name)
    return sym.interp_bilinear(T_K, f_Hz, maps.temperatures, maps.frequencies, m.values)


def validity_warnings(maps: InternalMaps | None, T_K: float, f_Hz: float, where: str = "strut") -> list[str]:
    """Warnings when (T, f) leave the maps' grid (the values are then held at its edge)."""
    if maps is None or not maps.mapped():
        return []
    out = []
    T0, T1 = maps.temperatures[0], maps.temperatures[-1]
    f0, f1 = maps.frequencies[0], maps.frequencies[-1]
    if not T0 - 1e-9 <= T_K <= T1 + 1e-9:
        out.append(f"{where}: body temperature {T_K - 273.15:.1f} degC outside the internal maps' "
                   f"{T0 - 273.15:.0f}-{T1 - 273.15:.0f} degC: the values at the nearest edge are used")
    if len(maps.frequencies) > 1 and not f0 * (1 - 1e-9) <= f_Hz <= f1 * (1 + 1e-9):
        out.append(f"{where}: excitation frequency {f_Hz:.3g} Hz outside the internal maps' {f0:g}-{f1:g} Hz: "
                   "the values at the nearest edge are used")
    return out
