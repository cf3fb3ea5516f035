"""A solver made ready for an engine's blocks: its libraries compiled together, then bound.

Every engine integrates blocks of M output samples of K solver steps. Before binding, the compiled
libraries an engine needs (the solver's block function, its extra graphs such as the step-doubling probes,
the block outputs, and any library of the engine's own, such as the multiscale slow-rate Jacobian) are
compiled together, one compiler each, when the cache misses them (`vehicle.numerics.codegen.precompile`).
"""
from __future__ import annotations

from dataclasses import dataclass

from vehicle.numerics.codegen import precompile
from vehicle.numerics.solvers import compiled_outputs, outputs_graph


@dataclass
class BoundSolver:
    """solver: the solver bound to blocks of (K, M); outputs: the compiled block outputs, or None (CasADi's
    virtual machine: an uncompiled solver, or one whose capabilities say compiled_outputs False)."""

    solver: object
    outputs: object | None


def bind_solver(solver, model, steps_per_sample: int, samples_per_call: int, *, graphs: list = (),
                libraries: list = ()) -> BoundSolver:
    """`solver` bound to blocks of samples_per_call samples of steps_per_sample steps, with `graphs` (more uncompiled
    functions of the solver: probes) and `libraries` (`codegen.Library`) compiled beside its block function."""
    caps = solver.capabilities
    if caps.compiled:
        block = [solver.block_graph(model, steps_per_sample, samples_per_call)] + list(graphs)
        if caps.compiled_outputs:
            block.append(outputs_graph(model, samples_per_call))
        precompile([g for g in block + list(libraries) if g is not None])
    bound = solver.bind(model, steps_per_sample, samples_per_call)
    return BoundSolver(bound, compiled_outputs(model, samples_per_call) if caps.compiled_outputs else None)
