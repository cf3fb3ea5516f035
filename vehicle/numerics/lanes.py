"""The compiled ROS2 step over many cases at once: one instruction, several lanes (docs/engines.md).

`Ros2.step_functions` gives the step as an SX function, the straight-line list of operations CasADi's C
generator walks to write one statement per operation (``a5=(a3*a4);``). This module walks the same list and
writes the same statements over a lane type `V` instead of `double`:

- with GCC or Clang, `V` is a vector of NL doubles (``__attribute__((vector_size(8 * NL)))``, structure of
  arrays: work variable a5 holds lane l's value in a5[l]). The operators + - * / and the comparisons are the
  vector extension's element-wise operations, sqrt a per-lane loop (one `sqrtpd`). The functions exp, log,
  tanh and pow are
  `vehicle.numerics.vector_math`'s functions over the lane type (the scalar engine calls the same code on one
  lane: the same bits), the other C library functions run lane by lane, and CasADi's conditionals (`c ? b : 0`,
  `x <= y` as 1.0 / 0.0) are bit masks. Every lane computes
  every operation: the step has no branch (the sparse LU of W is symbolic, without pivoting, and the
  valves' Newton iterations are a fixed count), so nothing needs masking inside it: a lane gone non-finite
  stays in its own lane;
- elsewhere (no vector extension, or `-DHPSIM_LANES_SCALAR`) `V` is `double` and the block runs the
  lanes one after the other: the scalar step, the same statements as CasADi's;
- the one-lane build with batched calls (`emit_batched`, `LaneStepper(..., batched=True)`, `BatchedBlock`) is
  the scalar engine's block function (`vehicle.numerics.solvers.Ros2`): `V` is `double`, and the step's
  exp/log/tanh/pow calls of one depth run a vector's width at a time;
- the step split around the struts (`vehicle.numerics.split_step`, `split_step_source`): three scalar pieces over
  `V` and the strut kernel over the stations, a case's stations in one vector where `V` is one lane (`emit_kernel`),
  else two stations per call over `V`'s lanes: the same operations per station either way.

fmin/fmax are written as the C library computes them (glibc 2.36: a NaN operand gives the other one, of
+0 and -0 the minimum is -0), so that lanes equal the scalar engine bit for bit. The library is compiled
with the scalar engine's flags (`codegen.COMPILER_FLAGS`: no value-changing flag, -ffp-contract=off: no
fused multiply-add even where the instruction set has one); the divisions GCC's -freciprocal-math would
rewrite are rewritten in the graph (`step_graph.explicit_reciprocals`), the same for scalar and lanes.

`LaneStepper` is the block function over NL lanes: (z0 (nz, NL), U (K M + 1, nu, NL), P (np, NL)) ->
states at the M samples (M, nz, NL); `vehicle.engines.ensemble` steps K cases of one model structure with it.
"""
from __future__ import annotations

import ctypes
import os
import re
import string
from pathlib import Path

import casadi as ca
import numpy as np

from vehicle.numerics.codegen import CLibrary, compile_c, compile_library
from vehicle.numerics.instructions import Instruction, defining_instructions, instructions
from vehicle.numerics import vector_math

# instruction sets the lane library can be built for: extra compiler flags, doubles per hardware vector
ISAS = {"sse2": ((), 2), "avx2": (("-mavx2",), 4), "avx512": (("-mavx512f",), 8)}
ISA_ENV = "HPSIM_LANES_ISA"
EXTRA_FLAGS = ()        # codegen.COMPILER_FLAGS has -ffp-contract=off

_BINARY = {ca.OP_ADD: "({0}+{1})", ca.OP_SUB: "({0}-{1})", ca.OP_MUL: "({0}*{1})", ca.OP_DIV: "({0}/{1})",
           ca.OP_LT: "CMP({0}<{1})", ca.OP_LE: "CMP({0}<={1})", ca.OP_EQ: "CMP({0}=={1})",
           ca.OP_NE: "CMP({0}!={1})", ca.OP_AND: "AND({0},{1})", ca.OP_OR: "OR({0},{1})",
           ca.OP_IF_ELSE_ZERO: "IFZ({0},{1})", ca.OP_FMIN: "FMIN({0},{1})", ca.OP_FMAX: "FMAX({0},{1})",
           ca.OP_POW: "POW({0},{1})", ca.OP_CONSTPOW: "POW({0},{1})",
           ca.OP_ATAN2: "LANE2(atan2,{0},{1})", ca.OP_COPYSIGN: "LANE2(copysign,{0},{1})",
           ca.OP_FMOD: "LANE2(fmod,{0},{1})", ca.OP_HYPOT: "LANE2(hypot,{0},{1})"}
_UNARY = {ca.OP_NEG: "(-{0})", ca.OP_TWICE: "(2.*{0})", ca.OP_SQ: "({0}*{0})", ca.OP_INV: "(1./{0})",
          ca.OP_ASSIGN: "{0}", ca.OP_NOT: "NOT({0})", ca.OP_SQRT: "SQRT({0})", ca.OP_FABS: "FABS({0})",
          ca.OP_SIGN: "SIGN({0})"}
_LIBM = {"SIN": "sin", "COS": "cos", "TAN": "tan", "ASIN": "asin",
         "ACOS": "acos", "ATAN": "atan", "SINH": "sinh", "COSH": "cosh", "ASINH": "asinh", "ACOSH": "acosh",
         "ATANH": "atanh", "FLOOR": "floor", "CEIL": "ceil", "ERF": "erf", "LOG1P": "log1p", "EXPM1": "expm1"}
_UNARY.update({getattr(ca, f"OP_{k}"): f"LANE1({v},{{0}})" for k, v in _LIBM.items()})
_UNARY.update({ca.OP_EXP: "EXP({0})", ca.OP_LOG: "LOG({0})", ca.OP_TANH: "TANH({0})"})   # vehicle.numerics.vector_math

# the operations over a GCC / Clang vector type ($T, lanes $W, its integer vector $TL), as macros and functions named
# with the prefix $P (the step's lanes: no prefix; the strut kernel's lanes: K_), its exp/log/tanh/pow
# vector_math's functions of suffix $S (`vector_math.vector_source`)
_VECTOR_OPS = string.Template(r"""
/* a constant in every lane: a vector literal, so that the compiler folds with it as with a scalar constant */
#define ${P}BC(c) (($T){$BROADCAST})
static const double ${P}ONE_ = 1.0;
#define ${P}ONES (($TL)${P}BC(${P}ONE_))
#define ${P}CMP(m) (($T)((m) & ${P}ONES))
#define ${P}NOT(x) ${P}CMP((x) == 0.)
#define ${P}AND(x, y) (($T)(((x) != 0.) & ((y) != 0.) & ${P}ONES))
#define ${P}OR(x, y) (($T)((((x) != 0.) | ((y) != 0.)) & ${P}ONES))
#define ${P}IFZ(c, b) (($T)(($TL)(b) & ((c) != 0.)))
#define ${P}FABS(x) (($T)(($TL)(x) & ($TL)${P}BC(-0.) ^ ($TL)(x)))
#define ${P}LANE1(f, x) ({ $T r_ = (x); for (int l = 0; l < $W; ++l) r_[l] = f(r_[l]); r_; })
#define ${P}LANE2(f, x, y) ({ $T r_ = (x), s_ = (y); for (int l = 0; l < $W; ++l) r_[l] = f(r_[l], s_[l]); r_; })
#define ${P}SQRT(x) ${P}LANE1(sqrt, x)
#define ${P}SIGN(x) ({ $T s_ = (x); $T r_ = ${P}CMP(s_ > 0.) - ${P}CMP(s_ < 0.); ($T)(($TL)r_ | (($TL)s_ & ((s_ == 0.) | (s_ != s_)))); })
/* glibc's fmin/fmax: a NaN operand gives the other operand; of equal operands (+0 and -0) the OR / AND of the bits */
static inline $T ${P}FMIN($T x, $T y) {
  $TL tx = (x < y) | (y != y), ty = (y < x) | (x != x);
  return ($T)((($TL)x & tx) | (($TL)y & ty & ~tx) | ((($TL)x | ($TL)y) & ~(tx | ty)));
}
static inline $T ${P}FMAX($T x, $T y) {
  $TL tx = (x > y) | (y != y), ty = (y > x) | (x != x);
  return ($T)((($TL)x & tx) | (($TL)y & ty & ~tx) | ((($TL)x & ($TL)y) & ~(tx | ty)));
}
#define ${P}EXP(x) hp_exp_$S(x)
#define ${P}LOG(x) hp_log_$S(x)
#define ${P}TANH(x) hp_tanh_$S(x)
#define ${P}POW(x, y) hp_pow_$S(x, y)
""")
# the names the statements use (`_statement`): the strut kernel's code takes them with its prefix
OPERATION_MACROS = ("BC", "CMP", "NOT", "AND", "OR", "IFZ", "FABS", "LANE1", "LANE2", "SQRT", "SIGN", "FMIN", "FMAX",
                    "EXP", "LOG", "TANH", "POW")


def vector_ops(prefix: str, vtype: str, ltype: str, width: int, suffix: str) -> str:
    """C of the lane operations over the vector type `vtype` of `width` doubles (`_VECTOR_OPS`)."""
    return _VECTOR_OPS.substitute(P=prefix, T=vtype, TL=ltype, W=width, S=suffix,
                                  BROADCAST=", ".join(["(c)"] * width))


_PRELUDE = r"""
#include <math.h>
#include <string.h>
#define NL %(lanes)d
/* the step compiled on its own, as CasADi's (no knowledge of its callers' pointers: the same code as there) */
#if defined(__GNUC__) && !defined(__clang__)
#define NOIPA __attribute__((noipa))
#elif defined(__GNUC__)
#define NOIPA __attribute__((noinline))
#else
#define NOIPA
#endif
#if (defined(__GNUC__) || defined(__clang__)) && !defined(HPSIM_LANES_SCALAR)
/* NL lanes in one vector: structure of arrays */
#define VW NL
typedef double V __attribute__((vector_size(8 * NL)));
typedef long long VL __attribute__((vector_size(8 * NL)));
%(vector_ops)s#else
/* no vector extension: the lanes one after the other, CasADi's scalar statements */
#define VW 1
typedef double V;
#define BC(c) (c)
#define CMP(m) ((double)(m))
#define NOT(x) ((double)(!(x)))
#define AND(x, y) ((double)((x) && (y)))
#define OR(x, y) ((double)((x) || (y)))
#define IFZ(c, b) ((c) ? (b) : 0)
#define FABS(x) fabs(x)
#define LANE1(f, x) f(x)
#define LANE2(f, x, y) f(x, y)
#define SQRT(x) sqrt(x)
#define SIGN(x) ((x) < 0 ? -1. : (x) > 0 ? 1. : (x))
/* glibc's fmin/fmax written out (a compiler may inline its own, e.g. clang's minnum, with another zero) */
static inline double FMIN(double x, double y) {
  union { double d; unsigned long long u; } a = {x}, b = {y};
  if (x < y || y != y) return x;
  if (y < x || x != x) return y;
  a.u |= b.u; return a.d;
}
static inline double FMAX(double x, double y) {
  union { double d; unsigned long long u; } a = {x}, b = {y};
  if (x > y || y != y) return x;
  if (y > x || x != x) return y;
  a.u &= b.u; return a.d;
}
/* the scalar engine's functions (vehicle.numerics.vector_math.scalar_header): hp_* under GCC and Clang */
%(scalar_math)s
#if defined(HP_VECTOR_MATH) && defined(HP_BATCH)
/* independent calls of one step gathered into one vector call (`emit_batched`): the lanes' functions */
typedef double HB __attribute__((vector_size(8 * HP_BATCH)));
typedef long long HBL __attribute__((vector_size(8 * HP_BATCH)));
%(batch_math)s
#endif
#ifdef HP_VECTOR_MATH
#define EXP(x) hp_exp(x)
#define LOG(x) hp_log(x)
#define TANH(x) hp_tanh(x)
#define POW(x, y) hp_pow(x, y)
#else
#define EXP(x) exp(x)
#define LOG(x) log(x)
#define TANH(x) tanh(x)
#define POW(x, y) pow(x, y)
#endif
#endif
static inline void load(V* dst, const double* src, int n, int g) {
  for (int i = 0; i < n; ++i) memcpy(&dst[i], src + (long)i * NL + g * VW, sizeof(V));
}
static inline void store(double* dst, const V* src, int n, int g) {
  for (int i = 0; i < n; ++i) memcpy(dst + (long)i * NL + g * VW, &src[i], sizeof(V));
}
"""

_BLOCK = r"""
/* the block: M samples of K steps from z0 (nz x NL), inputs U ((K M + 1) x nu x NL), parameters P (np x NL);
   the states at the samples into Z (M x nz x NL). Lanes are independent: groups of VW lanes one after the other. */
int %(name)s(const double* z0, const double* U, const double* P, double* Z, int M, int K) {
  for (int g = 0; g < NL / VW; ++g) {
    V p[%(np)d], pw[%(npw)d], za[%(nz)d], zb[%(nz)d], u0[%(nu)d], u1[%(nu)d];
    V *z = za, *zn = zb, *t;
    load(p, P, %(np)d, g);
    parametric(p, pw);
    load(z, z0, %(nz)d, g);
    load(u1, U, %(nu)d, g);
    for (int m = 0; m < M; ++m) {
      for (int k = 0; k < K; ++k) {
        memcpy(u0, u1, sizeof(u0));
        load(u1, U + ((long)m * K + k + 1) * %(nu)d * NL, %(nu)d, g);
        step(z, u0, u1, pw, zn);
        t = z; z = zn; zn = t;
      }
      store(Z + (long)m * %(nz)d * NL, z, %(nz)d, g);
    }
  }
  return 0;
}
/* one step and the parametric part alone (same layouts: [i][NL]): for tests and instruction counts */
int %(name)s_step(const double* z, const double* u0, const double* u1, const double* pw, double* out) {
  for (int g = 0; g < NL / VW; ++g) {
    V za[%(nz)d], zb[%(nz)d], a[%(nu)d], b[%(nu)d], w[%(npw)d];
    load(za, z, %(nz)d, g); load(a, u0, %(nu)d, g); load(b, u1, %(nu)d, g); load(w, pw, %(npw)d, g);
    step(za, a, b, w, zb);
    store(out, zb, %(nz)d, g);
  }
  return 0;
}
int %(name)s_parametric(const double* P, double* pw) {
  for (int g = 0; g < NL / VW; ++g) {
    V p[%(np)d], w[%(npw)d];
    load(p, P, %(np)d, g);
    parametric(p, w);
    store(pw, w, %(npw)d, g);
  }
  return 0;
}
int %(name)s_lanes(void) { return NL; }
int %(name)s_npw(void) { return %(npw)d; }
int %(name)s_vector_width(void) { return VW; }
"""


def _constant(v: float) -> str:
    if np.isnan(v):
        return "NAN"
    if np.isinf(v):
        return "INFINITY" if v > 0 else "(-INFINITY)"
    return repr(float(v))


def _dense(fn: ca.Function, who: str, outputs: bool = False) -> None:
    """Refuse a sparse input (and with outputs=True a sparse output) of `fn`: the lane code reads and writes dense
    arrays."""
    for kind, n, sparsity in (("input", fn.n_in(), fn.sparsity_in), ("output", fn.n_out(), fn.sparsity_out)):
        if kind == "output" and not outputs:
            continue
        for k in range(n):
            if not sparsity(k).is_dense():
                raise ValueError(f"{who}: {kind} {k} of {fn.name()} is sparse")


def emit_function(fn: ca.Function, cname: str) -> str:
    """C of an SX function over lanes: `static void cname(const V* in0, ..., V* out0, ...)`, one statement per
    instruction of `fn` (its work registers a0, a1, ... as CasADi's C generator numbers them). Inputs are read and
    outputs written under the same null-pointer tests as in CasADi's C: they split the code into the same basic
    blocks, and the compiler's -freciprocal-math (one reciprocal for several divisions by one divisor) works per
    block: without them it rewrites other divisions than in the scalar engine (3e-10 relative after 100 steps)."""
    if not isinstance(fn, ca.Function) or not fn.is_a("SXFunction"):
        raise TypeError("emit_function: expected an SX function")
    n_in, n_out = fn.n_in(), fn.n_out()
    args = [f"const V* restrict i{k}" for k in range(n_in)] + [f"V* restrict o{k}" for k in range(n_out)]
    lines = [f"NOIPA static void {cname}({', '.join(args)}) {{"]
    n_work = fn.sz_w()
    if n_work:
        names = ", ".join(f"a{j}" for j in range(n_work))
        lines.append(f"  V {names};")
    rows_out = [fn.sparsity_out(k).row() for k in range(n_out)]
    for k in range(n_out):
        sp = fn.sparsity_out(k)
        if sp.nnz() != sp.numel():                       # structural zeros: written as 0
            lines.append(f"  for (int i = 0; i < {sp.numel()}; ++i) o{k}[i] = BC(0.);")
    _dense(fn, "emit_function")
    for ins in instructions(fn):
        lines.append(_statement(fn.name(), ins, f"a{ins.outputs[0]}", [f"a{i}" for i in ins.inputs[:2]], rows_out))
    lines.append("}")
    return "\n".join(lines)


def _statement(fname: str, ins: Instruction, target: str, args: list[str], rows_out) -> str:
    """C of instruction `ins` of the function `fname`: its value into `target` (a register, or a declaration) from
    the operands `args` (C names; an output writes args[0])."""
    op, i_in, i_out = ins.op, ins.inputs, ins.outputs
    if op == ca.OP_INPUT:
        return f"  {target}=i{i_in[0]} ? i{i_in[0]}[{i_in[1]}] : BC(0.);"
    if op == ca.OP_OUTPUT:
        return f"  if (o{i_out[0]}!=0) o{i_out[0]}[{rows_out[i_out[0]][i_out[1]]}]={args[0]};"
    if op == ca.OP_CONST:
        return f"  {target}=BC({_constant(ins.constant)});"
    if op in _BINARY:
        return f"  {target}=" + _BINARY[op].format(*args) + ";"
    if op in _UNARY:
        return f"  {target}=" + _UNARY[op].format(*args) + ";"
    raise NotImplementedError(f"operation {op} of {fname} has no lane form")


_TRANSCENDENTAL = {ca.OP_EXP: "exp", ca.OP_LOG: "log", ca.OP_TANH: "tanh", ca.OP_POW: "pow", ca.OP_CONSTPOW: "pow"}


def emit_batched(fn: ca.Function, cname: str, width: int) -> str:
    """C of an SX function on one lane (V = double) whose exp, log, tanh and pow calls run `width` at a time in
    one vector call of vehicle.numerics.vector_math (lane-count independent: the same bits as one call each).

    Each value gets its own variable (w<k>: instruction k) and the instructions are reordered by their depth in
    calls (d = the most calls on a path from an input). For d = 0, 1, ...: the calls at depth d (their arguments
    are of lower depth), gathered by function into vectors, then the other instructions at depth d in their
    original order. Every instruction reads only values computed before it, as in the original order, and each
    is the same IEEE operation, so the results are those of `emit_function`'s code bit for bit; the ROS2 step's
    216 calls (8 struts x stages) fall into a few dozen vector calls."""
    if not isinstance(fn, ca.Function) or not fn.is_a("SXFunction"):
        raise TypeError("emit_batched: expected an SX function")
    n_in, n_out = fn.n_in(), fn.n_out()
    _dense(fn, "emit_batched")
    values = defining_instructions(fn)
    depth = []
    for ins, reads in values:
        d = max((depth[r] for r in reads), default=0)
        depth.append(d + 1 if ins.op in _TRANSCENDENTAL else d)
    args = [f"const V* restrict i{k}" for k in range(n_in)] + [f"V* restrict o{k}" for k in range(n_out)]
    lines = [f"NOIPA static void {cname}({', '.join(args)}) {{"]
    rows_out = [fn.sparsity_out(k).row() for k in range(n_out)]
    for k in range(n_out):
        sp = fn.sparsity_out(k)
        if sp.nnz() != sp.numel():
            lines.append(f"  for (int i = 0; i < {sp.numel()}; ++i) o{k}[i] = BC(0.);")
    by_depth: dict[int, list[int]] = {}
    for k, d in enumerate(depth):
        by_depth.setdefault(d, []).append(k)
    for d in sorted(by_depth):
        calls: dict[str, list[int]] = {}
        for k in by_depth[d]:
            if values[k][0].op in _TRANSCENDENTAL:
                calls.setdefault(_TRANSCENDENTAL[values[k][0].op], []).append(k)
        for name, ks in calls.items():
            lines.extend(_batched_calls(name, ks, values, width))
        for k in by_depth[d]:
            ins, reads = values[k]
            if ins.op in _TRANSCENDENTAL:
                continue
            lines.append(_statement(fn.name(), ins, f"V w{k}", [f"w{r}" for r in reads], rows_out))
    lines.append("}")
    return "\n".join(lines)


def _batched_calls(name: str, ks: list[int], values, width: int) -> list[str]:
    """C of the calls `name` of instructions `ks` (same depth: independent), `width` per vector call; a short
    last vector repeats its first argument in the unused lanes."""
    lines = [f"  V {', '.join(f'w{k}' for k in ks)};"]
    for start in range(0, len(ks), width):
        chunk = ks[start:start + width]
        pad = chunk + [chunk[0]] * (width - len(chunk))
        args = [f"(HB){{{', '.join(f'w{values[k][1][a]}' for k in pad)}}}" for a in range(len(values[chunk[0]][1]))]
        outs = " ".join(f"w{k}=y_[{i}];" for i, k in enumerate(chunk))
        lines.append(f"  {{ HB y_ = hp_{name}_b({', '.join(args)}); {outs} }}")
    return lines


_MACRO_NAMES = re.compile(r"\b(" + "|".join(OPERATION_MACROS) + r")\(")


def emit_kernel(fn: ca.Function, cname: str, copies: int = 1) -> str:
    """C of the strut kernel (`vehicle.numerics.split_step`): `fn`'s statements over the kernel's lane type K_T
    with the K_ operations, its inputs and outputs read and written through K_LOAD / K_STORE (value q of station
    s at q NSP + s: `_SPLIT`). `copies` lane vectors per call, from stations s0_, s0_ + KSTEP, ..., each statement
    written for each in turn (their own registers: the same operations per station). Dense inputs and outputs."""
    _dense(fn, "emit_kernel", outputs=True)
    args = [f"const V* restrict i{k}" for k in range(fn.n_in())] + [f"V* restrict o{k}" for k in range(fn.n_out())]
    lines = [f"NOIPA static void {cname}({', '.join(args)}, int s0_) {{"]
    for c in range(copies):
        if fn.sz_w():
            lines.append(f"  K_T {', '.join(f'a{j}_{c}' for j in range(fn.sz_w()))};")
    for ins in instructions(fn):
        op, i_in, i_out = ins.op, ins.inputs, ins.outputs
        for c in range(copies):
            if op == ca.OP_INPUT:
                lines.append(f"  a{i_out[0]}_{c}=K_LOAD(i{i_in[0]}, {i_in[1]}, s0_ + {c} * KSTEP);")
            elif op == ca.OP_OUTPUT:
                lines.append(f"  K_STORE(o{i_out[0]}, {i_out[1]}, s0_ + {c} * KSTEP, a{i_in[0]}_{c});")
            else:
                lines.append(_MACRO_NAMES.sub(r"K_\1(", _statement(fn.name(), ins, f"a{i_out[0]}_{c}",
                                                                     [f"a{i}_{c}" for i in i_in[:2]], [])))
    lines.append("}")
    return "\n".join(lines)


_SPLIT = r"""
/* the step split around the struts (vehicle.numerics.split_step): pieces A, B, C over the step's lanes, the strut
   kernel of each stage over the stations. Buffers between them: value q of station s at q * NSP + s. */
#define NS %(stations)d
#define NSP %(padded)d
#if VW == 1 && (defined(__GNUC__) || defined(__clang__)) && !defined(HPSIM_KERNEL_STATIONWISE)
/* one case per call: its stations in vectors of KW doubles (one hardware vector each), NSP / KW of them
   interleaved in one call */
#define K_STATION_VECTOR 1
#define KW %(kernel_width)d
#define KSTEP KW
typedef double S __attribute__((vector_size(8 * KW)));
typedef long long SL __attribute__((vector_size(8 * KW)));
#define K_T S
%(kernel_ops)s
#define K_LOAD(p, k, s) ({ S t_; memcpy(&t_, (p) + (long)(k) * NSP + (s), sizeof t_); t_; })
#define K_STORE(p, k, s, v) do { S t_ = (v); memcpy((p) + (long)(k) * NSP + (s), &t_, sizeof t_); } while (0)
#define STATIONS(f, in, pw, out) f##_group(in, pw, out, 0)
#else
/* the step's lanes (cases), several stations per call */
#define KSTEP 1
#define K_T V
%(kernel_aliases)s
#define K_LOAD(p, k, s) ((p)[(long)(k) * NSP + (s)])
#define K_STORE(p, k, s, v) ((p)[(long)(k) * NSP + (s)] = (v))
/* STATIONS_PER_CALL stations per call, their statements interleaved: independent work beside each long chain of
   the kernel */
#define STATIONS(f, in, pw, out) for (int s_ = 0; s_ < NS; s_ += %(per_call)d) f##_group(in, pw, out, s_)
#endif
%(functions)s
NOIPA static void step(const V* restrict i0, const V* restrict i1, const V* restrict i2, const V* restrict i3,
                       V* restrict o0) {
  V ki1[%(nki1)d], ko1[%(nko1)d], ki2[%(nki2)d], ko2[%(nko2)d], k1[%(nk1)d], lu[%(nlu)d];
  piece_a(i0, i1, i3 + %(off_a)d, ki1);
  STATIONS(kernel_1, ki1, i3 + %(off_k1)d, ko1);
  piece_b(i0, i1, i2, i3 + %(off_b)d, ko1, ki2, k1, lu);
  STATIONS(kernel_2, ki2, i3 + %(off_k2)d, ko2);
  piece_c(i0, i2, i3 + %(off_c)d, ko2, k1, lu, o0);
}
"""

# stations per kernel call over the ensemble's lanes (docs/engines.md, "Lanes across struts": the fastest there)
STATIONS_PER_CALL = 2


def split_step_source(split, batch: int, width: int) -> str:
    """C of the split step `step(z, u0, u1, pw, z_next)` (a `vehicle.numerics.split_step.SplitStep`): the pieces
    by `emit_batched` (batch > 0) or `emit_function`, the kernels by `emit_kernel`; width: doubles per hardware
    vector (a case's stations in vectors of min(width, stations) doubles)."""
    a, b, c = split.pieces
    piece = (lambda fn, nm: emit_batched(fn, nm, batch)) if batch else emit_function
    k1, k2 = split.kernels
    kernel_width = min(int(width), split.padded)
    groups = split.padded // kernel_width
    functions = [piece(a, "piece_a"), piece(b, "piece_b"), piece(c, "piece_c"),
                 "#ifdef K_STATION_VECTOR", emit_kernel(k1, "kernel_1_group", groups),
                 emit_kernel(k2, "kernel_2_group", groups), "#else",
                 emit_kernel(k1, "kernel_1_group", STATIONS_PER_CALL),
                 emit_kernel(k2, "kernel_2_group", STATIONS_PER_CALL), "#endif"]
    return _SPLIT % {"stations": split.stations, "padded": split.padded, "kernel_width": kernel_width,
                     "per_call": STATIONS_PER_CALL,
                     "kernel_ops": vector_math.vector_source("S", "SL", "s") + vector_ops("K_", "S", "SL", kernel_width,
                                                                                        "s"),
                     "kernel_aliases": "\n".join(f"#define K_{m} {m}" for m in OPERATION_MACROS),
                     "functions": "\n".join(functions),
                     "nki1": a.size1_out(0), "nko1": b.size1_in(4), "nki2": b.size1_out(0), "nko2": c.size1_in(3),
                     "nk1": b.size1_out(1), "nlu": b.size1_out(2), **{f"off_{k}": v for k, v in split.offsets.items()}}


def _step_sizes(step) -> tuple[int, int]:
    """(nz, nu) of a step: one SX function (z, u0, u1, pw) -> z_next or a `split_step.SplitStep`."""
    if isinstance(step, ca.Function):
        return step.size1_in(0), step.size1_in(1)
    return step.nz, step.nu


def lanes_source(step, parametric: ca.Function, lanes: int, name: str, batch: int = 0, *, width: int) -> str:
    """The C of the lane block function `name` (see the module docstring) for NL = `lanes`; batch > 0: the step by
    `emit_batched` with vector calls of `batch` lanes (the one-lane build, -DHPSIM_LANES_SCALAR). `step`: the step
    as one SX function, or a `vehicle.numerics.split_step.SplitStep` (`split_step_source`); width: doubles per
    hardware vector (`ISAS`)."""
    split = None if isinstance(step, ca.Function) else step
    nz, nu = _step_sizes(step)
    npw, np_ = parametric.size1_out(0), parametric.size1_in(0)
    if split is None and (step.size1_in(3) != npw or step.size1_out(0) != nz):
        raise ValueError("lanes_source: the step and the parametric function do not fit together")
    prelude = (f"#define HP_BATCH {int(batch)}\n" if batch else "") + _PRELUDE % {"lanes": lanes,
                          "vector_ops": vector_math.tables_source() + vector_math.vector_source("V", "VL", "v")
                          + vector_ops("", "V", "VL", lanes, "v"),
                          "scalar_math": vector_math.scalar_functions(),
                          "batch_math": vector_math.vector_source("HB", "HBL", "b")}
    if split is not None:
        step_c = split_step_source(split, batch, width)
    else:
        step_c = emit_batched(step, "step", batch) if batch else emit_function(step, "step")
    return "\n".join([prelude, step_c, emit_function(parametric, "parametric"),
                      _BLOCK % {"name": name, "np": np_, "npw": npw, "nz": nz, "nu": nu}])


def default_isa() -> str:
    """The instruction set for the lane library: $HPSIM_LANES_ISA, else the widest the processor has (AVX-512,
    AVX2, SSE2): one hardware vector of lanes is the fastest per lane-step (docs/engines.md, "Vector
    lanes"). Valgrind cannot run AVX-512: HPSIM_LANES_ISA=avx2 for instruction counts."""
    asked = os.environ.get(ISA_ENV, "").strip().lower()
    if asked:
        if asked not in ISAS:
            raise ValueError(f"{ISA_ENV}: {asked!r}, expected one of {sorted(ISAS)}")
        return asked
    try:
        flags = set(re.findall(r"\w+", Path("/proc/cpuinfo").read_text().split("flags", 1)[1].split("\n", 1)[0]))
    except (OSError, IndexError):
        return "sse2"
    return "avx512" if "avx512f" in flags else "avx2" if "avx2" in flags else "sse2"


def default_lanes(isa: str | None = None) -> int:
    """Lanes of one hardware vector of doubles for `isa` (default: `default_isa()`): the ensemble's group size."""
    return ISAS[isa or default_isa()][1]


class LaneStepper:
    """The ROS2 block function of `solver` (a bound-able `Ros2`) over `lanes` cases of `model`'s
    structure, compiled (cached like every library) and loaded: `advance(z0, U, P, K, M)`.

    scalar=True builds the fallback (lanes one after the other, no vector extension) on any compiler;
    batched=True the one-lane build whose step gathers its exp/log/tanh/pow calls into vectors of the instruction
    set's width (`emit_batched`; GCC or Clang): the scalar engine's block function (`Ros2`)."""

    def __init__(self, solver, model, lanes: int, *, isa: str | None = None, scalar: bool = False,
                 cc: str | None = None, batched: bool = False, load: bool = True):
        strut_lanes = solver.strut_lanes
        self._setup(lanes, f"hpsim_lanes_{model.structure}_{int(lanes)}{'b' if batched else ''}"
                    f"{'s' if strut_lanes else ''}", isa, scalar or batched, cc)
        batch = ISAS[self.isa][1] if batched else 0
        self.nz, self.nu, self.np = model.nx + model.n_memory, model.nu, model.np

        def build() -> bytes:
            split = solver.split_step_functions(model)
            if split is not None:
                step, parametric = split, split.parametric
            else:
                step, parametric = solver.step_functions(model)
            self.source = self._source(step, parametric, batch)
            return self.source.encode()
        # found in the compile cache by what determines the C (no graph built when it is there)
        self.spec = CLibrary(self.name, (model.structure, float(solver.dt), self.lanes, batch, strut_lanes), build,
                             self.flags)
        if load:           # load=False: `spec` for codegen.precompile, `load()` later
            self.load()

    @classmethod
    def from_functions(cls, step, parametric: ca.Function, lanes: int, name: str, *,
                       isa: str | None = None, scalar: bool = False, cc: str | None = None,
                       batch: int = 0, flags: tuple = ()) -> "LaneStepper":
        """The lane block function of any step (z, u0, u1, pw) -> z_next (SX, or a `split_step.SplitStep`) and
        parametric part p -> pw (SX), cached by its C; batch > 0: its calls gathered `batch` at a time
        (`emit_batched`, the one-lane build); flags: more compiler flags (-DHPSIM_KERNEL_STATIONWISE: the strut
        kernel station after station, as without GCC's vector types)."""
        self = cls.__new__(cls)
        self._setup(lanes, name, isa, scalar or batch > 0, cc)
        self.flags += tuple(flags)
        self.nz, self.nu = _step_sizes(step)
        self.np = parametric.size1_in(0)
        self.source = self._source(step, parametric, batch)
        self.spec = None
        return self.load()

    def _source(self, step, parametric: ca.Function, batch: int) -> str:
        """`lanes_source` of this stepper's lanes, name and instruction set."""
        return lanes_source(step, parametric, self.lanes, self.name, batch=batch, width=ISAS[self.isa][1])

    def _setup(self, lanes, name, isa, scalar, cc) -> None:
        self.lanes = int(lanes)
        if self.lanes < 1 or self.lanes & (self.lanes - 1):
            raise ValueError(f"LaneStepper: lanes must be a power of two (a vector's length), got {lanes}")
        self.isa = isa or default_isa()
        self.name = name
        self.flags = (*EXTRA_FLAGS, *ISAS[self.isa][0]) + (("-DHPSIM_LANES_SCALAR",) if scalar else ())
        self.cc = cc
        self.source = None            # the C, when this process wrote it
        self.library = None

    def load(self) -> "LaneStepper":
        """Compile (or find in the cache) and load the library."""
        if self.library is not None:
            return self
        if self.spec is not None:
            lib, error = compile_library(self.spec, cc=self.cc)
        else:
            lib, error = compile_c(self.source.encode(), self.name, self.flags, cc=self.cc)
        if lib is None:
            raise RuntimeError(f"the lane library could not be compiled ({error})")
        self.library = lib
        self._lib = ctypes.CDLL(str(lib))
        self._fn = getattr(self._lib, self.name)
        ptr = np.ctypeslib.ndpointer(dtype=np.float64, flags="C_CONTIGUOUS")
        self._fn.argtypes = [ptr, ptr, ptr, ptr, ctypes.c_int, ctypes.c_int]
        self._fn.restype = ctypes.c_int
        self.vector_width = int(getattr(self._lib, f"{self.name}_vector_width")())
        self.npw = int(getattr(self._lib, f"{self.name}_npw")())
        self._step = getattr(self._lib, f"{self.name}_step")
        self._step.argtypes = [ptr] * 5
        self._parametric = getattr(self._lib, f"{self.name}_parametric")
        self._parametric.argtypes = [ptr] * 2
        return self

    def step(self, z, u0, u1, pw) -> np.ndarray:
        """One step of every lane: z (nz, lanes), u0 and u1 (nu, lanes), pw (the parametric part, (npw, lanes))."""
        out = np.empty((self.nz, self.lanes))
        self._step(*(np.ascontiguousarray(a, dtype=np.float64) for a in (z, u0, u1, pw)), out)
        return out

    def parametric(self, P) -> np.ndarray:
        """The parameters with their lifted subexpressions (npw, lanes) from P (np, lanes)."""
        pw = np.empty((self.npw, self.lanes))
        self._parametric(np.ascontiguousarray(P, dtype=np.float64), pw)
        return pw

    def advance(self, z0: np.ndarray, U: np.ndarray, P: np.ndarray, K: int, M: int) -> np.ndarray:
        """States at the M samples (M, nz, lanes) from z0 (nz, lanes), the inputs U (K M + 1, nu, lanes) at every
        step and the parameters P (np, lanes)."""
        L = self.lanes
        z0 = np.ascontiguousarray(z0, dtype=np.float64)
        U = np.ascontiguousarray(U, dtype=np.float64)
        P = np.ascontiguousarray(P, dtype=np.float64)
        if z0.shape != (self.nz, L) or U.shape != (K * M + 1, self.nu, L) or P.shape != (self.np, L):
            raise ValueError(f"LaneStepper.advance: shapes {z0.shape}, {U.shape}, {P.shape}; expected "
                             f"{(self.nz, L)}, {(K * M + 1, self.nu, L)}, {(self.np, L)}")
        Z = np.empty((M, self.nz, L))
        self._fn(z0, U, P, Z, int(M), int(K))
        return Z


class BatchedBlock:
    """The scalar engine's block function on a one-lane `LaneStepper` (batched calls), called as CasADi's block
    function is: (z (nz,), U (nu, K M + 1), p (np,)) -> the states at the M samples (nz, M)."""

    def __init__(self, stepper: LaneStepper, K: int, M: int):
        if stepper.lanes != 1:
            raise ValueError("BatchedBlock: a one-lane stepper is needed")
        self.stepper, self.K, self.M = stepper, int(K), int(M)

    def name(self) -> str:
        return self.stepper.name

    def __call__(self, z, U, p) -> np.ndarray:
        U = np.asarray(U, dtype=np.float64)
        Z = self.stepper.advance(np.asarray(z, dtype=np.float64).reshape(-1, 1), U.T[:, :, None],
                                 np.asarray(p, dtype=np.float64).reshape(-1, 1), self.K, self.M)
        return Z[:, :, 0].T
