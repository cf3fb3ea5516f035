"""Seal friction laws (REFERENCE §7; seed 001 eq. 2-3; seed 000 §4.1).

Sign convention (docs/CONTRIBUTING.md): v [m/s] > 0 is compression and the friction force
[N] has the sign of v (it resists the motion). Every function is pure, takes NumPy values or
CasADi SX/MX symbols, and every coefficient is an argument. Non-smooth parts (sgn, |.|, the
switches of the seed-001 hysteresis band) are smoothed with explicit widths: eps [m/s] for
velocity, eps_x [m] for displacement.
"""
from __future__ import annotations

from numbers import Real

from hpsim import symbolic as sym
from hpsim.errors import UserInputError

__all__ = [
    "coulomb_level",
    "stribeck_friction",
    "seal_friction",
    "stroke_direction_rate",
    "lugre_bristle_rate",
    "lugre_force",
    "friction_power",
]


def coulomb_level(p_Pa, F0_N, f_p_N_per_Pa):
    """Coulomb friction level [N] F_C = F0 + f_p p: the seal is pressed harder at higher pressure (seed 000 §4.1)."""
    return F0_N + f_p_N_per_Pa * p_Pa


def _stribeck_magnitude(abs_v, F_c, K_brk, v_s):
    """|F| without the viscous part: F_C (1 + (K_brk - 1) e^(-|v|/v_s)) (REFERENCE §7)."""
    return F_c * (1.0 + (K_brk - 1.0) * sym.exp(-abs_v / v_s))


def stribeck_friction(v, F_c, K_brk, v_s, f_v, eps):
    """Stribeck friction [N]: F = F_C (1 + (K_brk - 1) e^(-|v|/v_s)) sgn(v) + f_v v (REFERENCE §7, seed 001 eq. 2).

    v [m/s], F_c [N] Coulomb level, K_brk = breakaway / Coulomb force ratio (seed 001: F_s =
    F_C (K_brk - 1), k = 1/v_s), v_s [m/s] Stribeck velocity, f_v [N s/m] viscous coefficient.
    sgn(v) ~ v/sqrt(v^2+eps^2) and |v| ~ sqrt(v^2+eps^2), width eps [m/s] (errors O(eps^2/v)
    away from zero; |F(0+)| -> F_C K_brk e^(-eps/v_s)). Odd in v; F v >= 0 for F_c >= 0, f_v >= 0.
    """
    s = sym.smooth_sign(v, eps)
    a = _smooth_magnitude(v, eps)
    return _stribeck_magnitude(a, F_c, K_brk, v_s) * s + f_v * v


def _smooth_magnitude(v, eps):
    """|v| ~ sqrt(v^2 + eps^2) [m/s]: even, smooth, >= |v|, error eps^2/(2|v|) for |v| >> eps."""
    return sym.sqrt(v * v + eps * eps)


def _is_zero(value) -> bool:
    return isinstance(value, Real) and value == 0


def seal_friction(v, x, p, *, F0_comp, F0_reb, f_p, K_brk, v_s, f_v, eps, v_h_comp=0.0, v_h_reb=0.0,
                  eps_x=None, K_brk_reb=None, v_s_reb=None, stroke_dir=None):
    """Asymmetric seal friction [N] with the seed-001 hysteresis band (seed 001 eq. 2-3, seed 000 §4.1).

    v [m/s] deflection rate (> 0 compression); x [m] deflection measured from the mid position
    of the motion; p [Pa] pressure on the seal. Coulomb levels F_C = F0_comp + f_p p in
    compression and F0_reb + f_p p in rebound (`coulomb_level`), blended by the smooth sign of
    v; Stribeck peak ratio K_brk, Stribeck velocity v_s [m/s], viscous f_v [N s/m], smoothing
    width eps [m/s] (`stribeck_friction` = seed 001 eq. 2).

    Hysteresis band (v_h_comp, v_h_reb [m/s] > 0; seed 001 eq. 3): just after a reversal,
    x v < 0 and |v| < v_h of the new stroke, the force moves linearly in |v| from the breakaway
    level of the previous stroke, F_C,old K_brk sgn(x), at v = 0 to the eq.-2 value of the new
    stroke at |v| = v_h. With equal compression/rebound levels this is eq. 3 exactly
    (F = f_v v + F_C (2v/v_h - sgn v) + F_s ((1 + e^(-k v_h)) v/v_h - sgn v)); with different
    levels it keeps the force continuous through the reversal. Smooth blends only: sgn(x) with
    width eps_x [m] (required when a band is on), the band edge with a C1 step of width eps
    that ends before |v| = v_h, so outside the band the force is eq. 2 exactly.
    Inside the band F v < 0 is possible (stored seal deformation is released); without the
    band F v >= 0. Limits of the smooth form: exactly at a reversal (|v| ~ eps) the force dips
    to about half the breakaway level over a few eps; for |x| < eps_x the reversal test is
    undecided and the band contributes half its weight. x = 0 must be the centre of the motion
    (seed 001 uses the excitation displacement).

    Per stroke direction (seed 001 §5.2, Fig. 11b-c): K_brk and v_s are the compression values and K_brk_reb,
    v_s_reb (default: the same) the rebound ones. Reversal memory: stroke_dir (in [-1, 1], the state of
    `stroke_direction_rate`: +1 after a compression stroke, -1 after a rebound one) replaces sgn(x) as the
    direction of the stroke before the reversal, so the band needs no centre and works on any motion. On a
    sinusoid it is sgn(x) wherever the band is active (the sgn(x) band exactly). eps_x is then not used.
    """
    K_reb = K_brk if K_brk_reb is None else K_brk_reb
    v_s_r = v_s if v_s_reb is None else v_s_reb
    s_v = sym.smooth_sign(v, eps)
    a_v = _smooth_magnitude(v, eps)
    F_c_comp = coulomb_level(p, F0_comp, f_p)
    F_c_reb = coulomb_level(p, F0_reb, f_p)
    w_comp = 0.5 * (1.0 + s_v)                       # 1 in compression, 0 in rebound
    if K_brk_reb is None and v_s_reb is None:     # one Stribeck law, the Coulomb level blended (fewer operations)
        mag = _stribeck_magnitude(a_v, w_comp * F_c_comp + (1.0 - w_comp) * F_c_reb, K_brk, v_s)
    else:
        mag = (w_comp * _stribeck_magnitude(a_v, F_c_comp, K_brk, v_s)
               + (1.0 - w_comp) * _stribeck_magnitude(a_v, F_c_reb, K_reb, v_s_r))
    F_out = mag * s_v + f_v * v   # seed 001 eq. 2
    if _is_zero(v_h_comp) and _is_zero(v_h_reb):
        return F_out
    if stroke_dir is None and eps_x is None:
        raise UserInputError(
            "seal_friction: eps_x (smoothing width of sgn(x) for the seed-001 hysteresis band, m) is required "
            f"when v_h_comp or v_h_reb is non-zero (got v_h_comp={v_h_comp!r}, v_h_reb={v_h_reb!r}); "
            "pass eps_x > 0, e.g. a small fraction of the motion amplitude")

    return _reversal_band(F_out, v, x, s_v, a_v, (F_c_comp, F_c_reb), (K_brk, K_reb), (v_s, v_s_r),
                          (v_h_comp, v_h_reb), f_v, eps, eps_x, stroke_dir)


def _reversal_band(F_out, v, x, s_v, a_v, F_c, K, v_s, v_h_dir, f_v, eps, eps_x, stroke_dir):
    """Seed 001 eq. 3, the band after a reversal, blended into the eq.-2 force F_out (see `seal_friction`). F_c, K,
    v_s, v_h_dir: the (compression, rebound) Coulomb levels, Stribeck ratios, Stribeck velocities and bands."""
    (F_c_comp, F_c_reb), (K_brk, K_reb), (v_s, v_s_r), (v_h_comp, v_h_reb) = F_c, K, v_s, v_h_dir
    s_x = sym.smooth_sign(x, eps_x) if stroke_dir is None else stroke_dir
    old_comp = 0.5 * (1.0 + s_x)      # x > 0 (or stroke_dir > 0): the stroke before the reversal was compression
    # v = 0: breakaway level of the old stroke; |v| = v_h: eq. 2 of the new stroke
    F_start = (old_comp * K_brk * F_c_comp + (1.0 - old_comp) * K_reb * F_c_reb) * s_x
    v_h = (1.0 - old_comp) * v_h_comp + old_comp * v_h_reb       # band of the new stroke
    F_end = -s_x * ((1.0 - old_comp) * _stribeck_magnitude(v_h, F_c_comp, K_brk, v_s)
                    + old_comp * _stribeck_magnitude(v_h, F_c_reb, K_reb, v_s_r))
    F_band = F_start + (F_end - F_start) * a_v / sym.fmax(v_h, eps) + f_v * v
    # weights: reversal (x v < 0) and inside the band (|v| < v_h; zero for |v| >= v_h or v_h = 0)
    reversal = 0.5 * (1.0 - s_x * s_v)
    inside = 1.0 - sym.smooth_step(a_v, v_h - 2.0 * eps, v_h - eps)
    return F_out + reversal * inside * (F_band - F_out)


def stroke_direction_rate(stroke_dir, v, v_h_comp, v_h_reb, eps, tau_s):
    """d(stroke_dir)/dt [1/s]: the reversal memory of `seal_friction` (seed 001 eq. 3 on any motion).

    stroke_dir relaxes to sgn(v) with time constant tau_s [s] only once |v| has passed the transition velocity
    of the current stroke (v_h_comp or v_h_reb [m/s], C1 switch of width eps [m/s]): through a reversal and the
    band after it, it holds the direction of the stroke that ended. Bounded in [-1, 1]; smooth.
    """
    s_v = sym.smooth_sign(v, eps)
    w_comp = 0.5 * (1.0 + s_v)
    v_h = w_comp * v_h_comp + (1.0 - w_comp) * v_h_reb
    a_v = _smooth_magnitude(v, eps)
    past = sym.smooth_step(a_v, v_h, v_h + eps)
    return past * (s_v - stroke_dir) / tau_s


def _lugre_g(v, F_c, F_s, v_s):
    """LuGre steady-state level g(v) = F_c + (F_s - F_c) e^(-(v/v_s)^2) [N]."""
    r = v / v_s
    return F_c + (F_s - F_c) * sym.exp(-r * r)


def lugre_bristle_rate(z_m, v, F_c, F_s, v_s, sigma0, eps):
    """LuGre bristle deflection rate [m/s]: dz/dt = v - sigma0 |v| z / g(v), g = F_c + (F_s - F_c) e^(-(v/v_s)^2).

    (Canudas de Wit et al. 1995; REFERENCE §7.) z_m [m] bristle deflection, F_c / F_s [N]
    Coulomb / static level, v_s [m/s], sigma0 [N/m] bristle stiffness. The smooth |v| ~ sqrt(v^2 + eps^2)
    (width eps [m/s]) keeps the steady state exactly z_ss = g(v) v / (sigma0 sqrt(v^2 +
    eps^2)) = g(v)/sigma0 sgn_eps(v) and adds a slow creep (time constant g/(sigma0 eps)) in
    presliding: choose eps well below the velocities of interest.
    """
    abs_v = sym.sqrt(v * v + eps * eps)
    return v - sigma0 * abs_v * z_m / _lugre_g(v, F_c, F_s, v_s)


def lugre_force(z_m, dz_dt, v, sigma0, sigma1, f_v):
    """LuGre friction force [N]: F = sigma0 z + sigma1 dz/dt + f_v v (sigma0 [N/m], sigma1, f_v [N s/m])."""
    return sigma0 * z_m + sigma1 * dz_dt + f_v * v


def friction_power(F_N, v):
    """Power [W] taken by the friction force F [N] at deflection rate v [m/s]: P = F v (>= 0 when dissipative)."""
    return F_N * v
