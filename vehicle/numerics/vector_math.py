"""exp, log, pow and tanh as C over any number of lanes: the same operations in the scalar engine and in the vector
lanes, so both give the same bits and a vector of lanes costs about what one lane does.

The C library's functions are scalar: in the lane code (vehicle.numerics.lanes) each one runs lane after lane and
would make up most of a lane-step's instructions (docs/engines.md, "Vector math and batched calls"). A vector math library (libmvec, SLEEF) rounds differently
from the scalar libm, so the lanes would no longer equal the scalar engine. Here the four functions the model uses
are written out once, branch-free, in GCC/Clang vector-extension C over a lane type; the scalar engine's CasADi C
calls the same code through a one-lane vector (`scalar_header`), so scalar and lanes round alike by construction.

Methods: table-driven argument reduction (P. T. P. Tang, "Table-driven implementation of the exponential function
in IEEE floating-point arithmetic", ACM TOMS 15(2), 1989; and of the logarithm, ACM TOMS 16(4), 1990; J.-M.
Muller, "Elementary Functions", 3rd ed., 2016, ch. 11), short Taylor polynomials evaluated by Estrin's scheme:

- exp(x) = 2^m 2^(j/N) exp(r): n = round(x N / ln 2) = N m + j, r = x - n (ln 2 / N)_hi - n (ln 2 / N)_lo (the hi
  part has its low 32 bits zero, so n times it is exact), |r| <= ln 2 / (2N). Then exp(r) - 1 = r + r^2 Q(r) to r^5
  (truncation < 2^-60), and 2^(j/N) from a table as hi + lo. 2^m is applied as two exact power-of-two factors, so a
  subnormal result rounds once. x is clamped to [EXP_MIN_ARG, EXP_MAX_ARG], beyond which the result is 0 or +inf.
- log(x) = k ln 2 + log(c) + log1p(r): x = 2^k z with z in [sqrt(2)/2, sqrt(2)), c = 1 + i / N the grid point
  nearest z. The reduced argument r = z / c - 1 is computed as z_hi (1/c)' - 1 + z_lo (1/c)' with (1/c)' = 1/c rounded to 21 bits (z_hi:
  z's top 32 bits, so the product is exact). log(c) comes from a table as -log((1/c)') hi + lo. The polynomial log1p(r) = r + r^2 Q(r)
  to r^8 (|r| < 2^-7.4, truncation < 2^-60). The grid point 1 has (1/c)' = 1: near x = 1 the result is log1p(x-1)
  itself, without cancellation. Subnormal x is scaled by 2^54 first.
- pow(x, y) = exp(y log|x|), with the sign of a negative base for an odd integer y and NaN for a non-integer y.
  The error grows with |y log x| (the absolute error of y log x becomes a relative error of the result): about
  (1 + |y log x|) ulp; the model's powers (correlation exponents, y log x of order 1) stay within a few ulp.
- tanh(x) = -e / (e + 2), e = expm1(-2|x|) = (2^m 2^(j/N) - 1) + 2^m (2^(j/N) (r + r^2 Q(r)) + lo), with the
  sign of x: accurate near 0, where 1 - 2/(exp(2x) + 1) would cancel.

Every operation is correctly rounded IEEE arithmetic (the code is compiled without fused multiply-add and without
value-changing flags: vehicle.numerics.codegen.COMPILER_FLAGS) and the table lookups are exact, so a lane gives the
bits of the scalar function whatever the vector width. Special values follow C99 Annex F where the model can meet
them (NaN in gives NaN out, log(0) = -inf, log(x < 0) = NaN, exp(+-inf) = inf, 0, pow(x, 0) = 1). The
accuracy against the C library is tested in tests/unit/numerics/test_vector_math.py. Without the vector extension
(a compiler other than GCC or Clang) both the scalar engine and the lanes use the C library.
"""
from __future__ import annotations

import math
import struct
from decimal import Decimal, getcontext

getcontext().prec = 60
_LN2 = Decimal(2).ln()


def _cleared_low_bits(value, bits: int) -> float:
    """`value` rounded to a double, then its last `bits` mantissa bits set to zero."""
    (u,) = struct.unpack("<Q", struct.pack("<d", float(value)))
    (v,) = struct.unpack("<d", struct.pack("<Q", u & ~((1 << bits) - 1)))
    return v


def _hi_lo(value: Decimal) -> tuple[float, float]:
    hi = float(value)
    return hi, float(value - Decimal(hi))


EXP_TABLE_BITS = 7                       # N = 128 table entries of 2^(j/N)
LOG_TABLE_BITS = 7                       # grid 1 + i / 128 over [sqrt(2)/2, sqrt(2))
EXP_POLY_DEGREE = 5                      # |r| <= ln 2 / 256: r^6 / 6! < 2^-60 relative
LOG_POLY_DEGREE = 8                      # |r| < 2^-7.4: r^9 / 9 < 2^-60 relative
LOG_INVERSE_BITS = 21                    # (1/c)' times a 32-bit z_hi is exact
LOG_SPLIT_BITS = 21                      # z_hi: z with its low 21 mantissa bits zero (32 significant bits)
ROUNDING_SHIFTER = 1.5 * 2.0 ** 52       # x + this - this rounds x to an integer (|x| < 2^51)
EXP_MAX_ARG = 710.0                      # exp(710) > DBL_MAX: +inf
EXP_MIN_ARG = -746.0                     # exp(-746) < the smallest subnormal / 2: 0
EXPM1_MIN_ARG = -40.0                    # expm1(-40) = -1 to double precision (e^-40 < 2^-57)
SUBNORMAL_SCALE_BITS = 54

_N_EXP = 1 << EXP_TABLE_BITS
_N_LOG = 1 << LOG_TABLE_BITS
LN2_N_HI = _cleared_low_bits(_LN2 / _N_EXP, 32)
LN2_N_LO = float(_LN2 / _N_EXP - Decimal(LN2_N_HI))
N_LOG2E = float(_N_EXP / _LN2)
LN2_HI = _cleared_low_bits(_LN2, 32)
LN2_LO = float(_LN2 - Decimal(LN2_HI))
SQRT2 = float(Decimal(2).sqrt())
_LOG_I_MIN = round((1 / math.sqrt(2) - 1) * _N_LOG)    # grid points of z in [sqrt(2)/2, sqrt(2))
_LOG_I_MAX = round((math.sqrt(2) - 1) * _N_LOG)

FUNCTIONS = ("exp", "log", "pow", "tanh")    # the C library functions these replace


def _c(value: float) -> str:
    return float(value).hex()


def _c_mask(low_zero_bits: int) -> str:
    """C literal of the 64-bit mask with the low `low_zero_bits` bits zero."""
    return f"0x{(2 ** 64 - 1) ^ ((1 << low_zero_bits) - 1):016x}ULL"


def exp_table() -> list[tuple[float, float]]:
    """2^(j/N), j = 0 .. N-1, as (hi, lo): hi the double nearest, lo the rest rounded."""
    return [_hi_lo(Decimal(2) ** (Decimal(j) / _N_EXP)) for j in range(_N_EXP)]


def log_table() -> list[tuple[float, float, float]]:
    """For the grid points c = 1 + i/N, i = _LOG_I_MIN .. _LOG_I_MAX: ((1/c)', -log((1/c)') hi, lo), (1/c)' = 1/c
    rounded to LOG_INVERSE_BITS significant bits (exactly 1 at c = 1)."""
    rows = []
    for i in range(_LOG_I_MIN, _LOG_I_MAX + 1):
        inv = 1.0 / (1.0 + i / _N_LOG)
        m, e = math.frexp(inv)
        inv = math.ldexp(round(m * (1 << LOG_INVERSE_BITS)), e - LOG_INVERSE_BITS)
        rows.append((inv, *_hi_lo(-Decimal(inv).ln())))
    return rows


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


def tables_source() -> str:
    """The C tables of `exp_table` and `log_table` (static, shared by every lane type of one file)."""
    e = ",\n  ".join(f"{{{_c(h)}, {_c(lo)}}}" for h, lo in exp_table())
    lg = ",\n  ".join(f"{{{_c(a)}, {_c(b)}, {_c(c)}}}" for a, b, c in log_table())
    return (f"static const double hp_exp_table[{_N_EXP}][2] = {{\n  {e}}};\n"
            f"static const double hp_log_table[{_LOG_I_MAX - _LOG_I_MIN + 1}][3] = {{\n  {lg}}};\n")


def vector_source(v: str, vl: str, suffix: str) -> str:
    """C of hp_exp_<suffix>, hp_log_<suffix>, hp_pow_<suffix>, hp_tanh_<suffix> over the lane type `v` (a GCC
    vector of doubles) with `vl` its 64-bit integer vector of the same length (comparisons give -1 / 0 lanes).
    Needs `tables_source()` before it in the file."""
    return "\n" + _exp_source(v, vl, suffix) + _log_source(v, vl, suffix) + _pow_source(v, vl, suffix) + \
        _tanh_source(v, vl, suffix)


def _exp_source(v: str, vl: str, suffix: str) -> str:
    """The lane helpers (select, 2^n, broadcast, sign mask), the exp argument reduction shared with tanh, and exp."""
    # exp(r) - 1 = r + r^2 Q(r), Q(r) = sum_k r^k / (k + 2)!
    exp_decl, exp_q = _estrin("r", [1.0 / math.factorial(k + 2) for k in range(EXP_POLY_DEGREE - 1)], v)
    sh = _c(ROUNDING_SHIFTER)
    return f"""static inline {v} hp_sel_{suffix}({vl} m, {v} a, {v} b) {{ return ({v})((({vl})a & m) | (({vl})b & ~m)); }}
static inline {v} hp_pow2_{suffix}({vl} n) {{ return ({v})((n + 1023) << 52); }}
static inline {v} hp_bc_{suffix}(double c) {{ return ({v}){{0}} + c; }}
static inline {vl} hp_sign_{suffix}(void) {{ return ({vl}){{0}} + (long long)0x8000000000000000ULL; }}
#define HP_LANES_{suffix} ((int)(sizeof({v}) / sizeof(double)))
/* n = round(x N / ln 2) (k: as an integer), r = x - n ln 2 / N, |r| <= ln 2 / 2N; exp(x) = 2^(k/N) exp(r) */
#define HP_EXP_REDUCE_{suffix}(x) \\
  {v} t = x * {_c(N_LOG2E)} + {sh}; \\
  {v} n = t - {sh}; \\
  {vl} k = ({vl})t - ({vl})hp_bc_{suffix}({sh}); \\
  {v} r = (x - n * {_c(LN2_N_HI)}) - n * {_c(LN2_N_LO)}; \\
  {vl} j = k & {_N_EXP - 1}, m = k >> {EXP_TABLE_BITS}; \\
  {v} th, tl; \\
  for (int l_ = 0; l_ < HP_LANES_{suffix}; ++l_) {{ th[l_] = hp_exp_table[j[l_]][0]; tl[l_] = hp_exp_table[j[l_]][1]; }} \\
  {exp_decl} \\
  {v} p = r + r2 * {exp_q};
static inline {v} hp_exp_{suffix}({v} x) {{
  x = hp_sel_{suffix}(x > {_c(EXP_MAX_ARG)}, hp_bc_{suffix}({_c(EXP_MAX_ARG)}), x);
  x = hp_sel_{suffix}(x < {_c(EXP_MIN_ARG)}, hp_bc_{suffix}({_c(EXP_MIN_ARG)}), x);
  HP_EXP_REDUCE_{suffix}(x)
  {vl} m1 = m >> 1;
  return (th + (th * p + tl)) * hp_pow2_{suffix}(m1) * hp_pow2_{suffix}(m - m1);
}}
"""


def _log_source(v: str, vl: str, suffix: str) -> str:
    """log: the table-driven reduction, log1p of the reduced argument, the special values."""
    # log1p(r) = r + r^2 Q(r), Q(r) = sum_k (-1)^(k+1) r^k / (k + 2)
    log_decl, log_q = _estrin("r", [(-1.0) ** (k + 1) / (k + 2) for k in range(LOG_POLY_DEGREE - 1)], v)
    sh = _c(ROUNDING_SHIFTER)
    return f"""static inline {v} hp_log_{suffix}({v} x) {{
  {vl} tiny = x < {_c(2.0 ** -1022)};
  {v} xs = hp_sel_{suffix}(tiny, x * {_c(2.0 ** SUBNORMAL_SCALE_BITS)}, x);
  {vl} bits = ({vl})xs;
  {vl} e = ((bits >> 52) & 2047) - 1023 - (tiny & {SUBNORMAL_SCALE_BITS});
  {v} z = ({v})((bits & 0xfffffffffffffLL) | 0x3ff0000000000000LL);
  {vl} big = z >= {_c(SQRT2)};
  z = hp_sel_{suffix}(big, z * 0.5, z);
  e = e - big;
  {v} t = (z - 1.) * {_c(float(_N_LOG))} + {sh};
  {vl} i = ({vl})t - ({vl})hp_bc_{suffix}({sh}) - ({_LOG_I_MIN});
  {v} inv, lh, ll;
  for (int l_ = 0; l_ < HP_LANES_{suffix}; ++l_) {{
    inv[l_] = hp_log_table[i[l_]][0]; lh[l_] = hp_log_table[i[l_]][1]; ll[l_] = hp_log_table[i[l_]][2];
  }}
  {v} zh = ({v})(({vl})z & (long long){_c_mask(LOG_SPLIT_BITS)});
  {v} r = (zh * inv - 1.) + (z - zh) * inv;
  {log_decl}
  {v} ed = ({v})(e + ({vl})hp_bc_{suffix}({sh})) - {sh};
  {v} y = (ed * {_c(LN2_HI)} + lh) + (r + (r2 * {log_q} + (ed * {_c(LN2_LO)} + ll)));
  y = hp_sel_{suffix}(x == 0., hp_bc_{suffix}(-__builtin_inf()), y);
  y = hp_sel_{suffix}(x < 0., hp_bc_{suffix}(__builtin_nan("")), y);
  y = hp_sel_{suffix}(x == __builtin_inf(), x, y);
  return hp_sel_{suffix}(x != x, x, y);
}}
"""


def _pow_source(v: str, vl: str, suffix: str) -> str:
    """pow = exp(y log|x|), with the sign of a negative base for an odd integer y, NaN for a non-integer y."""
    sh = _c(ROUNDING_SHIFTER)
    return f"""static inline {v} hp_pow_{suffix}({v} x, {v} y) {{
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
"""


def _tanh_source(v: str, vl: str, suffix: str) -> str:
    """tanh = -e / (e + 2), e = expm1(-2|x|), with the sign of x."""
    return f"""static inline {v} hp_tanh_{suffix}({v} x) {{
  {vl} sign = hp_sign_{suffix}();
  {v} u = ({v})(({vl})x & ~sign) * -2.;
  u = hp_sel_{suffix}(u < {_c(EXPM1_MIN_ARG)}, hp_bc_{suffix}({_c(EXPM1_MIN_ARG)}), u);
  HP_EXP_REDUCE_{suffix}(u)
  {v} s = hp_pow2_{suffix}(m);
  {v} e = (s * th - 1.) + s * (th * p + tl);
  {v} h = -e / (e + 2.);
  return ({v})((({vl})h & ~sign) | (({vl})x & sign));
}}
"""

def scalar_functions() -> str:
    """C of hp_exp, hp_log, hp_pow and hp_tanh on doubles under GCC and Clang: the one-lane form of `vector_source`,
    the same operations as every lane of the vector code."""
    return ("\n#if defined(__GNUC__) || defined(__clang__)\n"
            "#define HP_VECTOR_MATH 1\n"
            "#define HP_OUTLINE static inline\n"
            "typedef double hp_v1 __attribute__((vector_size(8)));\n"
            "typedef long long hp_l1 __attribute__((vector_size(8)));\n"
            + tables_source() + vector_source("hp_v1", "hp_l1", "1")
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
