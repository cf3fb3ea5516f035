"""The walk over an SX function's instruction list (vehicle.numerics.instructions), which the lane code generators,
the step graph's rewrites and the split step all read CasADi's algorithm through.

A replay without a rewrite is the same algorithm, instruction for instruction, and evaluates to the same bits; the
values a register holds are followed across CasADi's reuse of registers; the reciprocal rewrites built on the
replay change only the divisions they are meant to change.
"""
from __future__ import annotations

import casadi as ca
import numpy as np

from vehicle.numerics.instructions import defining_instructions, instructions, replay
from vehicle.numerics.step_graph import divisions_as_reciprocals, explicit_reciprocals


def _function() -> ca.Function:
    """Unary, binary and transcendental operations, a constant divisor, a parameter divisor used three times and
    enough intermediate values for CasADi to reuse registers."""
    x, p = ca.SX.sym("x", 3), ca.SX.sym("p", 2)
    a = ca.exp(-x[0] / 4.0) + ca.sqrt(x[1] * x[1] + 1.0)
    b = (x[0] - x[2]) / p[0] + ca.tanh(x[1] / p[0]) - x[2] / p[0]
    c = ca.fmax(a, b) * ca.log(1.0 + ca.fabs(x[2])) / p[1]
    return ca.Function("f", [x, p], [ca.vertcat(a, b), c], ["x", "p"], ["ab", "c"])


POINTS = [(np.array([0.3, -1.2, 2.5]), np.array([1.7, 0.9])), (np.array([-2.0, 0.1, 0.0]), np.array([3.0, 0.25]))]


def _values(fn: ca.Function, x, p) -> np.ndarray:
    return np.concatenate([np.asarray(v, float).ravel() for v in fn(x, p)])


def test_a_replay_without_a_rewrite_is_the_same_algorithm():
    f = _function()
    g = replay(f, lambda ins, operands: None)
    assert instructions(g) == instructions(f)
    for x, p in POINTS:
        assert np.array_equal(_values(g, x, p), _values(f, x, p))


def test_the_values_read_are_followed_across_reused_registers():
    """Evaluating each instruction on the values of the instructions it reads (not on registers) gives the
    function's outputs."""
    f = _function()
    x, p = POINTS[0]
    value: dict[int, float] = {}
    outputs: dict[tuple, float] = {}
    for ins, reads in defining_instructions(f):
        if ins.op == ca.OP_INPUT:
            value[ins.index] = (x, p)[ins.inputs[0]][ins.inputs[1]]
        elif ins.op == ca.OP_CONST:
            value[ins.index] = ins.constant
        elif ins.op == ca.OP_OUTPUT:
            outputs[ins.outputs] = value[reads[0]]
        else:
            args = [ca.DM(value[r]) for r in reads]
            value[ins.index] = float(ca.DM.binary(ins.op, *args) if len(args) == 2 else ca.DM.unary(ins.op, args[0]))
    assert f.sz_w() < len(value)                                   # registers were reused
    expected = _values(f, x, p)
    assert np.array_equal([outputs[(0, 0)], outputs[(0, 1)], outputs[(1, 0)]], expected)


def _divisions(fn: ca.Function) -> int:
    return sum(ins.op == ca.OP_DIV for ins in instructions(fn))


def test_the_reciprocal_rewrites_change_only_their_divisions():
    """Both rewrites turn the division by the constant 4 into a product with its reciprocal 0.25 (exact: a power of
    two, so the values keep every bit); a product with the reciprocal of a symbol is what CasADi's SX stores as
    the division itself, so the divisions by p stay as they are."""
    f = _function()
    assert _divisions(f) == 5
    for rewritten in (divisions_as_reciprocals(f, parameter_inputs={1}), explicit_reciprocals(f)):
        ops = [ins for ins in instructions(rewritten)]
        assert _divisions(rewritten) == 4
        assert any(ins.op == ca.OP_CONST and ins.constant == 0.25 for ins in ops)
        assert not any(ins.op == ca.OP_CONST and ins.constant == 4.0 for ins in ops)
        for x, p in POINTS:
            assert np.array_equal(_values(rewritten, x, p), _values(f, x, p))
