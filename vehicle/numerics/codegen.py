"""Compiled code for CasADi functions: generate C, compile it with the system compiler, cache it.

The cache lives in ~/.cache/hpsim (or $HPSIM_CACHE), keyed by a hash of the generated code, the
compiler and its flags, so a structural change of the model compiles anew and everything else
reuses the library. Without a C compiler the function runs in CasADi's virtual machine.
"""
from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path

import casadi as ca


def cache_dir() -> Path:
    d = Path(os.environ.get("HPSIM_CACHE", Path.home() / ".cache" / "hpsim"))
    d.mkdir(parents=True, exist_ok=True)
    return d


# -freciprocal-math turns the model's many divisions by constants into multiplications and
# -fno-math-errno lets sqrt compile to one instruction; both change results at the last-bit level
# only. (No -ffast-math: NaN and infinity must survive, the drive checks for them.)
COMPILER_FLAGS = ("-O2", "-fno-math-errno", "-freciprocal-math", "-fno-trapping-math")


def compile_function(fn: ca.Function, *, opt_level: str = "-O2", verbose: bool = False) -> ca.Function:
    """Generate C for `fn`, compile it to a shared library (cached) and load it.

    Falls back to CasADi's virtual machine (slower, same results) when no C compiler is found.
    """
    cc = os.environ.get("CC") or shutil.which("gcc") or shutil.which("cc") or shutil.which("clang")
    if cc is None:
        warnings.warn("no C compiler found: running the model in CasADi's virtual machine (slower)")
        return fn
    with tempfile.TemporaryDirectory() as tmp:
        src_name = f"{fn.name()}.c"
        cg = ca.CodeGenerator(src_name, {"with_header": False})
        cg.add(fn)
        cwd = os.getcwd()
        os.chdir(tmp)
        try:
            cg.generate()
        finally:
            os.chdir(cwd)
        code = (Path(tmp) / src_name).read_bytes()
    key = hashlib.sha256(code + opt_level.encode() + " ".join(COMPILER_FLAGS).encode() + cc.encode()).hexdigest()[:20]
    lib = cache_dir() / f"{fn.name()}_{key}.so"
    if not lib.exists():
        src = cache_dir() / f"{fn.name()}_{key}.c"
        src.write_bytes(code)
        tmp_lib = lib.with_suffix(f".{os.getpid()}.tmp")
        t0 = time.perf_counter()
        flags = [opt_level, *COMPILER_FLAGS[1:]]
        res = subprocess.run([cc, *flags, "-fPIC", "-shared", str(src), "-o", str(tmp_lib), "-lm"],
                             capture_output=True, text=True)
        if res.returncode != 0:
            warnings.warn(f"C compilation failed ({res.stderr.strip()[:300]}); using CasADi's virtual machine")
            return fn
        os.replace(tmp_lib, lib)  # atomic: parallel sweep workers may compile the same model
        src.unlink(missing_ok=True)
        if verbose:
            print(f"compiled {fn.name()} in {time.perf_counter() - t0:.1f} s", file=sys.stderr)
    return ca.external(fn.name(), str(lib))
