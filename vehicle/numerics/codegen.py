"""Compiled code for CasADi functions: generate C, compile it with the system compiler, cache it.

The cache lives in ~/.cache/hpsim (or $HPSIM_CACHE). A CasADi function given as a `Library` (what
the drives compile) is keyed by what determines its code: its name, the caller's key (the model's
structure, the step, the block shape), the source of hpsim's packages (`source_version`), CasADi's
version, the compiler and its flags. A run finds its library by that key before any graph is built,
and builds the graph and its C only when the library is missing. A plain `casadi.Function` is keyed by
a hash of its generated code, the compiler and its flags. Either way a structural change of the model
compiles anew and everything else reuses the library. Without a C compiler the function runs in
CasADi's virtual machine.

Trust model (README, "Set-up"): loading a library runs its code, so only libraries this user
built are loaded.

- The cache folder is created with mode 0700. A folder owned by another user or writable by
  group/others is not used: a private temporary cache (removed at exit) takes its place, with a
  warning.
- Beside each library `<name>_<key>.so` a record `<name>_<key>.json` holds the SHA-256 of the
  generated C and of the built library. A library is loaded only when the library bytes on disk
  match the record, and (a plain function) the record's C is the C this process generated, or (a
  `Library`, found by its key without generating C) the record holds that key and both files are
  this user's; anything else (truncated, empty, another model's library, a foreign file, no record)
  is rebuilt, never loaded. After loading, the function's inputs and outputs are compared with the
  model's (a `Library`: with the graph's, kept in the record when it was built).
- Libraries and records are written to temporary names and renamed into place (atomic), so
  parallel sweep workers compiling the same model never see half a file.
- The cache is bounded: beyond HPSIM_CACHE_MAX_MB (default 200 MB) the least recently used
  entries are removed after each build.
"""
from __future__ import annotations

import atexit
import functools
import hashlib
import json
import os
import shutil
import sys
import tempfile
import time
import warnings
from dataclasses import dataclass
from importlib.util import find_spec
from pathlib import Path
from typing import Callable

import casadi as ca

from hpsim.cache import CACHE_ENV, cache_problem, least_recently_used, remove_stale_temporaries, size_limit_bytes
from hpsim.stages import timed

from vehicle.numerics import compile_time, vector_math
from vehicle.numerics.compiler_processes import (BuildJob, CACHE_MAX_ENV, build_one, library_record, run_builds,
                                                 sha256_file)
from vehicle.numerics.direct_call import DirectFunction

DEFAULT_CACHE_MAX_MB = 200.0


@functools.lru_cache(maxsize=1)
def _private_cache() -> Path:
    d = Path(tempfile.mkdtemp(prefix="hpsim-cache-"))    # mode 0700
    atexit.register(shutil.rmtree, d, ignore_errors=True)
    return d


def cache_dir() -> Path:
    """The compile cache folder (created 0700); a private temporary one when it cannot be trusted. A bad
    HPSIM_CACHE_MAX_MB is a UserInputError whenever the cache is used, not only when it is trimmed."""
    cache_limit_bytes()
    d, problem = cache_problem()
    if problem is None:
        return d
    fallback = _private_cache()
    warnings.warn(f"compile cache {d}: {problem}; not used, compiling into a private cache {fallback} "
                  f"(removed at exit). Give {CACHE_ENV} a folder of your own (mode 0700).", stacklevel=2)
    return fallback


def cache_limit_bytes() -> float:
    return size_limit_bytes(CACHE_MAX_ENV, DEFAULT_CACHE_MAX_MB, 1.0, "the cache size limit")


# -fno-math-errno lets sqrt compile to one instruction (same result). No -ffast-math: NaN and infinity must
# survive, the drive checks for them; no value-changing flag at all: the divisions that -freciprocal-math turned
# into multiplications are rewritten in the SX graph instead (vehicle.numerics.step_graph.explicit_reciprocals), and
# no contraction into fused multiply-adds, so that every statement rounds as written and the vector lanes
# (vehicle.numerics.lanes) equal the scalar engine bit for bit.
COMPILER_FLAGS = ("-O2", "-fno-math-errno", "-fno-trapping-math", "-ffp-contract=off")


def _verified(lib: Path, record: Path, code_sha: str | None, lookup_key: str | None = None) -> bool:
    """The library on disk is the one built from this C code (code_sha), or the one recorded under this lookup key
    by this user (see the module's trust model)."""
    try:
        meta = json.loads(record.read_text())
        if not isinstance(meta, dict):
            return False
        if code_sha is not None and meta.get("c_sha256") != code_sha:
            return False
        if lookup_key is not None and (meta.get("lookup_key") != lookup_key or not _mine(lib) or not _mine(record)):
            return False
        return lib.stat().st_size == meta.get("library_bytes") and sha256_file(lib) == meta.get("library_sha256")
    except (OSError, ValueError):
        return False


def _mine(path: Path) -> bool:
    return not hasattr(os, "geteuid") or path.stat().st_uid == os.geteuid()


# the packages whose source builds the graphs (and generates their C): a change of any of them is a new key
SOURCE_PACKAGES = ("hpsim", "struts", "terrain", "vehicle")


@functools.lru_cache(maxsize=1)
def source_version() -> str:
    """SHA-256 of the Python source of SOURCE_PACKAGES as installed (each file's path and bytes): part of every
    `Library` key, so that an edit of the code that builds a graph or writes its C is never served an old library."""
    h = hashlib.sha256()
    for pkg in SOURCE_PACKAGES:
        spec = find_spec(pkg)
        for root in sorted(spec.submodule_search_locations or ()) if spec else ():
            for path in sorted(Path(root).rglob("*.py")):
                h.update(f"{pkg}/{path.relative_to(root).as_posix()}\0".encode())
                h.update(path.read_bytes())
    return h.hexdigest()


@dataclass(frozen=True)
class Library:
    """A CasADi function to compile, known before its graph is built: `name` (the function's own name, which the
    graph `build()` returns must carry) and `key` (what, besides hpsim's source and CasADi's version, determines
    its code: the model's structure, the step, the block shape). `compile_function` and `precompile` find its
    library in the cache by these and call `build` only when it is missing (or no compiler is found)."""
    name: str
    key: tuple
    build: Callable[[], ca.Function]

    def graph(self) -> ca.Function:
        fn = self.build()
        if fn.name() != self.name:
            raise ValueError(f"Library {self.name}: its graph is named {fn.name()}")
        return fn


def _signature(fn: ca.Function) -> str:
    """Digest of a function's inputs and outputs (count, shapes and sparsity patterns)."""
    parts = [(fn.n_in(), fn.n_out())]
    for sp in [fn.sparsity_in(i) for i in range(fn.n_in())] + [fn.sparsity_out(i) for i in range(fn.n_out())]:
        parts.append((sp.size1(), sp.size2(), tuple(sp.colind()), tuple(sp.row())))
    return hashlib.sha256(repr(parts).encode()).hexdigest()


def _same_signature(a: ca.Function, b: ca.Function) -> bool:
    if (a.n_in(), a.n_out()) != (b.n_in(), b.n_out()):
        return False
    return (all(a.sparsity_in(i) == b.sparsity_in(i) for i in range(a.n_in()))
            and all(a.sparsity_out(i) == b.sparsity_out(i) for i in range(a.n_out())))


def generate_c(fns: list[ca.Function], file_name: str) -> bytes:
    """CasADi's C of the functions `fns` in one file named `file_name` (its helpers are named after it), with
    vehicle.numerics.vector_math's exp, log, pow and tanh: what every compiled library is built from."""
    return vector_math.with_scalar_math(casadi_c(fns, file_name))


def casadi_c(fns: list[ca.Function], file_name: str) -> bytes:
    """CasADi's C of the functions `fns` in one file named `file_name`, as CasADi writes it (the C library's exp,
    log, pow and tanh)."""
    with tempfile.TemporaryDirectory() as tmp:
        cg = ca.CodeGenerator(file_name, {"with_header": False})
        for fn in fns:
            cg.add(fn)
        cwd = os.getcwd()
        os.chdir(tmp)                     # CasADi writes into the working folder
        try:
            cg.generate()
        finally:
            os.chdir(cwd)
        return (Path(tmp) / file_name).read_bytes()


def _generate_c(fn: ca.Function) -> bytes:
    return generate_c([fn], f"{fn.name()}.c")


def evict(d: Path, limit_bytes: float, keep: tuple[str, ...] = ()) -> list[str]:
    """Remove least recently used entries (by the record's time, touched on each use) until the
    cache holds at most `limit_bytes`; entries whose stem is in `keep` stay. Returns removed stems."""
    remove_stale_temporaries(d, ".build-*")
    entries: dict[str, list[Path]] = {}
    for p in d.iterdir():
        if p.name.startswith(".build-"):
            continue
        if p.suffix in (".so", ".json", ".c", ".casadi") or p.name.endswith(".tmp"):
            entries.setdefault(p.name.split(".", 1)[0], []).append(p)

    def use_and_size(paths):
        there = [p.stat() for p in paths if p.exists()]
        return max((st.st_mtime for st in there), default=0.0), sum(st.st_size for st in there)

    removed = least_recently_used({stem: use_and_size(paths) for stem, paths in entries.items()}, limit_bytes, keep)
    for stem in removed:
        for p in entries[stem]:
            try:
                p.unlink()
            except OSError:
                pass
    return removed


def _compiler() -> str | None:
    return os.environ.get("CC") or shutil.which("gcc") or shutil.which("cc") or shutil.which("clang")


@dataclass(frozen=True)
class CLibrary:
    """Hand-generated C (not a CasADi function: `vehicle.numerics.lanes`) to compile, known before its C is written:
    `name`, `key` (what, besides hpsim's source, determines the C: the model's structure, the step, the lanes) and
    `extra_flags`; `build()` returns the C, called only when the library is missing from the cache.
    `compile_library` and `precompile` find it by these, as `Library`s."""
    name: str
    key: tuple
    build: Callable[[], bytes]
    extra_flags: tuple[str, ...] = ()


def _c_flags(opt_level: str, extra_flags: tuple[str, ...]) -> list[str]:
    return [opt_level, *COMPILER_FLAGS[1:], *extra_flags]


def _c_stem(code: bytes, name: str, flags: list[str], cc: str) -> str:
    return f"{name}_{hashlib.sha256(code + ' '.join(flags).encode() + cc.encode()).hexdigest()[:20]}"


def _plan(fn, cc: str, opt_level: str):
    """(flags, code, code_sha, cache folder, stem) of the library of CasADi function `fn`: its C and where the cache
    keeps it."""
    code = _generate_c(fn)
    code_sha = hashlib.sha256(code).hexdigest()
    flags = [opt_level, *COMPILER_FLAGS[1:]]
    key = hashlib.sha256(code + opt_level.encode() + " ".join(COMPILER_FLAGS).encode() + cc.encode()).hexdigest()[:20]
    return flags, code, code_sha, cache_dir(), f"{fn.name()}_{key}"


def lookup_key(lib: Library, cc: str, opt_level: str = "-O2") -> str:
    """The cache key of a `Library`: its name and key, hpsim's source, CasADi's version, the compiler, its flags."""
    text = repr((lib.name, lib.key, source_version(), ca.__version__, cc, opt_level, COMPILER_FLAGS))
    return hashlib.sha256(text.encode()).hexdigest()[:20]


def _library_stem(lib: Library | CLibrary, cc: str, opt_level: str) -> tuple[Path, str, str]:
    """(cache folder, stem, lookup key) of a `Library` or `CLibrary` (whose extra flags are part of its key)."""
    key = lookup_key(lib if isinstance(lib, Library) else Library(lib.name, (lib.key, lib.extra_flags), None),
                     cc, opt_level)
    return cache_dir(), f"{lib.name}_{key}", key


def _clibrary_job(lib: CLibrary, cc: str, opt_level: str, d: Path, stem: str, key: str):
    """The build job of a `CLibrary` missing from the cache (its C written now)."""
    code = lib.build()
    return BuildJob(cc, _c_flags(opt_level, lib.extra_flags), code, hashlib.sha256(code).hexdigest(), d, stem,
                    {"lookup_key": key})


def compile_library(lib: CLibrary, *, opt_level: str = "-O2", cc: str | None = None) -> tuple[Path | None, str]:
    """The library of a `CLibrary`, found in the cache by its key (its C not written) or built: (path, "") or
    (None, why not: no compiler, the compiler's error). The caller loads it (ctypes)."""
    cc = cc or _compiler()
    if cc is None:
        return None, "no C compiler found"
    d, stem, key = _library_stem(lib, cc, opt_level)
    so, record = d / f"{stem}.so", d / f"{stem}.json"
    if not _verified(so, record, None, key):
        job = _clibrary_job(lib, cc, opt_level, d, stem, key)
        compile_time.announce([len(job.code)], 1, d)
        t0 = time.perf_counter()
        error = _cache_build(job, key)
        if error is not None:
            return None, error
        compile_time.add_compiled_s(time.perf_counter() - t0)
    _touch(record)
    return so, ""


def _library_job(lib: Library, cc: str, opt_level: str, d: Path, stem: str, key: str):
    """The graph of a `Library` missing from the cache, and its build job."""
    graph = lib.graph()
    code = _generate_c(graph)
    meta = {"lookup_key": key, "signature": _signature(graph)}
    return graph, BuildJob(cc, [opt_level, *COMPILER_FLAGS[1:]], code, hashlib.sha256(code).hexdigest(), d, stem, meta)


def _load_library(lib: Library, d: Path, stem: str) -> ca.Function | None:
    """The cached library `stem` of `lib` loaded, when its signature is the one recorded when it was built."""
    compiled = ca.external(lib.name, str(d / f"{stem}.so"))
    try:
        recorded = json.loads((d / f"{stem}.json").read_text()).get("signature")
    except (OSError, ValueError, AttributeError):
        recorded = None
    return compiled if recorded == _signature(compiled) else None


def precompile(fns, *, opt_level: str = "-O2") -> int:
    """Build the libraries of several functions (`casadi.Function`, `Library` or `CLibrary`) at once, one compiler
    process each, so that `compile_function` and `compile_library` then find them in the cache; returns how many
    were built.

    A drive needs two or three libraries (the block stepper, the half-step stepper of its error estimate, the
    block outputs) of about 5 s of compiler time each: built one after the other they add up, built together
    they take about the longest one on a machine with that many cores. Only the compilers run in parallel (at
    most one per core, processes started here and waited for); the C is generated here, one function after the
    other (a `Library` found in the cache by its key: neither its graph nor its C). A Ctrl-C stops every
    compiler and keeps nothing; a failed build is left to `compile_function`, which reports it and falls back to
    the virtual machine.
    """
    cc = _compiler()
    if cc is None:
        return 0

    def plan(fn):
        if isinstance(fn, CLibrary):
            d, stem, key = _library_stem(fn, cc, opt_level)
            return None if _verified(d / f"{stem}.so", d / f"{stem}.json", None, key) else \
                _clibrary_job(fn, cc, opt_level, d, stem, key)
        if isinstance(fn, Library):
            d, stem, key = _library_stem(fn, cc, opt_level)
            if _verified(d / f"{stem}.so", d / f"{stem}.json", None, key):
                return None
            return _library_job(fn, cc, opt_level, d, stem, key)[1]
        flags, code, code_sha, d, stem = _plan(fn, cc, opt_level)
        if _verified(d / f"{stem}.so", d / f"{stem}.json", code_sha):
            return None
        return BuildJob(cc, flags, code, code_sha, d, stem)
    todo: list[BuildJob] = []
    for job in timed("compile: looked up in the cache (C generated when missing)", lambda: [plan(f) for f in fns]):
        if job is not None and job.stem not in {t.stem for t in todo}:
            todo.append(job)
    width = max(1, os.cpu_count() or 1)                         # no more compilers than cores
    if todo:
        compile_time.announce([len(t.code) for t in todo], width, todo[0].folder)
    t0 = time.perf_counter()
    timed("compile", run_builds, todo, width=width)
    if todo:
        compile_time.record([len(t.code) for t in todo], width, time.perf_counter() - t0, todo[0].folder)
        evict(todo[0].folder, cache_limit_bytes(), keep=tuple(t.stem for t in todo))
    return len(todo)


def compile_c(code: bytes, name: str, extra_flags: tuple[str, ...] = (), *, opt_level: str = "-O2",
              cc: str | None = None) -> tuple[Path | None, str]:
    """Compile hand-generated C `code` (not a CasADi function: e.g. `vehicle.numerics.lanes`) into a cached, verified
    shared library (the same cache, records and trust model as `compile_function`): (path of the library, "") or
    (None, why not: no compiler, the compiler's error). The caller loads it (ctypes)."""
    cc = cc or _compiler()
    if cc is None:
        return None, "no C compiler found"
    flags = _c_flags(opt_level, tuple(extra_flags))
    code_sha = hashlib.sha256(code).hexdigest()
    d = cache_dir()
    stem = _c_stem(code, name, flags, cc)
    lib, record = d / f"{stem}.so", d / f"{stem}.json"
    if not _verified(lib, record, code_sha):
        error = _cache_build(BuildJob(cc, flags, code, code_sha, d, stem))
        if error is not None:
            return None, error
    _touch(record)
    return lib, ""


def compile_function(fn: ca.Function | Library, *, opt_level: str = "-O2", verbose: bool = False,
                     direct: bool = False):
    """Generate C for `fn`, compile it to a shared library (cached, verified) and load it. A `Library` found in the
    cache by its key is loaded without building its graph. direct: the loaded library as a
    `vehicle.numerics.direct_call.DirectFunction` (called on NumPy arrays without CasADi's conversions).

    Falls back to CasADi's virtual machine (slower; the same results to rounding: it calls the C library's exp, log,
    pow and tanh, the compiled code vehicle.numerics.vector_math's) when no C compiler is found
    or the compilation fails.
    """
    cc = _compiler()
    if cc is None:
        warnings.warn("no C compiler found: running the model in CasADi's virtual machine (slower)")
        return fn.graph() if isinstance(fn, Library) else fn
    if isinstance(fn, Library):
        return _compile_library(fn, cc, opt_level, verbose, direct)
    flags, code, code_sha, d, stem = _plan(fn, cc, opt_level)
    lib, record = d / f"{stem}.so", d / f"{stem}.json"
    if not _verified(lib, record, code_sha):
        error = _compile_announced(fn.name(), BuildJob(cc, flags, code, code_sha, d, stem), verbose)
        if error is not None:
            return fn
        if not _verified(lib, record, code_sha):     # replaced by someone else in between
            warnings.warn(f"compile cache {d}: {lib.name} changed while it was built; "
                          "using CasADi's virtual machine")
            return fn
    _touch(record)
    compiled = ca.external(fn.name(), str(lib))
    if not _same_signature(compiled, fn):
        warnings.warn(f"compile cache {d}: {lib.name} does not match the model; using CasADi's virtual machine")
        return fn
    return _loaded(compiled, lib, direct)


def _loaded(compiled: ca.Function, lib: Path, direct: bool):
    """The library loaded as `compile_function` returns it: the `casadi.external`, or called directly."""
    return DirectFunction(compiled, str(lib)) if direct else compiled


def _compile_library(spec: Library, cc: str, opt_level: str, verbose: bool, direct: bool = False):
    """compile_function of a `Library`: found by its key (no graph built), else built from its graph."""
    d, stem, key = _library_stem(spec, cc, opt_level)
    lib, record = d / f"{stem}.so", d / f"{stem}.json"
    if _verified(lib, record, None, key):
        compiled = _load_library(spec, d, stem)
        if compiled is not None:
            _touch(record)
            return _loaded(compiled, lib, direct)
    graph, job = _library_job(spec, cc, opt_level, d, stem, key)
    if _compile_announced(spec.name, job, verbose) is not None:
        return graph
    compiled = _load_library(spec, d, stem) if _verified(lib, record, job.code_sha, key) else None
    if compiled is None or not _same_signature(compiled, graph):
        warnings.warn(f"compile cache {d}: {lib.name} changed while it was built or does not match the model; "
                      "using CasADi's virtual machine")
        return graph
    _touch(record)
    return _loaded(compiled, lib, direct)


def _compile_announced(name: str, job: BuildJob, verbose: bool) -> str | None:
    """Build one library (announced, its time counted, the cache trimmed); None when built, else the error (warned
    about: the caller falls back to the virtual machine)."""
    compile_time.announce([len(job.code)], 1, job.folder)
    t0 = time.perf_counter()
    error = build_one(job)
    if error is not None:
        warnings.warn(f"C compilation failed ({error}); using CasADi's virtual machine")
        return error
    compile_time.add_compiled_s(time.perf_counter() - t0)
    if verbose:
        print(f"compiled {name} in {time.perf_counter() - t0:.1f} s", file=sys.stderr)
    evict(job.folder, cache_limit_bytes(), keep=(job.stem,))
    return None


def _cache_build(job: BuildJob, lookup_key: str | None = None) -> str | None:
    """Build one job into the cache, trim the cache and
    check what is there now: None when the library is the one built, else why not (the compiler's error, or
    replaced by someone else in between)."""
    error = build_one(job)
    if error is not None:
        return error
    evict(job.folder, cache_limit_bytes(), keep=(job.stem,))
    if not _verified(job.folder / f"{job.stem}.so", job.folder / f"{job.stem}.json", job.code_sha, lookup_key):
        return f"{job.stem}.so changed while it was built"
    return None


def _touch(record: Path) -> None:
    try:
        os.utime(record)                # last use, for the eviction order
    except OSError:
        pass


def compile_source(code: bytes, name: str, extra_flags: tuple[str, ...] = ()) -> Path:
    """Compile a self-contained C translation unit into a shared library in the cache (built once, verified like
    the model libraries: see the module's trust model) and return its path. For C that is not one CasADi
    function (the FMU binaries of vehicle.fmu): `compile_c`, raising RuntimeError without a compiler or when it
    fails."""
    if _compiler() is None:
        raise RuntimeError("no C compiler found (gcc, cc or clang; or set CC)")
    lib, error = compile_c(code, name, tuple(extra_flags))
    if lib is None:
        raise RuntimeError(f"C compilation of {name} failed: {error}")
    return lib


def serialized_function(lib: Library) -> ca.Function:
    """A `Library`'s graph kept in the cache as CasADi's serialization (`<name>_<key>.casadi`, no C, no compiler):
    for functions that are built in a fraction of a second but evaluated a few times only, where compiling does not
    pay and building the model's equations does (the linearisation's Jacobians: 0.15 s to build, 15 ms to read).
    Found by the `Library`'s lookup key (hpsim's source, CasADi's version) and loaded only under the module's trust
    model: the record holds the file's SHA-256 and that key, and both files are this user's (a deserialized
    function can name a library to load). Anything else is built again and written atomically."""
    key = lookup_key(lib, "serialized")
    d = cache_dir()
    stem = f"{lib.name}_{key}"
    data, record = d / f"{stem}.casadi", d / f"{stem}.json"
    if _verified(data, record, None, key):
        fn = ca.Function.deserialize(data.read_text())
        if fn.name() == lib.name:
            _touch(record)
            return fn
    fn = lib.graph()
    text = fn.serialize()
    tmp = None
    try:
        tmp = Path(tempfile.mkdtemp(prefix=f".build-{stem}-", dir=d))
        (tmp / data.name).write_text(text)
        meta = {**library_record(tmp / data.name), "lookup_key": key}
        (tmp / record.name).write_text(json.dumps(meta))
        os.replace(tmp / data.name, data)             # the data first: an old record with new data fails to verify
        os.replace(tmp / record.name, record)
        evict(d, cache_limit_bytes(), keep=(stem,))
    except OSError:
        pass                               # a cache that cannot be written: the function is used as built
    finally:
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)
    return fn
