"""What an instrument would read: measurement models with priors (docs/measurements.md; REFERENCE §10-11).

The simulator predicts states (the mean outer skin of a strut, the oil, the hull at an axle in its frictionless
standing equilibrium, the wheel loads there). A test reads something else: a pyrometer a visible spot of the
skin some minutes after the vehicle stopped, photogrammetry a reference line on the hull standing on warm tyres,
a scale the load a strut held by its seals leaves on the wheel. Each model below turns a predicted state into
the reading, drawing its assumptions from priors (each with its source, `PRIORS`), per station (every wheel's
strut is read on its own: spot, emissivity) or per drive (the delay: one walk round the vehicle).

Pyrometer (surface_temperature), a reading of station i (before and after the drive alike):
    T_hot  = T_s + h (T_oil - T_s)                the hottest skin, over the valve end, between the mean skin
                                                  (the model's surface node) and the oil (it cannot exceed it)
    T_spot = T_hot - f (T_hot - T_bg)             the visible spot below the hidden hottest part by a fraction f
                                                  of its excess over the ambient (the skin loses heat to the
                                                  ambient in proportion to that excess: no excess, no deficit)
    T_read = radiometric(T_spot, eps, eps_set, T_bg) + noise

The temperatures are those of the standing network (`standing_network`: no driving power, no wind) `delay` after the
stop; before the drive every node stands at the start temperature. Here radiometric(...) is what a broadband IR
thermometer set to eps_set shows for a grey surface of emissivity eps before a background at T_bg (the ambient):
eps_set T_r^4 + (1 - eps_set) T_bg^4 = eps T^4 + (1 - eps) T_bg^4 (the radiometric equation, e.g. Incropera 7th ed.
§12.4 with the instrument's emissivity compensation). One station's h, f and eps are drawn once and read both times
(the same instrument on the same spot), so a change's offset is the difference of the two readings' offsets: about
zero for a strut that did not warm.

Thermocouple (oil_temperature): T_oil after the delay + noise.

Photogrammetry (height), after minus before at axle k:
    dh_read = dh_friction + dh_tyre + dh_cool + noise

The friction term dh_friction is uniform in the seal-friction band of the two standing poses
(vehicle.physics.weighing, `dh_band_mm` of the report; the frictionless dh when the results hold no band). The
tyre term dh_tyre is the lift of tyres warmed by the drive (`tyre_lift_m`: inflation pressure up with the absolute
air temperature, stiffness ~ p + p_carcass, static deflection W/k_t down). The cooling term dh_cool is the sinking
of the hull while the struts cool during the delay, linear in
the oil temperature's drop (the gas follows the oil through the floating piston in 10-60 s, and both expand
linearly in T): dh_cool = dh_model (T_oil(delay) - T_oil,end) / (T_oil,end - T_start).

Scale (wheel_load), after minus before: uniform in the friction band of the two weighings (`dN_band_pct`), the
frictionless change without a band; plus noise. The change of the load while the struts cool is left out (all
struts cool alike: it shifts the loads by a fraction of the after-drive change).

Noise: normal with the reading's standard uncertainty (the measurement file), one draw per reading (a change:
two readings).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hpsim.errors import UserInputError
from hpsim.priors import Prior, parse_prior
from struts.model import make_strut
from struts.params import StrutParams

from vehicle.physics import thermal
from vehicle.physics.params import VehicleParams

STEFAN_BOLTZMANN = 5.670374419e-8   # W/(m^2 K^4), CODATA 2018
ATMOSPHERE_PA = 101325.0            # standard atmosphere (gauge -> absolute inflation pressure)

# measurement-model priors: {value, prior, source} as in parameter files (hpsim.priors), in SI after parsing
PRIOR_SPECS = {
    "pyrometer.hot_fraction": {
        "value": 0.5, "prior": {"uniform": [0.0, 1.0]},
        "source": "assumed: the hottest skin (over the valve end, hidden by the wheel, seed 000 §4.4) lies between "
                  "the mean skin (the heat network's surface node, h = 0) and the oil (h = 1: the oil wets the "
                  "wall there; the skin cannot be hotter than the oil with no heat source outside)"},
    "pyrometer.spot_deficit_fraction": {
        "value": 0.0925, "prior": {"uniform": [0.0, 0.185]},
        "source": "REFERENCE §11 / §10: the visible surface 0-10 K below the part hidden by the wheel (seed 000 "
                  "§4.4) with the skin about 54 K above the ambient (REFERENCE §4): 0-10/54 of the excess"},
    "pyrometer.emissivity": {
        "value": 0.925, "prior": {"uniform": [0.90, 0.95]},
        "source": "REFERENCE §11: painted or oxidised steel 0.90-0.95 (emissivity tables)"},
    "delay": {
        "value": "12.5 min", "prior": {"uniform": ["5 min", "20 min"]},
        "source": "REFERENCE §10-11: 5-20 min from stopping to reading temperatures, heights and loads "
                  "(the vehicle drives to the scale and stops); the measurement file's instrument `delay` "
                  "replaces it; one draw per drive"},
    "tyre.air_temperature_rise": {
        "value": "27.5 K", "prior": {"uniform": ["15 K", "40 K"]},
        "source": "REFERENCE §11: tyre carcass/air temperature rise after hours of off-road driving at "
                  "~20 km/h, large off-road tyres, mostly hysteresis heating; the tyre's own cooling over the "
                  "delay neglected (a 14.00R20 carcass cools over hours)"},
    "tyre.inflation_pressure": {
        "value": "3.5 bar", "prior": {"uniform": ["2 bar", "5 bar"]},
        "source": "vehicle file tyre.stiffness prior: 14.00R20 at 2-5 bar (central tyre inflation lowered off "
                  "road); gauge pressure"},
    "tyre.carcass_pressure_fraction": {
        "value": 0.15, "prior": {"uniform": [0.10, 0.20]},
        "source": "REFERENCE §11: tyre vertical stiffness ~ (p + p_carcass), p_carcass 0.1-0.2 of the rated "
                  "pressure (tyre handbooks); here of the inflation pressure"},
}
# fixed settings of the models (no prior: one value with its source)
EMISSIVITY_SETTING = 0.95   # REFERENCE §11 ("0.95 set"): the usual default of handheld IR thermometers; a
                            # measurement file's instrument `emissivity_setting` replaces it
PRIORS: dict[str, Prior] = {k: parse_prior(v, k, "vehicle.analysis.instruments") for k, v in PRIOR_SPECS.items()}
# which priors a reading of each instrument type uses (and whether per station)
STATION_PRIORS = ("pyrometer.hot_fraction", "pyrometer.spot_deficit_fraction", "pyrometer.emissivity")
DRIVE_PRIORS = ("delay", "tyre.air_temperature_rise", "tyre.inflation_pressure",
                "tyre.carcass_pressure_fraction")


def draw(name: str, rng: np.random.Generator, shape) -> np.ndarray:
    """Draws of a measurement-model prior [SI] (inverse-CDF of uniform random numbers)."""
    return np.asarray(PRIORS[name].ppf(rng.random(shape)), float)


# --- physics of the readings -------------------------------------------------------------------------
def radiometric_reading_K(T_K, emissivity, emissivity_setting, T_background_K):
    """Temperature a broadband IR thermometer set to `emissivity_setting` shows for a grey surface at T_K
    with `emissivity` before a background at T_background_K (module docstring; Incropera §12.4)."""
    T_K, Tb = np.asarray(T_K, float), np.asarray(T_background_K, float)
    W = emissivity * T_K ** 4 + (emissivity_setting - emissivity) * Tb ** 4
    return (W / emissivity_setting) ** 0.25


def tyre_lift_m(static_deflection_m, air_rise_K, T_start_K, gauge_pressure_Pa, carcass_fraction):
    """Hull lift [m] from warm tyres at a wheel: the inflation pressure rises with the absolute air temperature
    at constant volume (ideal gas, p_abs2 = p_abs1 T2/T1), the vertical stiffness ~ p + p_carcass
    (p_carcass = carcass_fraction p), the static deflection W/k falls: lift = d0 (1 - k1/k2)."""
    dp = (gauge_pressure_Pa + ATMOSPHERE_PA) * air_rise_K / T_start_K
    k1 = gauge_pressure_Pa * (1.0 + carcass_fraction)
    return static_deflection_m * (1.0 - k1 / (k1 + dp))


@dataclass
class StandingNetwork:
    """The strut heat network of every station standing still (no driving power, vehicle speed 0), from the
    stored vehicle and strut parameters of a results file (vehicle.physics.thermal)."""

    heat: object
    envs: list
    struts: list
    T_ambient_K: float

    @classmethod
    def from_resolved(cls, resolved: dict, n_stations: int) -> "StandingNetwork":
        V = VehicleParams.model_validate(resolved["vehicle"])
        per_axle = n_stations // len(V.axles)
        envs = [thermal.station_environment(V.heat, V.axles[i // per_axle].heat) for i in range(n_stations)]
        struts_by_axle = [make_strut(StrutParams.model_validate(resolved["struts"][f"axle{k + 1}"]), check=False)
                          for k in range(len(V.axles))]
        return cls(V.heat, envs, [struts_by_axle[i // per_axle] for i in range(n_stations)],
                   float(resolved["scenario"]["ambient_temperature"]))

    def rates(self, T: np.ndarray) -> np.ndarray:
        n = len(self.envs)
        out = np.empty(3 * n)
        for i, (env, s) in enumerate(zip(self.envs, self.struts)):
            To, Tw, Ts = T[i], T[n + i], T[2 * n + i]
            Pr = thermal.oil_prandtl(self.heat, s.oil_viscosity(s.p.oil.reference_temperature), s.p.oil.density)
            f = thermal.network_flows(self.heat, env, To, Tw, Ts, self.T_ambient_K, 0.0, 0.0, s.oil_viscosity(To),
                                      s.oil_density(To), s.p.oil.expansion, Pr)
            out[i], out[n + i], out[2 * n + i] = thermal.network_rates(self.heat, f, 0.0, 0.0, 0.0, 0.0)
        return out

    def cool(self, T_oil, T_wall, T_surface, times_s) -> np.ndarray:
        """Node temperatures [K], shape (3 nodes: oil, wall, surface; stations; times), after standing
        `times_s` from the given end state (BDF: the wall-surface pair has a time constant of seconds)."""
        from scipy.integrate import solve_ivp

        times_s = np.atleast_1d(np.asarray(times_s, float))
        y0 = np.concatenate([np.asarray(T_oil, float), np.asarray(T_wall, float), np.asarray(T_surface, float)])
        if times_s.max() <= 0:
            return np.repeat(y0.reshape(3, -1)[:, :, None], times_s.size, axis=2)
        order = np.unique(np.concatenate([[0.0], times_s]))
        sol = solve_ivp(lambda t, y: self.rates(y), (0.0, order[-1]), y0, method="BDF", t_eval=order,
                        rtol=1e-6, atol=1e-4)
        if not sol.success:
            raise UserInputError(f"the standing heat network could not be integrated: {sol.message}")
        Y = np.stack([np.interp(times_s, sol.t, row) for row in sol.y])
        return Y.reshape(3, len(y0) // 3, times_s.size)


# --- readings ------------------------------------------------------------------------------------------
@dataclass
class PyrometerSpot:
    """The drawn assumptions of one station's pyrometer readings (arrays of n draws): the hottest skin's place
    between surface and oil `hot_fraction`, the visible spot's deficit `spot_deficit_fraction` of its excess over
    the ambient, the true `emissivity` (module docstring)."""

    hot_fraction: np.ndarray
    spot_deficit_fraction: np.ndarray
    emissivity: np.ndarray

    @classmethod
    def draw(cls, rng: np.random.Generator, n: int) -> "PyrometerSpot":
        return cls(*(draw(name, rng, n) for name in STATION_PRIORS))


def pyrometer_reading_K(T_oil, T_surface, T_background_K, spot: PyrometerSpot, emissivity_setting=None) -> np.ndarray:
    """The pyrometer reading of one station [K] (no noise) for the oil and surface temperatures at the moment of
    reading (arrays broadcast against the n draws of `spot`), the ambient T_background_K (module docstring)."""
    eps_set = EMISSIVITY_SETTING if emissivity_setting is None else emissivity_setting
    T_hot = T_surface + spot.hot_fraction * (T_oil - T_surface)
    T_spot = T_hot - spot.spot_deficit_fraction * (T_hot - T_background_K)
    return radiometric_reading_K(T_spot, spot.emissivity, eps_set, T_background_K)


def uniform_in_band(low, high, rng, n) -> np.ndarray:
    """Draws anywhere in a friction band [low, high] (each standing pose equally likely: the approach leaves
    each strut anywhere in its band, vehicle.physics.weighing)."""
    return low + (high - low) * rng.random(n)


def noise(u: float, rng, n, readings: int = 1) -> np.ndarray:
    """Instrument noise of `readings` independent readings combined by difference (a change) [SI]."""
    return rng.normal(0.0, u * math.sqrt(readings), n)


def priors_table() -> list[dict]:
    """The measurement-model priors with their sources (for reports and docs)."""
    return [{"name": k, "prior": p.describe(), "per": "station" if k in STATION_PRIORS else "drive",
             "source": p.note} for k, p in PRIORS.items()]


# standard uncertainty of one reading of the usual instruments of a mileage test, for predicted readings
# without a measurement file (`hpsim validate PREDICTION` alone): quantity -> (instrument, value, source)
STANDARD_INSTRUMENTS = {
    "surface_temperature": ("pyrometer", "1 K", "assumed: handheld IR thermometer, +-1 K or +-1 % of the reading "
                                                "(typical data sheets), read as a standard uncertainty"),
    "height": ("photogrammetry", "3.5 mm", "REFERENCE §11: +-2-5 mm per reading (close-range photogrammetry of a "
                                           "marked line at a few metres); the middle as a standard uncertainty"),
    "wheel_load": ("scale", "25 daN", "REFERENCE §11: stationary overrun scale +-0.5-1 % of the wheel load (class "
                                      "III/IIII): 0.75 % of 3300 daN"),
}
