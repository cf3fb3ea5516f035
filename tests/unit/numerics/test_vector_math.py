"""vehicle.numerics.vector_math: exp, log, pow and tanh of the engine against the C library (NumPy's), their special
values, and the same bits in every lane width and from GCC and Clang (what lets the lanes equal the scalar engine).
"""
from __future__ import annotations

import ctypes
import shutil

import casadi as ca
import numpy as np
import pytest

from vehicle.numerics import vector_math
from vehicle.numerics.codegen import compile_c
from vehicle.numerics.lanes import LaneStepper, emit_batched, emit_function

WIDTHS = (1, 2, 4, 8)


def _library(cc: str | None = None):
    """The four functions on doubles (the scalar engine's one-lane form) and over WIDTHS lanes, as
    f(x, y, out, n) loops: name <fn>_<width> (width 0: the scalar wrapper the CasADi code calls)."""
    parts = ["#include <math.h>\n#include <string.h>\n", vector_math.scalar_functions()]
    for w in WIDTHS:
        parts.append(f"typedef double V{w} __attribute__((vector_size({8 * w})));\n"
                     f"typedef long long L{w} __attribute__((vector_size({8 * w})));\n")
        parts.append(vector_math.vector_source(f"V{w}", f"L{w}", f"w{w}"))
        for fn in vector_math.FUNCTIONS:
            call = f"hp_{fn}_w{w}(a, b)" if fn == "pow" else f"hp_{fn}_w{w}(a)"
            parts.append(f"void {fn}_{w}(const double* x, const double* y, double* out, int n) {{\n"
                         f"  for (int i = 0; i < n; i += {w}) {{ V{w} a, b; memcpy(&a, x + i, sizeof a); "
                         f"memcpy(&b, y + i, sizeof b); a = {call}; memcpy(out + i, &a, sizeof a); }}\n}}\n")
    for fn in vector_math.FUNCTIONS:
        call = f"hp_{fn}(x[i], y[i])" if fn == "pow" else f"hp_{fn}(x[i])"
        parts.append(f"void {fn}_0(const double* x, const double* y, double* out, int n) {{\n"
                     f"  for (int i = 0; i < n; ++i) out[i] = {call};\n}}\n")
    lib, error = compile_c("".join(parts).encode(), "hpsim_test_vector_math", cc=cc)
    if lib is None:
        pytest.skip(f"no library: {error}")
    return ctypes.CDLL(str(lib))


@pytest.fixture(scope="module")
def lib():
    return _library()


def _call(lib, fn: str, width: int, x, y=None) -> np.ndarray:
    x = np.ascontiguousarray(x, float)
    y = np.ascontiguousarray(np.zeros_like(x) if y is None else y, float)
    n = len(x)
    out = np.empty(n)
    f = getattr(lib, f"{fn}_{width}")
    f.argtypes = [np.ctypeslib.ndpointer(np.float64, flags="C_CONTIGUOUS")] * 3 + [ctypes.c_int]
    f(x, y, out, n)
    return out


def _ulps(got: np.ndarray, ref: np.ndarray) -> np.ndarray:
    return np.abs(got - ref) / np.spacing(np.abs(ref))


def _sample(rng, n=1 << 16) -> dict:
    """Arguments over the ranges the functions are accurate in, with a multiple of 8 entries."""
    return {"exp": np.concatenate([rng.uniform(-30, 30, n), rng.uniform(-745, 709, n), rng.uniform(-1e-8, 1e-8, n)]),
            "log": np.concatenate([np.exp(rng.uniform(-700, 700, n)), rng.uniform(0.5, 2.0, n),
                                   1.0 + rng.uniform(-1e-6, 1e-6, n)]),
            "tanh": np.concatenate([rng.uniform(-3, 3, n), rng.uniform(-1e-6, 1e-6, n), rng.uniform(-25, 25, n)])}


def test_exp_log_tanh_are_within_a_few_ulp_of_the_c_library(lib):
    """Measured: exp and log 1 ulp, tanh 4 ulp at most (tanh = -e/(e + 2) with e = expm1(-2|x|): three roundings
    after expm1's); the bound is twice that."""
    rng = np.random.default_rng(0)
    bounds = {"exp": 2.0, "log": 2.0, "tanh": 8.0}
    for fn, x in _sample(rng).items():
        ref = getattr(np, fn)(x)
        got = _call(lib, fn, 8, x)
        ok = ref != 0
        assert np.max(_ulps(got[ok], ref[ok])) <= bounds[fn], fn


def test_pow_error_grows_with_y_log_x_as_stated(lib):
    """pow = exp(y log|x|): the absolute error of y log x (about 1 ulp of it) becomes the relative error of the
    result; measured at most 12 ulp for |y log x| < 6. Bound: 4 + 2 |y log x| ulp."""
    rng = np.random.default_rng(1)
    x = rng.uniform(0.05, 20.0, 1 << 17)
    y = rng.uniform(-2.0, 2.0, 1 << 17)
    ref = x ** y
    got = _call(lib, "pow", 8, x, y)
    assert np.all(_ulps(got, ref) <= 4.0 + 2.0 * np.abs(y * np.log(x)))
    # the model's correlation exponents (Churchill-Chu 1/12, Dittus-Boelter 0.4, mixed convection 1/3, ...)
    for c in (1 / 12, 0.4, 1 / 3, 0.625, 0.8, 1.4):
        xs = np.exp(rng.uniform(-20, 20, 4096))
        assert np.all(_ulps(_call(lib, "pow", 8, xs, np.full_like(xs, c)), xs ** c) <= 4.0 + 2.0 * c * 20.0)


def test_special_values_follow_c99(lib):
    inf, nan = np.inf, np.nan
    cases = {"exp": [0.0, -0.0, inf, -inf, nan, 709.78, 710.0, -745.2, -750.0, 1e-310, -708.5, 1.0],
             "log": [0.0, -0.0, -1.0, inf, -inf, nan, 5e-324, 1e-310, 1.0, 2.0, 0.5, 2.2250738585072014e-308],
             "tanh": [0.0, -0.0, inf, -inf, nan, 1e-310, 20.0, -20.0, 40.0, 0.5, -0.5, 1e-300]}
    with np.errstate(all="ignore"):
        for fn, x in cases.items():
            x = np.array(x)
            got, ref = _call(lib, fn, 4, x), getattr(np, fn)(x)
            assert np.array_equal(np.isnan(got), np.isnan(ref)), fn
            finite = np.isfinite(ref)
            assert np.array_equal(got[~finite & ~np.isnan(ref)], ref[~finite & ~np.isnan(ref)]), fn
            assert np.all(_ulps(got[finite & (ref != 0)], ref[finite & (ref != 0)]) <= 8.0), fn
            assert np.array_equal(np.signbit(got[ref == 0]), np.signbit(ref[ref == 0])), fn
        x = np.array([-2.0, -2.0, -2.0, 0.0, 0.0, nan, 1.0, -0.5])
        y = np.array([3.0, 2.0, 0.5, -1.4, 1.4, 0.0, nan, 3.0])
        # a negative base with an integer exponent: the sign of the C library, the magnitude to a few ulp
        np.testing.assert_allclose(_call(lib, "pow", 8, x, y), x ** y, rtol=4 * np.finfo(float).eps, atol=0)


def _bits(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(a).view(np.int64)


def test_every_lane_width_gives_the_scalar_bits(lib):
    """The engine's premise: a lane of any width rounds as the one-lane scalar function does, NaN and inf included."""
    rng = np.random.default_rng(2)
    for fn, x in _sample(rng, 4096).items():
        x = np.concatenate([x, [0.0, -0.0, np.inf, -np.inf, np.nan, 1e-310, -1.0, 750.0]])
        ref = _bits(_call(lib, fn, 0, x))
        for w in WIDTHS:
            assert np.array_equal(_bits(_call(lib, fn, w, x)), ref), (fn, w)
    x, y = rng.uniform(-5, 20, 4096), rng.uniform(-3, 3, 4096)
    y[::7] = np.round(y[::7])                      # negative bases with integer exponents
    ref = _bits(_call(lib, "pow", 0, x, y))
    for w in WIDTHS:
        assert np.array_equal(_bits(_call(lib, "pow", w, x, y)), ref), w


@pytest.mark.skipif(not (shutil.which("gcc") and shutil.which("clang")), reason="needs gcc and clang")
def test_gcc_and_clang_give_the_same_bits(lib):
    other = _library(cc="clang")
    rng = np.random.default_rng(3)
    for fn, x in _sample(rng, 2048).items():
        assert np.array_equal(_bits(_call(lib, fn, 8, x)), _bits(_call(other, fn, 8, x))), fn


def test_batched_calls_give_the_bits_of_one_call_each():
    """`emit_batched` reorders a function by its depth in calls and gathers the calls of one depth into vector calls:
    on a function with calls at several depths, shared arguments, both pow forms and outputs read between calls,
    the one-lane library with batched calls equals the one with a call per statement, bit for bit."""
    x = ca.SX.sym("x", 6)
    u0, u1 = ca.SX.sym("u0", 1), ca.SX.sym("u1", 1)
    p = ca.SX.sym("p", 2)
    a = ca.exp(x[0] * p[0]) + ca.log(1 + x[1] ** 2)
    b = ca.tanh(a - x[2]) * ca.power(ca.fabs(x[3]) + 1, 0.4) + ca.power(x[4] ** 2 + 2, x[5] / 7)
    c = ca.exp(-ca.fabs(b)) + ca.log(ca.exp(a / 50) + 1) + u0 * u1
    # bounded (tanh of everything): the map iterates to finite values
    z_next = ca.tanh(ca.vertcat(a, b, c, ca.tanh(c) + ca.exp(ca.tanh(a)), x[4] * p[1], ca.power(ca.fabs(c) + 1, 1 / 12)))
    step = ca.Function("step", [x, u0, u1, p], [z_next])
    pv = ca.SX.sym("pv", 2)
    parametric = ca.Function("parametric", [pv], [pv])
    rng = np.random.default_rng(4)
    z0, P = rng.normal(size=(6, 1)), np.array([[0.3], [1.7]])
    U = rng.normal(size=(5 * 3 + 1, 1, 1))
    out = {}
    for batch in (0, 8, 4):
        st = LaneStepper.from_functions(step, parametric, 1, f"hpsim_test_batched_{batch}", scalar=True, batch=batch)
        assert ("HB y_ = hp_pow_b(" in st.source) == (batch > 0)
        out[batch] = st.advance(z0, U, P, 5, 3)
    assert np.all(np.isfinite(out[0]))
    assert np.array_equal(_bits(out[8]), _bits(out[0])) and np.array_equal(_bits(out[4]), _bits(out[0]))
    assert emit_function(step, "s") != emit_batched(step, "s", 8)
