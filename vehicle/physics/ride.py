"""Ride metrics: ISO 2631-1 frequency weightings, absorbed power, seat motion, road-holding statistics.

What a suspension engineer reads from a drive besides temperatures:

* ISO 2631-1:1997 frequency-weighted acceleration at a seat: Wk (vertical) and Wd (horizontal)
  from the standard's Annex A transfer functions (band limiting high and low pass, acceleration-
  velocity transition, upward step), weighted RMS a_w = sqrt(int a_w^2 dt / T) and vibration dose
  value VDV = (int a_w^4 dt)^(1/4) (ISO 2631-1 §6.3, eq. 1 and 9), and the comfort bands of its
  Annex C.
* Absorbed power (Pradko & Lee 1966; Lins 1972), the 6 W criterion of off-road vehicle ride
  (the NATO Reference Mobility Model's ride-limiting speed): the seat's vertical acceleration
  through the absorbed-power filter, squared and averaged, is the power [W] the seated body
  dissipates.
* Seat acceleration from the hull's heave, pitch and roll (the kinematics of `hull.py`).
* Road holding: dynamic load coefficient (std / mean of the tyre load) from the integrals of F
  and F^2, strut-travel percentiles from a travel histogram.

The filters are continuous-time linear systems written as a cascade of first- and second-order
sections, each realised in a scaled controllable form whose states stay of the order of the
input (no 1e-6 states for the 100 Hz band limit). `LinearFilter.rates(states, u)` works on NumPy
values and CasADi symbols alike (`hpsim.symbolic` conventions), so the model can carry the filter
states and integrate a_w^2, a_w^4 and P_abs as quadratures during a drive without dense output.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hpsim import symbolic as sym

from vehicle.physics import hull as hull_eq
from vehicle.physics.params import GRAVITY

FEET_PER_METRE = 1.0 / 0.3048          # the absorbed-power filter is defined on acceleration in ft/s^2
INF = math.inf


# --- linear filters as cascades of sections ------------------------------------------------------
@dataclass(frozen=True)
class Section:
    """H(s) = (b[0] s^n + ... + b[n]) / (s^n + a[1] s^(n-1) + ... + a[n]), n = 1 or 2 (a[0] = 1).

    `num` has n + 1 coefficients (zeros allowed at the front), `den` has n + 1 with den[0] = 1.
    """

    num: tuple[float, ...]
    den: tuple[float, ...]

    @property
    def order(self) -> int:
        return len(self.den) - 1

    def response(self, s):
        return np.polyval(self.num, s) / np.polyval(self.den, s)

    def rates(self, x, u):
        """(state rates, output) of this section for states x (list) and input u.

        Second order, with w = sqrt(a2): x0' = w x1, x1' = -w x0 - a1 x1 + w u. Then
        X0 = a2 / D(s) U (unit DC gain: x0 is a low-passed u) and X1 = s X0 / w, and the output is
        y = b0 u + ((b2 - b0 a2) x0 + (b1 - b0 a1) w x1) / a2.
        First order: x0' = a1 (u - x0), y = b0 u + (b1 - b0 a1) x0 / a1.
        """
        if self.order == 2:
            b0, b1, b2 = self.num
            _, a1, a2 = self.den
            w = math.sqrt(a2)
            rates = [w * x[1], -w * x[0] - a1 * x[1] + w * u]
            y = b0 * u + ((b2 - b0 * a2) * x[0] + (b1 - b0 * a1) * w * x[1]) / a2
            return rates, y
        b0, b1 = self.num
        _, a1 = self.den
        return [a1 * (u - x[0])], b0 * u + (b1 - b0 * a1) * x[0] / a1


@dataclass(frozen=True)
class LinearFilter:
    """A SISO filter: gain x the cascade of `sections` (input first)."""

    name: str
    sections: tuple[Section, ...]
    gain: float = 1.0
    input_unit: str = "m/s^2"
    output_unit: str = "m/s^2"

    @property
    def n_states(self) -> int:
        return sum(s.order for s in self.sections)

    def rates(self, states, u):
        """(list of state rates, output y) for a list of states and the input u (numeric or symbolic)."""
        out, k, signal = [], 0, self.gain * u
        for sec in self.sections:
            r, signal = sec.rates(states[k:k + sec.order], signal)
            out.extend(r)
            k += sec.order
        return out, signal

    def frequency_response(self, f_hz) -> np.ndarray:
        """Complex H(j 2 pi f) from the section polynomials."""
        s = 2j * np.pi * np.asarray(f_hz, float)
        h = np.full(s.shape, self.gain, dtype=complex)
        for sec in self.sections:
            h = h * sec.response(s)
        return h

    def state_space(self):
        """(A, B, C, D) NumPy arrays of the realisation that `rates` integrates (read off `rates`)."""
        n = self.n_states
        A, C = np.zeros((n, n)), np.zeros((1, n))
        for j in range(n):
            e = np.zeros(n)
            e[j] = 1.0
            r, y = self.rates(list(e), 0.0)
            A[:, j], C[0, j] = r, y
        r, y = self.rates([0.0] * n, 1.0)
        return A, np.asarray(r, float).reshape(n, 1), C, np.array([[float(y)]])


def _second(num, w, q):
    """Section num / (s^2 + w s / q + w^2)."""
    return Section(tuple(float(v) for v in num), (1.0, w / q, w * w))


# --- ISO 2631-1 weightings -------------------------------------------------------------------------
@dataclass(frozen=True)
class Weighting:
    """Parameters of an ISO 2631-1:1997 Annex A frequency weighting (also ISO 8041 Table 3).

    f1, f2: band-limiting high / low pass corner [Hz] (Q1 = Q2 = 1/sqrt(2), second-order
    Butterworth); f3, f4, Q4: acceleration-velocity transition; f5, Q5, f6, Q6: upward step
    (inf: none).
    """

    name: str
    f1: float
    f2: float
    f3: float
    f4: float
    Q4: float
    f5: float = INF
    Q5: float = 1.0
    f6: float = INF
    Q6: float = 1.0
    Q1: float = 1.0 / math.sqrt(2.0)
    Q2: float = 1.0 / math.sqrt(2.0)


# ISO 2631-1:1997 Table A.2 (= ISO 8041:2005 Table 3): Wk vertical (z, seated, standing,
# recumbent), Wd horizontal (x, y), Wf motion sickness (vertical, 0.1-0.5 Hz)
WK = Weighting("Wk", f1=0.4, f2=100.0, f3=12.5, f4=12.5, Q4=0.63, f5=2.37, Q5=0.91, f6=3.35, Q6=0.91)
WD = Weighting("Wd", f1=0.4, f2=100.0, f3=2.0, f4=2.0, Q4=0.63)
WF = Weighting("Wf", f1=0.08, f2=0.63, f3=INF, f4=0.25, Q4=0.86, f5=0.0625, Q5=0.80, f6=0.10, Q6=0.80)
WEIGHTINGS = {"Wk": WK, "Wd": WD, "Wf": WF}


def iso2631_weighting(weighting: str | Weighting, upper_band_limit: bool = True) -> LinearFilter:
    """The weighting as a `LinearFilter` (ISO 2631-1:1997 Annex A, eq. A.1-A.4).

    H = H_h H_l H_t H_s:
      H_h = s^2 / (s^2 + w1 s / Q1 + w1^2)                  band-limiting high pass
      H_l = w2^2 / (s^2 + w2 s / Q2 + w2^2)                 band-limiting low pass
      H_t = (1 + s / w3) / (1 + s / (Q4 w4) + s^2 / w4^2)   acceleration-velocity transition
      H_s = (s^2 + w5 s / Q5 + w5^2) / (s^2 + w6 s / Q6 + w6^2)   upward step (gain (w5/w6)^2 at
            low, 1 at high frequency)
    upper_band_limit=False leaves out H_l (100 Hz for Wk and Wd): above the bandwidth of a
    ride model and of a 4 ms solver step (Nyquist 125 Hz), where its 630 rad/s poles would only
    make the filter stiff; it changes |W| by less than 0.1 % below 20 Hz.
    """
    p = WEIGHTINGS[weighting] if isinstance(weighting, str) else weighting
    two_pi = 2.0 * math.pi
    w1, w2, w4 = two_pi * p.f1, two_pi * p.f2, two_pi * p.f4
    sections = [_second((1.0, 0.0, 0.0), w1, p.Q1)]
    if upper_band_limit:
        sections.append(_second((0.0, 0.0, w2 * w2), w2, p.Q2))
    if math.isinf(p.f3):
        sections.append(_second((0.0, 0.0, w4 * w4), w4, p.Q4))
    else:
        w3 = two_pi * p.f3
        sections.append(_second((0.0, w4 * w4 / w3, w4 * w4), w4, p.Q4))
    if not math.isinf(p.f5):
        w5, w6 = two_pi * p.f5, two_pi * p.f6
        sections.append(_second((1.0, w5 / p.Q5, w5 * w5), w6, p.Q6))
    return LinearFilter(p.name, tuple(sections))


def absorbed_power_filter() -> LinearFilter:
    """Vertical absorbed-power filter: seat acceleration [m/s^2] -> y [sqrt(W)], P_abs = y^2.

    H(s) = 14.5 s (s + 44) / ((s + 63)(s^2 + 24 s + 750)) on the acceleration in ft/s^2. It is the
    continuous filter of the vertical absorbed-power method of Pradko & Lee (1966) as used by the
    NATO Reference Mobility Model (Lins 1972, "Human vibration response measurement", US Army
    TACOM Technical Report 11551). It is recovered exactly from the Tustin coefficients of Project
    Chrono's `ChAbsorbed_Power_Vertical` (src/chrono/utils/ChFilters.cpp). Its peak is near 4.5 Hz
    (the seated body's vertical resonance); 6 W is the commonly used limit of tolerable ride.
    """
    return LinearFilter("absorbed_power",
                        (Section((0.0, 14.5), (1.0, 63.0)), Section((1.0, 44.0, 0.0), (1.0, 24.0, 750.0))),
                        gain=FEET_PER_METRE, output_unit="sqrt(W)")


# --- metrics from quadratures ---------------------------------------------------------------------
def weighted_rms(integral_aw2, duration_s):
    """a_w [m/s^2] = sqrt(int a_w^2 dt / T) (ISO 2631-1 eq. 1)."""
    return np.sqrt(np.maximum(np.asarray(integral_aw2, float), 0.0) / max(float(duration_s), 1e-300))


def vibration_dose_value(integral_aw4):
    """VDV [m/s^1.75] = (int a_w^4 dt)^(1/4) (ISO 2631-1 eq. 9)."""
    return np.maximum(np.asarray(integral_aw4, float), 0.0) ** 0.25


def combine_vdv(values):
    """VDV of consecutive periods: (sum VDV_i^4)^(1/4) (ISO 2631-1 §6.3.2)."""
    return float(np.sum(np.asarray(values, float) ** 4) ** 0.25)


# ISO 2631-1:1997 Annex C.2.3: likely reactions to overall vibration total values in public
# transport; the bands overlap on purpose (the standard gives them so)
COMFORT_BANDS = ((0.0, 0.315, "not uncomfortable"), (0.315, 0.63, "a little uncomfortable"),
                 (0.5, 1.0, "fairly uncomfortable"), (0.8, 1.6, "uncomfortable"),
                 (1.25, 2.5, "very uncomfortable"), (2.0, INF, "extremely uncomfortable"))


def comfort_band(a_w_m_s2: float) -> str:
    """ISO 2631-1 Annex C comfort reaction for a weighted RMS acceleration [m/s^2].

    In the overlaps both names are given ("fairly uncomfortable to uncomfortable").
    """
    a = float(a_w_m_s2)
    if not math.isfinite(a) or a < 0:
        raise ValueError(f"weighted acceleration must be a finite value >= 0 m/s^2, got {a_w_m_s2!r}")
    names = [name for lo, hi, name in COMFORT_BANDS if lo <= a < hi] or [COMFORT_BANDS[-1][2]]
    return names[0] if len(names) == 1 else f"{names[0]} to {names[-1]}"


def dynamic_load_coefficient(integral_F, integral_F2, duration_s):
    """DLC = std(F) / mean(F) of a tyre load from int F dt and int F^2 dt over T (Cole & Cebon)."""
    T = max(float(duration_s), 1e-300)
    mean = np.asarray(integral_F, float) / T
    var = np.maximum(np.asarray(integral_F2, float) / T - mean * mean, 0.0)
    return np.sqrt(var) / np.where(mean > 0, mean, np.nan)


# --- seat kinematics ------------------------------------------------------------------------------
def seat_vertical_acceleration(heave_acc, pitch_acc, roll_acc, x_from_cg_m, y_from_cg_m):
    """Vertical acceleration [m/s^2] of a hull point x behind and y left of the sprung CG.

    The hull kinematics of `hull.py` (small angles): z_seat = z - theta x + phi y, so
    a_seat = z'' - theta'' x + phi'' y (pitch + nose up, roll + left side up).
    """
    return hull_eq.station_displacement(heave_acc, pitch_acc, roll_acc, x_from_cg_m, y_from_cg_m, 0.0, 0.0)


def seat_lateral_acceleration(roll_acc, roll_rad, z_from_cg_m, gravity=GRAVITY):
    """Lateral acceleration [m/s^2, + left] a seat accelerometer z above the CG reads in hull roll.

    The hull rolls about its CG (the model has no lateral DOF): the seat moves -z phi sideways
    (phi + left side up), and the tilted sensor also reads the gravity component g phi.
    """
    return -z_from_cg_m * roll_acc + gravity * roll_rad


# --- strut travel ---------------------------------------------------------------------------------
def travel_percentiles(time_in_bins_s, bin_edges_m, percentiles=(1, 5, 50, 95, 99)):
    """Strut travel [m] at the given percentiles of time, from the time spent in each travel bin.

    time_in_bins_s: (..., n_bins) time per bin (one row per strut); bin_edges_m: n_bins + 1
    increasing edges. The travel is taken uniformly distributed within a bin (linear
    interpolation of the cumulative time). Returns (..., len(percentiles)); NaN for a row
    without time.
    """
    h = np.asarray(time_in_bins_s, float)
    edges = np.asarray(bin_edges_m, float)
    if edges.ndim != 1 or len(edges) != h.shape[-1] + 1 or np.any(np.diff(edges) <= 0):
        raise ValueError(f"bin_edges_m: expected {h.shape[-1] + 1} increasing edges, got {edges.shape}")
    q = np.asarray(percentiles, float) / 100.0
    rows = h.reshape(-1, h.shape[-1])
    out = np.full((rows.shape[0], len(q)), np.nan)
    for k, row in enumerate(rows):
        total = row.sum()
        if total > 0:
            row = np.maximum(row, 0.0)
            cum = np.concatenate([[0.0], np.cumsum(row)]) / total
            # keep the edges that touch a bin with time: runs of empty bins would make the
            # cumulative flat and the inverse ambiguous
            used = row > 0
            keep = np.concatenate([[False], used]) | np.concatenate([used, [False]])
            out[k] = np.interp(q, cum[keep], edges[keep])
    return out.reshape(h.shape[:-1] + (len(q),))


# --- building blocks for the model: per-seat filter states and quadrature integrands -------------
@dataclass(frozen=True)
class SeatFilters:
    """The filters a seat carries in a drive: Wk on its vertical, Wd on its lateral acceleration
    (both without the 100 Hz band limit, see `iso2631_weighting`) and the absorbed-power filter.

    A model adds `state_names(seat)` to its states and `QUADRATURES` (per seat) to its
    quadratures, and sets their rates from `rates(states, a_vertical, a_lateral)`:
      I_aw2  = int a_w^2 dt (Wk)       -> weighted_rms_acceleration_m_s2 = sqrt(dI / T)
      I_aw4  = int a_w^4 dt (Wk)       -> vdv_m_s175 = dI^(1/4)
      I_awl2 = int a_wl^2 dt (Wd, lateral) -> weighted_rms_lateral_acceleration_m_s2
      I_pabs = int P_abs dt            -> absorbed_power_W = dI / T
    """

    vertical: LinearFilter
    lateral: LinearFilter
    power: LinearFilter

    QUADRATURES = ("aw2", "aw4", "awl2", "pabs")

    @classmethod
    def default(cls) -> "SeatFilters":
        return cls(iso2631_weighting(WK, upper_band_limit=False), iso2631_weighting(WD, upper_band_limit=False),
                   absorbed_power_filter())

    @property
    def n_states(self) -> int:
        return self.vertical.n_states + self.lateral.n_states + self.power.n_states

    def state_names(self, seat: str) -> list[str]:
        return ([f"wk_{seat}[{j}]" for j in range(self.vertical.n_states)]
                + [f"wd_{seat}[{j}]" for j in range(self.lateral.n_states)]
                + [f"ap_{seat}[{j}]" for j in range(self.power.n_states)])

    def rates(self, states, a_vertical, a_lateral):
        """(state rates in `state_names` order, {quadrature: integrand}) for a seat's states (a list)."""
        nk, nd = self.vertical.n_states, self.lateral.n_states
        rk, yk = self.vertical.rates(states[:nk], a_vertical)
        rd, yd = self.lateral.rates(states[nk:nk + nd], a_lateral)
        rp, yp = self.power.rates(states[nk + nd:], a_vertical)
        yk2 = yk * yk
        return rk + rd + rp, {"aw2": yk2, "aw4": yk2 * yk2, "awl2": yd * yd, "pabs": yp * yp}

    # --- velocity-driven form (what the vehicle model integrates) ---------------------------------
    # The seat's accelerations are the rates of the hull velocities. A fixed-step solver evaluates them
    # at its stages, the second at a predicted state, where stiff seal friction and end stops make
    # them unreliable; the velocities are states, accurate at every stage. W(s) a = (W(s) s) v
    # (`derivative_input`): the same weighted signal from the velocity. The lateral reading
    # a_l = -z phi'' + g phi (seat_lateral_acceleration) is split: the roll velocity term through
    # Wd s, the gravity term g phi (a state) through Wd; the outputs add (a linear filter).
    def velocity_state_names(self, seat: str) -> list[str]:
        return ([f"wk_{seat}[{j}]" for j in range(self.vertical.n_states)]
                + [f"wd_{seat}[{j}]" for j in range(self.lateral.n_states)]
                + [f"wdg_{seat}[{j}]" for j in range(self.lateral.n_states)]
                + [f"ap_{seat}[{j}]" for j in range(self.power.n_states)])

    def rates_from_velocity(self, states, v_vertical, v_lateral, a_lateral_rest):
        """(state rates in `velocity_state_names` order, {quadrature: integrand}) from the seat's vertical
        velocity [m/s], the velocity part of its lateral motion [m/s] (-z phi') and the rest of its
        lateral reading [m/s^2] (g phi)."""
        nk, nd = self.vertical.n_states, self.lateral.n_states
        rk, yk = derivative_input(self.vertical).rates(states[:nk], v_vertical)
        rd, yd1 = derivative_input(self.lateral).rates(states[nk:nk + nd], v_lateral)
        rg, yd2 = self.lateral.rates(states[nk + nd:nk + 2 * nd], a_lateral_rest)
        rp, yp = derivative_input(self.power).rates(states[nk + 2 * nd:], v_vertical)
        yk2, yd = yk * yk, yd1 + yd2
        return rk + rd + rg + rp, {"aw2": yk2, "aw4": yk2 * yk2, "awl2": yd * yd, "pabs": yp * yp}


def tyre_integrands(tyre_force_N, lift_off_force_N=0.0):
    """Integrands of a wheel's road-holding quadratures: (F, F^2, 1 while lifted off).

    int F dt and int F^2 dt give the dynamic load coefficient (`dynamic_load_coefficient`); the
    third integrates to the time off the ground (F <= lift_off_force_N; the smoothed tyre law of
    tyre.py is exactly 0 there)."""
    return tyre_force_N, tyre_force_N * tyre_force_N, sym.if_else(tyre_force_N <= lift_off_force_N, 1.0, 0.0)


def end_stop_indicator(deflection_m, stroke_m):
    """1 while a strut is beyond full extension (x < 0) or full compression (x > stroke), else 0."""
    return sym.if_else(deflection_m < 0.0, 1.0, sym.if_else(deflection_m > stroke_m, 1.0, 0.0))


def travel_bin_indicators(deflection_m, bin_edges_m):
    """One indicator per travel bin [edge_k, edge_k+1) (the first and last bins take everything
    beyond the edges), to integrate into the time spent in each bin (`travel_percentiles`)."""
    edges = list(bin_edges_m)
    out = []
    for k in range(len(edges) - 1):
        above = 1.0 if k == 0 else sym.if_else(deflection_m >= edges[k], 1.0, 0.0)
        below = 1.0 if k == len(edges) - 2 else sym.if_else(deflection_m < edges[k + 1], 1.0, 0.0)
        out.append(above * below)
    return out


def travel_exceedance_indicators(deflection_m, inner_edges_m):
    """One indicator per inner travel-bin edge: 1 while the deflection is at or above it.

    Integrated, they give the time above each edge, from which `travel_histogram` gives the time in
    every bin of `travel_bin_indicators` with one comparison per edge instead of two per bin."""
    return [sym.if_else(deflection_m >= e, 1.0, 0.0) for e in inner_edges_m]


def travel_histogram(time_above_s, duration_s):
    """Time in each travel bin [s] (..., n_bins) from the time above each inner edge (n_bins - 1, ...)
    over a duration: bin 0 = T - above_1, bin k = above_k - above_k+1, last bin = above_last (the
    outer bins open, as in `travel_bin_indicators`)."""
    above = np.asarray(time_above_s, float)
    T = np.broadcast_to(np.asarray(duration_s, float), above.shape[1:])
    cum = np.concatenate([T[None], above, np.zeros((1,) + above.shape[1:])], axis=0)
    return np.moveaxis(np.maximum(cum[:-1] - cum[1:], 0.0), 0, -1)


def travel_range(time_in_bins_s, bin_edges_m):
    """(min, max) strut travel [m] to the bin resolution from the time in each bin (..., n_bins) and
    the edges (..., n_bins + 1): the lower edge of the first and the upper edge of the last bin with
    time (NaN without time). The outer bins are open: a minimum at the first edge or a maximum at
    the last one means 'at or beyond it'."""
    h = np.asarray(time_in_bins_s, float)
    edges = np.broadcast_to(np.asarray(bin_edges_m, float), h.shape[:-1] + (h.shape[-1] + 1,))
    used = h > 1e-9 * np.sum(np.abs(h), axis=-1, keepdims=True)    # round-off of T - above_1 is no time
    any_ = used.any(axis=-1)
    first = np.argmax(used, axis=-1)
    last = h.shape[-1] - 1 - np.argmax(used[..., ::-1], axis=-1)
    lo = np.take_along_axis(edges, first[..., None], -1)[..., 0]
    hi = np.take_along_axis(edges, last[..., None] + 1, -1)[..., 0]
    return np.where(any_, lo, np.nan), np.where(any_, hi, np.nan)


def derivative_input(flt: LinearFilter) -> LinearFilter:
    """The filter H(s) s: driven by the integral of the signal (a velocity instead of an acceleration),
    it gives the same output. The first strictly proper section takes the s into its numerator
    (b1 s + b2 -> b1 s^2 + b2 s), so the cascade stays proper; the filter must have one."""
    sections = list(flt.sections)
    for k, sec in enumerate(sections):
        if sec.num[0] == 0.0:
            sections[k] = Section(tuple(sec.num[1:]) + (0.0,), sec.den)
            return LinearFilter(flt.name + "_v", tuple(sections), flt.gain, flt.input_unit.replace("/s^2", "/s"),
                                flt.output_unit)
    raise ValueError(f"filter {flt.name}: no strictly proper section to take a derivative")
