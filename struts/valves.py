"""Hydraulic flow laws of a damping valve assembly (REFERENCE §7; seed 001 eq. 12).

Sign convention: dp_Pa is the pressure of the chamber that is squeezed in compression minus
the other one (seed 001: p_c - p_r), and q_m3_s > 0 is the flow leaving that chamber, so the
flow has the sign of dp and dp * q >= 0 is the power dissipated in the valve [W].

Every function is pure and accepts NumPy values or CasADi SX/MX symbols (math through
`hpsim.symbolic`). Every coefficient is an argument; nothing here has a default value
except the iteration count of the numerical inverse.
"""
from __future__ import annotations

from hpsim import symbolic as sym

__all__ = [
    "orifice_flow",
    "orifice_pressure_drop",
    "check_valve_area",
    "relief_valve_area",
    "leakage_flow",
    "valve_opening_area",
    "valve_flow",
    "valve_pressure_drop",
]


# --- single elements ------------------------------------------------------------------------

def _orifice_coefficient(cd, area_m2, rho_kg_m3):
    """C_d A sqrt(2/rho) [m^3/s per sqrt(Pa)]."""
    return cd * area_m2 * sym.sqrt(2.0 / rho_kg_m3)


def _flow_function(dp_Pa, p_crit_Pa):
    """phi(dp) = dp / (dp^2 + p_cr^2)^(1/4) [sqrt(Pa)]: odd, ~sgn(dp) sqrt|dp| above p_cr."""
    return dp_Pa / sym.sqrt(sym.sqrt(dp_Pa * dp_Pa + p_crit_Pa * p_crit_Pa))


def _flow_function_inverse(w, p_crit_Pa):
    """dp(w) with phi(dp) = w, exact: dp = w sqrt((w^2 + sqrt(w^4 + 4 p_cr^2)) / 2).

    From phi^4 = dp^4 / (dp^2 + p_cr^2): a quadratic in dp^2 whose positive root is
    dp^2 = w^2 (w^2 + sqrt(w^4 + 4 p_cr^2)) / 2; the sign of dp is that of w.
    """
    w2 = w * w
    return w * sym.sqrt(0.5 * (w2 + sym.sqrt(w2 * w2 + 4.0 * p_crit_Pa * p_crit_Pa)))


def _flow_function_inverse_derivative(w, p_crit_Pa):
    """d dp / d w of `_flow_function_inverse` [sqrt(Pa)], > 0 for p_cr > 0."""
    w2 = w * w
    S = sym.sqrt(w2 * w2 + 4.0 * p_crit_Pa * p_crit_Pa)
    R = 0.5 * (w2 + S)
    return sym.sqrt(R) * (1.0 + w2 / S)


def orifice_flow(dp_Pa, cd, area_m2, rho_kg_m3, p_crit_Pa):
    """Orifice flow [m^3/s] q = C_d A sqrt(2/rho) dp / (dp^2 + p_cr^2)^(1/4) (REFERENCE §7, seed 001 eq. 12).

    Turbulent q -> C_d A sqrt(2|dp|/rho) sgn(dp) for |dp| >> p_cr, laminar (linear,
    q ~ C_d A sqrt(2/rho) dp / sqrt(p_cr)) for |dp| << p_cr; odd in dp and C-infinity
    for p_cr > 0. rho in kg/m^3, area in m^2, pressures in Pa.
    """
    return _orifice_coefficient(cd, area_m2, rho_kg_m3) * _flow_function(dp_Pa, p_crit_Pa)


def orifice_pressure_drop(q_m3_s, cd, area_m2, rho_kg_m3, p_crit_Pa):
    """Pressure drop [Pa] that drives q [m^3/s] through the orifice: exact inverse of `orifice_flow`.

    Squaring orifice_flow twice gives a quadratic in dp^2 (REFERENCE §7 orifice law):
    dp = w sqrt((w^2 + sqrt(w^4 + 4 p_cr^2)) / 2), w = q / (C_d A sqrt(2/rho)).
    """
    w = q_m3_s / _orifice_coefficient(cd, area_m2, rho_kg_m3)
    return _flow_function_inverse(w, p_crit_Pa)


def check_valve_area(dp_Pa, area_max_m2, dp_crack_Pa, dp_full_Pa):
    """Check-valve opening area [m^2]: 0 for dp <= dp_crack, C1 ramp to area_max at dp >= dp_full.

    One-way (seed 001 eq. 12: q_c = 0 for p_c <= p_r); opens only for positive dp.
    Needs dp_full_Pa > dp_crack_Pa >= 0.
    """
    return area_max_m2 * sym.smooth_step(dp_Pa, dp_crack_Pa, dp_full_Pa)


def relief_valve_area(dp_Pa, area_max_m2, p_crack_Pa, p_full_Pa):
    """Relief (blow-off) valve opening area [m^2] for positive dp (REFERENCE §7).

    0 below the cracking pressure difference, C1 ramp to area_max at the full-open pressure
    difference (p_full_Pa > p_crack_Pa >= 0). Call with -dp for the rebound direction.
    """
    return area_max_m2 * sym.smooth_step(dp_Pa, p_crack_Pa, p_full_Pa)


def leakage_flow(dp_Pa, k_leak_m3_per_Pa_s):
    """Laminar leakage [m^3/s] past guide rings / clearances: q_l = k_l dp (seed 001 eq. 12)."""
    return k_leak_m3_per_Pa_s * dp_Pa


# --- the assembly --------------------------------------------------------------------------

def _smooth_step_derivative(x, x0, x1):
    """d/dx of hpsim.symbolic.smooth_step (0 outside [x0, x1])."""
    s = (x - x0) / (x1 - x0)
    s = sym.fmin(sym.fmax(s, 0.0), 1.0)
    return 6.0 * s * (1.0 - s) / (x1 - x0)


def valve_opening_area(dp_Pa, *, bleed_area, check_area_max, check_dp_crack, check_dp_full,
                       relief_comp_area, relief_comp_crack, relief_comp_full,
                       relief_reb_area, relief_reb_crack, relief_reb_full):
    """Total open area [m^2] at pressure difference dp [Pa]: bleed + check (dp > 0) + relief per direction.

    Non-decreasing in |dp| on each side, >= bleed_area.
    """
    return (bleed_area
            + check_valve_area(dp_Pa, check_area_max, check_dp_crack, check_dp_full)
            + relief_valve_area(dp_Pa, relief_comp_area, relief_comp_crack, relief_comp_full)
            + relief_valve_area(-dp_Pa, relief_reb_area, relief_reb_crack, relief_reb_full))


def _valve_opening_area_derivative(dp_Pa, *, bleed_area, check_area_max, check_dp_crack, check_dp_full,
                                   relief_comp_area, relief_comp_crack, relief_comp_full,
                                   relief_reb_area, relief_reb_crack, relief_reb_full):
    """d(area)/d(dp) [m^2/Pa] of `valve_opening_area`."""
    return (check_area_max * _smooth_step_derivative(dp_Pa, check_dp_crack, check_dp_full)
            + relief_comp_area * _smooth_step_derivative(dp_Pa, relief_comp_crack, relief_comp_full)
            - relief_reb_area * _smooth_step_derivative(-dp_Pa, relief_reb_crack, relief_reb_full))


_AREA_KEYS = ("bleed_area", "check_area_max", "check_dp_crack", "check_dp_full",
              "relief_comp_area", "relief_comp_crack", "relief_comp_full",
              "relief_reb_area", "relief_reb_crack", "relief_reb_full")


def valve_flow(dp_Pa, *, cd, rho, p_crit, bleed_area, check_area_max, check_dp_crack, check_dp_full,
               relief_comp_area, relief_comp_crack, relief_comp_full,
               relief_reb_area, relief_reb_crack, relief_reb_full, k_leak, check_p_crit=None):
    """Total flow [m^3/s] through a damping valve assembly at pressure difference dp [Pa].

    Bleed orifice (always open) + check valve (opens for dp > 0, compression) + one relief
    (blow-off) valve per direction: the areas add and the sum passes through `orifice_flow`
    (cd, rho [kg/m^3], p_crit [Pa]). Laminar leakage k_leak [m^3/(Pa s)] is added (seed 001 eq. 12,
    REFERENCE §7). check_p_crit [Pa]: the check valve's own laminar-turbulent transition
    (`struts.orifice`), its area then passing through its own orifice law. Odd-like and strictly
    increasing in dp (for bleed_area > 0).
    """
    area = valve_opening_area(
        dp_Pa, bleed_area=bleed_area, check_area_max=0.0 if check_p_crit is not None else check_area_max,
        check_dp_crack=check_dp_crack,
        check_dp_full=check_dp_full, relief_comp_area=relief_comp_area, relief_comp_crack=relief_comp_crack,
        relief_comp_full=relief_comp_full, relief_reb_area=relief_reb_area, relief_reb_crack=relief_reb_crack,
        relief_reb_full=relief_reb_full)
    q = orifice_flow(dp_Pa, cd, area, rho, p_crit) + leakage_flow(dp_Pa, k_leak)
    if check_p_crit is not None:
        q = q + orifice_flow(dp_Pa, cd, check_valve_area(dp_Pa, check_area_max, check_dp_crack, check_dp_full),
                             rho, check_p_crit)
    return q


def _flow_function_derivative(dp_Pa, p_crit_Pa):
    """d phi/d dp of `_flow_function` [1/sqrt(Pa)]: (dp^2/2 + p_cr^2) / (dp^2 + p_cr^2)^(5/4) > 0."""
    s = dp_Pa * dp_Pa + p_crit_Pa * p_crit_Pa
    return (0.5 * dp_Pa * dp_Pa + p_crit_Pa * p_crit_Pa) / (s * sym.sqrt(sym.sqrt(s)))


def _separate_check(kw: dict):
    """(area keywords without the check valve, its (area_max, crack, full, p_crit)) when the check valve has its own
    transition (check_p_crit given), else (kw, None)."""
    kw = dict(kw)
    p_crit_check = kw.pop("check_p_crit", None)
    if p_crit_check is None:
        return kw, None
    check = (kw["check_area_max"], kw["check_dp_crack"], kw["check_dp_full"], p_crit_check)
    kw["check_area_max"] = 0.0
    return kw, check


def _check_flow_and_slope(dp, c, check):
    """(flow per c [m^2 sqrt(Pa)], its derivative in dp) of a check valve with its own transition."""
    area_max, crack, full, p_crit = check
    area = check_valve_area(dp, area_max, crack, full)
    phi = _flow_function(dp, p_crit)
    return c * area * phi, c * (area_max * _smooth_step_derivative(dp, crack, full) * phi
                                 + area * _flow_function_derivative(dp, p_crit))


def valve_pressure_drop(q_m3_s, newton_iterations: int = 40, dp_guess=None, **valve_kwargs):
    """Pressure difference [Pa] that drives flow q [m^3/s] through the valve: solves valve_flow(dp) = q.

    valve_kwargs are those of `valve_flow` (bleed_area > 0 required). The unknown is the
    orifice flow variable w = phi(dp) = dp/(dp^2+p_cr^2)^(1/4), in which a fixed-area orifice
    is linear, so the laminar/turbulent law is inverted analytically and Newton only has to
    deal with the opening valves and leakage. Start: the analytic bleed-only inverse, which
    bounds |dp| from above because every other path only adds flow; the root is bracketed
    between 0 and that bound. Then `newton_iterations` Newton steps, each falling back to
    bisection of the bracket when it would leave it; the bracket shrinks with the sign of the
    residual. Written with hpsim.symbolic ops only, so with a CasADi q (or parameters) it
    unrolls into an SX/MX graph. dp_guess [Pa] (e.g. the previous time step) replaces the
    starting point (clamped into the bracket).
    """
    kw, check = _separate_check(valve_kwargs)
    cd, rho, p_crit, k_leak = kw.pop("cd"), kw.pop("rho"), kw.pop("p_crit"), kw.pop("k_leak")
    unknown = set(kw) - set(_AREA_KEYS)
    missing = set(_AREA_KEYS) - set(kw)
    if unknown or missing:
        raise TypeError(f"valve_pressure_drop: unknown {sorted(unknown)} / missing {sorted(missing)} valve arguments")
    c = sym.sqrt(2.0 / rho) * cd   # orifice flow per unit area per sqrt(Pa)

    def residual_and_slope(w):
        dp = _flow_function_inverse(w, p_crit)
        ddp_dw = _flow_function_inverse_derivative(w, p_crit)
        area = valve_opening_area(dp, **kw)
        darea = _valve_opening_area_derivative(dp, **kw)
        r = c * area * w + k_leak * dp - q_m3_s
        dr = c * area + (c * w * darea + k_leak) * ddp_dw
        if check is not None:
            q_check, dq_check = _check_flow_and_slope(dp, c, check)
            r = r + q_check
            dr = dr + dq_check * ddp_dw
        return r, dr

    w_bound = q_m3_s / (c * kw["bleed_area"])        # bleed only: |w*| <= |w_bound|
    lo = sym.fmin(w_bound, 0.0)
    hi = sym.fmax(w_bound, 0.0)
    if dp_guess is None:
        w = w_bound
    else:
        w = sym.fmin(sym.fmax(_flow_function(dp_guess, p_crit), lo), hi)
    step_before_last = 2.0 * (hi - lo)
    step_last = step_before_last
    w_best, r_best = w, None
    for _ in range(int(newton_iterations)):
        r, dr = residual_and_slope(w)
        if r_best is None:
            w_best, r_best = w, r
        else:
            better = sym.fabs(r) < sym.fabs(r_best)
            w_best = sym.if_else(better, w, w_best)
            r_best = sym.if_else(better, r, r_best)
        # the residual is increasing in w: shrink the bracket around the root
        lo = sym.if_else(r < 0, w, lo)
        hi = sym.if_else(r > 0, w, hi)
        newton_step = r / dr
        w_newton = w - newton_step
        # bisect when Newton leaves the bracket or does not at least halve the step of two
        # iterations ago (no cycling, no slow creeping: the rtsafe safeguard)
        leaves = sym.if_else(w_newton < lo, 1.0, sym.if_else(w_newton > hi, 1.0, 0.0))
        slow = sym.if_else(2.0 * sym.fabs(newton_step) > sym.fabs(step_before_last), 1.0, 0.0)
        bisect = sym.fmax(leaves, slow)
        w_next = sym.if_else(bisect > 0.5, 0.5 * (lo + hi), w_newton)
        step_before_last = step_last
        step_last = w_next - w
        w = w_next
    r, _ = residual_and_slope(w)
    if r_best is not None:
        w = sym.if_else(sym.fabs(r) < sym.fabs(r_best), w, w_best)
    return _flow_function_inverse(w, p_crit)


def valve_pressure_drop_warm(q_m3_s, dp_guess_Pa, iterations: int = 2, **valve_kwargs):
    """dp [Pa] with valve_flow(dp) = q by a few plain Newton steps from a warm start.

    For time stepping: the previous step's dp is within a few per cent of the answer, so two
    Newton steps in the orifice variable w (in which a fixed-area orifice is linear) reach the
    solver's tolerance; the iterate is kept in the bleed-only bracket [0, w_bound], which
    always contains the root. Much cheaper than `valve_pressure_drop`, which must work from a
    cold start. Symbolic-friendly.
    """
    kw, check = _separate_check(valve_kwargs)
    cd, rho, p_crit, k_leak = kw.pop("cd"), kw.pop("rho"), kw.pop("p_crit"), kw.pop("k_leak")
    c = sym.sqrt(2.0 / rho) * cd
    w_bound = q_m3_s / (c * kw["bleed_area"])
    lo, hi = sym.fmin(w_bound, 0.0), sym.fmax(w_bound, 0.0)
    w = sym.fmin(sym.fmax(_flow_function(dp_guess_Pa, p_crit), lo), hi)
    for _ in range(int(iterations)):
        dp = _flow_function_inverse(w, p_crit)
        area = valve_opening_area(dp, **kw)
        r = c * area * w + k_leak * dp - q_m3_s
        dr = c * area + (c * w * _valve_opening_area_derivative(dp, **kw) + k_leak) \
            * _flow_function_inverse_derivative(w, p_crit)
        if check is not None:
            q_check, dq_check = _check_flow_and_slope(dp, c, check)
            r = r + q_check
            dr = dr + dq_check * _flow_function_inverse_derivative(w, p_crit)
        w = sym.fmin(sym.fmax(w - r / dr, lo), hi)
    return _flow_function_inverse(w, p_crit)
