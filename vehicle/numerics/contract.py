"""The solver contract: what a drive may ask of a solver, and which optional capabilities a solver
declares (never probed with hasattr).

    bind(model, steps_per_sample, samples_per_call) -> the solver, ready (compiled or built)
    advance(x0, U, p) -> X           the states at the end of each output sample of one block
    get_state() / set_state(memory)  the warm-start memory a checkpoint saves
    describe() -> dict               what the results record about the solver
    capabilities: SolverCapabilities

Optional, by capability:
    compiled             block_graph(model, K, M): the uncompiled function to build together with others
                         (vehicle.numerics.codegen.precompile); the drive's outputs are compiled too
    step_doubling        refined_solver(factor) / refined(model, factor): the same method at dt/factor for the
                         a-posteriori error estimate (vehicle.numerics.error_estimate)
    compiled_outputs     the drive may evaluate its block outputs in one compiled call (False: CasADi's
                         virtual machine)
    thread_bound         advance only on the thread that bound it (an ensemble lane, whose block waits for the
                         other lanes under the lanes' lock): the drive keeps its integration and the work that
                         builds CasADi graphs on that thread (no windows or proxies on threads of their own)
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np


@dataclass(frozen=True)
class SolverCapabilities:
    compiled: bool = False
    step_doubling: bool = False
    compiled_outputs: bool = False
    thread_bound: bool = False


class Solver(Protocol):
    name: str
    dt: float
    capabilities: SolverCapabilities

    def bind(self, model, steps_per_sample: int, samples_per_call: int) -> "Solver": ...

    def advance(self, x0: np.ndarray, U: np.ndarray, p: np.ndarray) -> np.ndarray: ...

    def get_state(self) -> np.ndarray: ...

    def set_state(self, memory) -> None: ...

    def describe(self) -> dict: ...
