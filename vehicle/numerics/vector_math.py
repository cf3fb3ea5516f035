"""exp, log, pow and tanh as C over any number of lanes: the same operations in the scalar engine and in the vector
lanes, so both give the same bits and a vector of lanes costs about what one lane does (issue 26).

The C library's functions are scalar: in the lane code (vehicle.numerics.lanes) each one ran lane after lane and
made up 11.7k of the 19.3k instructions of a lane-step. A vector math library (libmvec, SLEEF) rounds differently
from the scalar libm, so the lanes would no longer equal the scalar engine. Here the four functions the model uses
are written out once, branch-free, in GCC/Clang vector-extension C over a lane type; the scalar engine's CasADi C
calls the same code through a one-lane vector (`scalar_header`), so scalar and lanes round alike by construction.

Methods (textbook argument reduction, e.g. J.-M. Muller, "Elementary Functions", 3rd ed., 2016, ch. 11; Cody &
Waite, "Software Manual for the Elementary Functions", 1980):

- exp(x) = 2^n exp(r), n = round(x / ln 2), r = x - n ln2_hi - n ln2_lo (|r| <= ln 2 / 2; ln2_hi has its low 32
  bits zero, so n ln2_hi is exact), exp(r) by its Taylor polynomial to r^13 (truncation < 2^-57 relative), 2^n
  applied as two exact power-of-two factors (subnormal results round once). x is clamped to
  [EXP_MIN_ARG, EXP_MAX_ARG], beyond which the result is 0 or +inf anyway.
- log(x) = k ln 2 + log(m), x = 2^k m with m in [sqrt(2)/2, sqrt(2)); log(m) = 2 atanh(s), s = (m - 1)/(m + 1),
  summed as f - (f^2/2 - s (f^2/2 + R)), f = m - 1, R = sum_{j=1..11} 2 s^(2j) / (2j + 1) (truncation < 2^-60;
  the form keeps the error below 1 ulp, as in 4.3BSD/fdlibm's log). Subnormal x is scaled by 2^54 first.
- pow(x, y) = exp(y log|x|), with the sign of a negative base for an odd integer y and NaN for a non-integer y.
  The error grows with |y log x| (the absolute error of y log x becomes a relative error of the result): about
  (1 + |y log x|) ulp; the model's powers (polytropic ratios, y log x of order 1) stay within a few ulp.
- tanh(x) = -e / (e + 2), e = expm1(-2|x|), with the sign of x: expm1(u) = 2^n (expm1(r) + 1) - 1, expm1(r) by
  r times its Taylor polynomial (to r^14 / 14!), accurate near 0 where 1 - 2/(exp(2x) + 1) would cancel.

Special values follow C99 Annex F where the model can meet them (NaN in gives NaN out, log(0) = -inf,
log(x < 0) = NaN, exp(+-inf) = inf, 0, pow(x, 0) = 1); the measured accuracy against the C library is tested in
tests/unit/numerics/test_vector_math.py. Without the vector extension (a compiler other than GCC or Clang) both
the scalar engine and the lanes use the C library.
"""
from __future__ import annotations

import math
import struct
from decimal import Decimal, getcontext

getcontext().prec = 50
_LN2 = Decimal(2).ln()


def _cleared_low_bits(value: Decimal, bits: int) -> float:
    """`value` rounded to a double whose last `bits` mantissa bits are zero (a product with a small integer exact)."""
    (u,) = struct.unpack("<Q", struct.pack("<d", float(value)))
    (v,) = struct.unpack("<d", struct.pack("<Q", u & ~((1 << bits) - 1)))
    return v


LN2_HI = _cleared_low_bits(_LN2, 32)
LN2_LO = float(_LN2 - Decimal(LN2_HI))
LOG2E = float(1 / _LN2)
SQRT2 = float(Decimal(2).sqrt())
ROUNDING_SHIFTER = 1.5 * 2.0 ** 52       # x + this - this rounds x to an integer (|x| < 2^51)
EXP_MAX_ARG = 710.0                      # exp(710) > DBL_MAX: +inf
EXP_MIN_ARG = -746.0                     # exp(-746) < the smallest subnormal / 2: 0
EXPM1_MIN_ARG = -40.0                    # expm1(-40) = -1 to double precision (e^-40 < 2^-57)
SUBNORMAL_SCALE_BITS = 54
EXP_TAYLOR_DEGREE = 13
EXPM1_TAYLOR_DEGREE = 14
LOG_ATANH_TERMS = 11

FUNCTIONS = ("exp", "log", "pow", "tanh")    # the C library functions these replace


def _c(value: float) -> str:
    return float(value).hex()


def _estrin(var: str, coefficients: list[float], v: str) -> tuple[str, str]:
    """C of sum_k coefficients[k] var^k by Estrin's scheme: (statements declaring var^2, var^4, ... as
    `{var}2`, `{var}4`, ..., the expression). Pairs c_2i + c_2i+1 x, then pairs of those with x^2, x^4, ...: a
    dependency chain of about 2 log2(degree) operations instead of Horner's 2 degree (the step's transcendental
    calls sit on its critical path: latency, not only instruction count, sets their cost)."""
    terms = [_c(c) if i + 1 >= len(coefficients) else f"({_c(c)}+{_c(coefficients[i + 1])}*{var})"
             for i, c in enumerate(coefficients) if i % 2 == 0]
    decls, power, name = [], 2, var
    while len(terms) > 1:
        decls.append(f"{v} {var}{power} = {name} * {name};")
        name = f"{var}{power}"
        terms = [f"({t}+{terms[i + 1]}*{name})" if i + 1 < len(terms) else t for i, t in enumerate(terms) if i % 2 == 0]
        power *= 2
    return " ".join(decls), terms[0]


def vector_source(v: str, vl: str, suffix: str) -> str:
    """C of hp_exp_<suffix>, hp_log_<suffix>, hp_pow_<suffix>, hp_tanh_<suffix> over the lane type `v` (a GCC
    vector of doubles) with `vl` its 64-bit integer vector of the same length (comparisons give -1 / 0 lanes)."""
    # exp(r) = 1 + (r + r^2 Q(r)) and expm1(r) = r + r^2 Q(r), Q(r) = sum_k r^k / (k + 2)!: one rounding at 1 +
    exp_decl, exp_q = _estrin("r", [1.0 / math.factorial(k + 2) for k in range(EXP_TAYLOR_DEGREE - 1)], v)
    em_decl, em_q = _estrin("r", [1.0 / math.factorial(k + 2) for k in range(EXPM1_TAYLOR_DEGREE - 1)], v)
    log_decl, log_poly = _estrin("z", [2.0 / (2 * j + 1) for j in range(1, LOG_ATANH_TERMS + 1)], v)
    sh = _c(ROUNDING_SHIFTER)
    return f"""
static inline {v} hp_sel_{suffix}({vl} m, {v} a, {v} b) {{ return ({v})((({vl})a & m) | (({vl})b & ~m)); }}
static inline {v} hp_pow2_{suffix}({vl} n) {{ return ({v})((n + 1023) << 52); }}
static inline {v} hp_bc_{suffix}(double c) {{ return ({v}){{0}} + c; }}
static inline {vl} hp_sign_{suffix}(void) {{ return ({vl}){{0}} + (long long)0x8000000000000000ULL; }}
static inline {v} hp_exp_{suffix}({v} x) {{
  x = hp_sel_{suffix}(x > {_c(EXP_MAX_ARG)}, hp_bc_{suffix}({_c(EXP_MAX_ARG)}), x);
  x = hp_sel_{suffix}(x < {_c(EXP_MIN_ARG)}, hp_bc_{suffix}({_c(EXP_MIN_ARG)}), x);
  {v} t = x * {_c(LOG2E)} + {sh};
  {v} n = t - {sh};
  {vl} k = ({vl})t - ({vl})hp_bc_{suffix}({sh});
  {v} r = (x - n * {_c(LN2_HI)}) - n * {_c(LN2_LO)};
  {vl} k1 = k >> 1;
  {exp_decl}
  {v} p = 1. + (r + r2 * {exp_q});
  return p * hp_pow2_{suffix}(k1) * hp_pow2_{suffix}(k - k1);
}}
static inline {v} hp_log_{suffix}({v} x) {{
  {vl} tiny = x < {_c(2.0 ** -1022)};
  {v} xs = hp_sel_{suffix}(tiny, x * {_c(2.0 ** SUBNORMAL_SCALE_BITS)}, x);
  {vl} bits = ({vl})xs;
  {vl} e = ((bits >> 52) & 2047) - 1023 - (tiny & {SUBNORMAL_SCALE_BITS});
  {v} m = ({v})((bits & 0xfffffffffffffLL) | 0x3ff0000000000000LL);
  {vl} big = m > {_c(SQRT2)};
  m = hp_sel_{suffix}(big, m * 0.5, m);
  e = e - big;
  {v} f = m - 1.;
  {v} s = f / (f + 2.);
  {v} z = s * s;
  {log_decl}
  {v} R = z * {log_poly};
  {v} hfsq = 0.5 * f * f;
  {v} ed = ({v})(e + ({vl})hp_bc_{suffix}({sh})) - {sh};
  {v} y = ed * {_c(LN2_HI)} + (f - (hfsq - (s * (hfsq + R) + ed * {_c(LN2_LO)})));
  y = hp_sel_{suffix}(x == 0., hp_bc_{suffix}(-__builtin_inf()), y);
  y = hp_sel_{suffix}(x < 0., hp_bc_{suffix}(__builtin_nan("")), y);
  y = hp_sel_{suffix}(x == __builtin_inf(), x, y);
  return hp_sel_{suffix}(x != x, x, y);
}}
static inline {v} hp_pow_{suffix}({v} x, {v} y) {{
  {vl} sign = hp_sign_{suffix}();
  {v} ax = ({v})(({vl})x & ~sign);
  {v} r = hp_exp_{suffix}(y * hp_log_{suffix}(ax));
  {v} ay = ({v})(({vl})y & ~sign);
  {v} ty = ay + {sh};
  {vl} huge = ay >= {_c(2.0 ** 52)};
  {vl} integer = (ty - {sh} == ay) | huge;
  {vl} odd = ((({vl})ty & 1) != 0) & ~huge;
  {vl} negative = x < 0.;
  r = hp_sel_{suffix}(negative & ~integer, hp_bc_{suffix}(__builtin_nan("")), r);
  r = ({v})(({vl})r ^ (negative & odd & sign));
  return hp_sel_{suffix}((y == 0.) | (x == 1.), hp_bc_{suffix}(1.), r);
}}
static inline {v} hp_tanh_{suffix}({v} x) {{
  {vl} sign = hp_sign_{suffix}();
  {v} u = ({v})(({vl})x & ~sign) * -2.;
  u = hp_sel_{suffix}(u < {_c(EXPM1_MIN_ARG)}, hp_bc_{suffix}({_c(EXPM1_MIN_ARG)}), u);
  {v} t = u * {_c(LOG2E)} + {sh};
  {v} n = t - {sh};
  {vl} k = ({vl})t - ({vl})hp_bc_{suffix}({sh});
  {v} r = (u - n * {_c(LN2_HI)}) - n * {_c(LN2_LO)};
  {v} scale = hp_pow2_{suffix}(k);
  {em_decl}
  {v} e = scale * (r + r2 * {em_q}) + (scale - 1.);
  {v} th = -e / (e + 2.);
  return ({v})((({vl})th & ~sign) | (({vl})x & sign));
}}
"""


def scalar_functions() -> str:
    """C of hp_exp, hp_log, hp_pow and hp_tanh on doubles under GCC and Clang: the one-lane form of `vector_source`,
    the same operations as every lane of the vector code."""
    return ("\n#if defined(__GNUC__) || defined(__clang__)\n"
            "#define HP_VECTOR_MATH 1\n"
            "#define HP_OUTLINE static __attribute__((noinline))\n"
            "typedef double hp_v1 __attribute__((vector_size(8)));\n"
            "typedef long long hp_l1 __attribute__((vector_size(8)));\n"
            + vector_source("hp_v1", "hp_l1", "1")
            + "HP_OUTLINE double hp_exp(double x) { return hp_exp_1((hp_v1){x})[0]; }\n"
              "HP_OUTLINE double hp_log(double x) { return hp_log_1((hp_v1){x})[0]; }\n"
              "HP_OUTLINE double hp_pow(double x, double y) { return hp_pow_1((hp_v1){x}, (hp_v1){y})[0]; }\n"
              "HP_OUTLINE double hp_tanh(double x) { return hp_tanh_1((hp_v1){x})[0]; }\n"
              "#endif\n")


def scalar_header() -> str:
    """C for the scalar engine's CasADi code, after its `#include <math.h>`: `scalar_functions`, and the calls of
    exp, log, pow and tanh redirected to them (under GCC and Clang; elsewhere the C library stays)."""
    return (scalar_functions()
            + "#ifdef HP_VECTOR_MATH\n"
              "#define exp(x) hp_exp(x)\n#define log(x) hp_log(x)\n#define pow(x, y) hp_pow(x, y)\n"
              "#define tanh(x) hp_tanh(x)\n"
              "#endif\n")


def with_scalar_math(c_code: bytes) -> bytes:
    """CasADi's generated C with `scalar_header` inserted after its `#include <math.h>`."""
    marker = b"#include <math.h>\n"
    if marker not in c_code:
        raise ValueError("with_scalar_math: the generated C does not include <math.h>")
    return c_code.replace(marker, marker + scalar_header().encode(), 1)
