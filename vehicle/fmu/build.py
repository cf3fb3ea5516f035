"""Build an FMI 2.0 co-simulation FMU from an hpsim model (docs/fmu.md).

`FmuSpec` holds what the archive needs: the CasADi functions (one internal ROS2 step of hpsim's compiled solver,
the outputs, the start state, the calculated parameters), the internal step and the variables with units,
descriptions and start values. `build_fmu(spec, path)` generates their C with CasADi, compiles it with the FMI
wrapper (fmi2_wrapper.c) into binaries/<platform>/<id>.so, writes modelDescription.xml and zips everything with
the sources (the generated C, the wrapper and the three FMI 2.0 headers, BSD-2, from FMPy's package), so an
importer can rebuild the binary for another platform. The C is one file (sources/<id>.c: model.h, the wrapper and
the generated functions), compiled once and kept in hpsim's compile cache (vehicle.numerics.codegen).
"""
from __future__ import annotations

import hashlib
import importlib.util
import platform
import shutil
import tempfile
import time
import uuid
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import casadi as ca

from hpsim.errors import UserInputError
from hpsim.outputs import atomic_output
from hpsim.extras import install_hint
from vehicle.fmu.description import model_description
from vehicle.numerics import codegen
from vehicle.numerics.codegen import compile_source

WRAPPER = Path(__file__).with_name("fmi2_wrapper.c")
FMI_HEADERS = ("fmi2Functions.h", "fmi2FunctionTypes.h", "fmi2TypesPlatform.h")


DOUBLE_MAX = 1.7976931348623157e308     # the largest finite double (C's DBL_MAX): "no bound"


@dataclass
class Variable:
    """One FMI variable: `index` is its position in p (parameters), u (inputs) or y (outputs)."""

    name: str
    unit: str
    description: str
    index: int
    start: float | None = None
    min: float | None = None        # the allowed range of a parameter (fmi2SetReal refuses a value outside it)
    max: float | None = None


@dataclass
class FmuSpec:
    identifier: str                 # modelIdentifier: the binary's name (a C identifier)
    model_name: str
    description: str
    dt_s: float                     # the internal (solver) step
    step: ca.Function               # (z, u0, u1, pw) -> z: one ROS2 step, z = (x, solver memory)
    parametric: ca.Function         # p -> pw: p and the step's subexpressions of p alone
    outputs: ca.Function            # (x, memory, u, p) -> y
    initial: ca.Function            # (p, u) -> z at the start
    nx: int
    p_start: list[float]
    parameters: list[Variable]      # exposed entries of p (others stay internal)
    inputs: list[Variable]
    output_variables: list[Variable]
    rate_of: list[int]              # per input: the index of its rate input, or -1
    run: ca.Function | None = None  # p -> the calculated parameters
    calculated: list[Variable] = field(default_factory=list)   # the entries of p `run` sets
    stop_time_s: float = 10.0

    def parameter_bounds(self) -> tuple[list[float], list[float]]:
        """Per entry of p, the allowed [min, max] of a value set through FMI: an exposed parameter's range, the
        start value for an internal entry (it cannot be set), unbounded for a calculated one."""
        lo, hi = list(self.p_start), list(self.p_start)
        for v in self.parameters:
            lo[v.index] = -DOUBLE_MAX if v.min is None else v.min
            hi[v.index] = DOUBLE_MAX if v.max is None else v.max
        for v in self.calculated:
            lo[v.index], hi[v.index] = -DOUBLE_MAX, DOUBLE_MAX
        return lo, hi

    @property
    def sizes(self) -> dict:
        return {"np": len(self.p_start), "nu": len(self.inputs), "ny": len(self.output_variables),
                "nz": self.step.size1_out(0), "nx": self.nx, "npw": self.parametric.size1_out(0)}


def fmi_headers() -> Path:
    """The folder with the FMI 2.0 headers of the FMPy package (its c-code folder)."""
    spec = importlib.util.find_spec("fmpy")
    if spec is None or not spec.origin:
        raise UserInputError(f"hpsim export fmu: the FMI 2.0 headers come with FMPy: {install_hint('fmu')}")
    folder = Path(spec.origin).parent / "c-code"
    if not all((folder / h).is_file() for h in FMI_HEADERS):
        raise UserInputError(f"hpsim export fmu: FMPy at {folder.parent} has no FMI 2.0 headers in c-code/; "
                             f"reinstall it: {install_hint('fmu')}")
    return folder


def platform_folder() -> str:
    """The FMI 2.0 binaries folder of this machine."""
    system, bits = platform.system(), 64 if platform.architecture()[0] == "64bit" else 32
    names = {"Linux": "linux", "Darwin": "darwin", "Windows": "win"}
    if system not in names:
        raise UserInputError(f"hpsim export fmu: no FMI 2.0 platform name for {system}")
    return f"{names[system]}{bits}"


def _renamed(fn: ca.Function, name: str) -> ca.Function:
    args = fn.sx_in() if fn.is_a("SXFunction") else fn.mx_in()
    return ca.Function(name, args, fn.call(args), fn.name_in(), fn.name_out())


def generate_c(spec: FmuSpec, folder: Path) -> Path:
    """<id>_model.c in `folder`: hp_step, hp_param, hp_outputs, hp_init (and hp_run) as CasADi C (its helper
    functions are named after the file: <id>_model_sq, ...), with vehicle.numerics.vector_math's exp/log/pow/tanh."""
    file_name = f"{spec.identifier}_model.c"
    fns = [_renamed(fn, name) for fn, name in ((spec.step, "hp_step"), (spec.parametric, "hp_param"),
                                               (spec.outputs, "hp_outputs"), (spec.initial, "hp_init"),
                                               (spec.run, "hp_run")) if fn is not None]
    # exp, log, pow and tanh as the engine computes them (GCC and Clang; other compilers: the C library), so that
    # the FMU's arithmetic is the engine's
    path = folder / file_name
    path.write_bytes(codegen.generate_c(fns, file_name))
    return path


def _c_array(ctype: str, name: str, values) -> str:
    items = ", ".join(repr(float(v)) if ctype == "double" else str(int(v)) for v in values) or "0"
    return f"static const {ctype} {name}[] = {{{items}}};\n"


def model_header(spec: FmuSpec, guid: str) -> str:
    s = spec.sizes
    text = (f"/* generated by hpsim export fmu: {spec.model_name} */\n"
            f'#define HP_GUID "{guid}"\n#define HP_DT {spec.dt_s!r}\n'
            f"#define HP_NP {s['np']}\n#define HP_NU {s['nu']}\n#define HP_NY {s['ny']}\n"
            f"#define HP_NZ {s['nz']}\n#define HP_NX {s['nx']}\n#define HP_NPW {s['npw']}\n"
            f"#define HP_NRUN {len(spec.calculated)}\n")
    text += _c_array("double", "HP_P_START", spec.p_start)
    lo, hi = spec.parameter_bounds()
    text += _c_array("double", "HP_P_MIN", lo)
    text += _c_array("double", "HP_P_MAX", hi)
    text += _c_array("double", "HP_U_START", [v.start for v in spec.inputs])
    text += _c_array("int", "HP_RATE_OF", spec.rate_of)
    text += _c_array("int", "HP_RUN_INDEX", [v.index for v in spec.calculated])
    return text


# the generated functions stay private to the binary (two FMUs in one process must not clash), also when an
# importer rebuilds it from sources/ with its own flags
HIDDEN = b"""
/* ---- the model: CasADi-generated ---- */
#ifndef CASADI_SYMBOL_EXPORT
#if defined(__GNUC__) && !defined(_WIN32)
#define CASADI_SYMBOL_EXPORT __attribute__((visibility("hidden")))
#else
#define CASADI_SYMBOL_EXPORT
#endif
#endif
"""


def amalgamation(spec: FmuSpec, code: bytes, guid: str) -> bytes:
    """One C file: model.h, the FMI wrapper and the generated functions (includes only the FMI headers)."""
    wrapper = WRAPPER.read_text().replace('#include "model.h"\n', model_header(spec, guid))
    return wrapper.encode() + HIDDEN + code


def compile_binary(source: bytes, name: str, headers: Path) -> Path:
    """The shared library of an FMU's C (cached in hpsim's compile cache, vehicle.numerics.codegen)."""
    flags = (f"-I{headers}",)
    try:
        return compile_source(source, name, flags)
    except RuntimeError as exc:
        raise UserInputError(f"hpsim export fmu: {exc}") from None


def build_fmu(spec: FmuSpec, path: str | Path, *, verbose: bool = False) -> dict:
    """Write the FMU of `spec` to `path`; returns facts about it (size, GUID, build time)."""
    t0 = time.perf_counter()
    headers = fmi_headers()
    path = Path(path)
    with tempfile.TemporaryDirectory(prefix="hpsim-fmu-") as tmp:
        root = Path(tmp)
        src = root / "sources"
        src.mkdir()
        generated = generate_c(spec, root)
        code = generated.read_bytes()
        guid = "{" + str(uuid.UUID(hashlib.sha256(code + repr(spec.p_start).encode()).hexdigest()[:32])) + "}"
        source = amalgamation(spec, code, guid)
        c_file = f"{spec.identifier}.c"
        (src / c_file).write_bytes(source)
        for h in FMI_HEADERS:
            shutil.copy(headers / h, src / h)
        binaries = root / "binaries" / platform_folder()
        binaries.mkdir(parents=True)
        t1 = time.perf_counter()
        shutil.copy(compile_binary(source, spec.identifier, headers), binaries / f"{spec.identifier}.so")
        compile_s = time.perf_counter() - t1
        generated.unlink()
        (root / "modelDescription.xml").write_bytes(model_description(spec, guid, [c_file]))
        with atomic_output(path) as tmp_zip, zipfile.ZipFile(tmp_zip, "w", zipfile.ZIP_DEFLATED) as z:
            for f in sorted(root.rglob("*")):
                if f.is_file():
                    z.write(f, f.relative_to(root).as_posix())
    return {"path": str(path), "bytes": path.stat().st_size, "guid": guid, "build_s": time.perf_counter() - t0,
            "compile_s": compile_s}
