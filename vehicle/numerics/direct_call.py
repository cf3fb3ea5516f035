"""A compiled CasADi function called on NumPy arrays through its C interface (ctypes), without CasADi's conversions.

`casadi.external(name, library)` called with NumPy arrays converts every argument to a DM first, which
costs more than the compiled code itself on a drive's block outputs (`vehicle.numerics.solvers.compiled_outputs`;
CHANGELOG.md, "Measurement history"). `DirectFunction` calls the same library's entry point, CasADi's generated C
interface (CasADi's code generation guide, "Calling generated code"):

    int f(const casadi_real** arg, casadi_real** res, casadi_int* iw, casadi_real* w, int mem)
    int f_work(casadi_int* sz_arg, casadi_int* sz_res, casadi_int* sz_iw, casadi_int* sz_w)

with the arguments' nonzeros in column-major order (the dense inputs: NumPy's Fortran order) and the outputs
scattered to dense arrays by their sparsity. Same code, same values as the `casadi.external` it wraps, bit for bit
(tests/unit/numerics/test_direct_call.py).
"""
from __future__ import annotations

import ctypes

import casadi as ca
import numpy as np


class DirectFunction:
    """`fn` (a `casadi.external` of `library`) callable on NumPy arrays: fn(*args) -> list of dense (n, m) arrays,
    the values of `np.asarray(fn(*args)[i])`. Arguments are anything `np.asarray` takes with the input's shape
    (a scalar or a vector for a column). Thread-safe: each call has its own work buffers."""

    def __init__(self, fn: ca.Function, library: str):
        self.fn = fn
        self.name = fn.name()
        self._lib = ctypes.CDLL(str(library))
        int_size = int(getattr(self._lib, f"{self.name}_casadi_int_size")())
        self._int = {4: ctypes.c_int32, 8: ctypes.c_int64}[int_size]
        self._int_dtype = np.dtype(f"i{int_size}")
        sizes = (self._int * 4)()
        work = getattr(self._lib, f"{self.name}_work")
        if work(*(ctypes.byref(sizes, k * int_size) for k in range(4))) != 0:
            raise RuntimeError(f"{self.name}_work failed")
        self.sz_arg, self.sz_res, self.sz_iw, self.sz_w = (int(v) for v in sizes)
        self._call = getattr(self._lib, self.name)
        self._call.restype = ctypes.c_int
        self.in_shapes = [fn.sparsity_in(i).shape for i in range(fn.n_in())]
        if not all(fn.sparsity_in(i).is_dense() for i in range(fn.n_in())):
            raise ValueError(f"{self.name}: DirectFunction takes dense inputs only")
        self.out_shapes, self.out_index = [], []
        for i in range(fn.n_out()):
            sp = fn.sparsity_out(i)
            self.out_shapes.append(sp.shape)
            # a sparse output's nonzeros: their positions in the dense array's Fortran-order values
            self.out_index.append(None if sp.is_dense() else np.asarray(sp.find(), dtype=np.intp))
        self.out_nnz = [fn.nnz_out(i) for i in range(fn.n_out())]
        self._incref = getattr(self._lib, f"{self.name}_incref", None)
        if self._incref is not None:
            self._incref()

    def __call__(self, *args) -> list[np.ndarray]:
        if len(args) != len(self.in_shapes):
            raise TypeError(f"{self.name}: {len(args)} arguments for {len(self.in_shapes)} inputs")
        inputs = []
        for a, shape in zip(args, self.in_shapes):
            v = np.asarray(a, dtype=np.float64)
            if v.shape != shape:
                if v.ndim == 2 or v.size != shape[0] * shape[1]:
                    raise ValueError(f"{self.name}: an argument of shape {v.shape} for an input of shape {shape}")
                v = v.reshape(shape, order="F")
            inputs.append(np.asfortranarray(v))
        nz = [np.empty(n) for n in self.out_nnz]
        arg = (ctypes.c_void_p * max(self.sz_arg, len(inputs)))(*(a.ctypes.data for a in inputs))
        res = (ctypes.c_void_p * max(self.sz_res, len(nz)))(*(r.ctypes.data for r in nz))
        iw = np.empty(max(self.sz_iw, 1), dtype=self._int_dtype)
        w = np.empty(max(self.sz_w, 1))
        flag = self._call(arg, res, ctypes.c_void_p(iw.ctypes.data), ctypes.c_void_p(w.ctypes.data), 0)
        if flag != 0:
            raise RuntimeError(f"{self.name} returned {flag}")
        out = []
        for values, shape, index in zip(nz, self.out_shapes, self.out_index):
            if index is None:
                out.append(values.reshape(shape, order="F"))
            else:
                full = np.zeros(shape[0] * shape[1])
                full[index] = values
                out.append(full.reshape(shape, order="F"))
        return out
