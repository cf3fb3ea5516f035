"""The layers import one way only (README "How the code is laid out", docs/CONTRIBUTING.md):

    hpsim  <-  struts, terrain  <-  vehicle.physics, vehicle.numerics  <-  vehicle.scenario
           <-  vehicle.engines  <-  vehicle.results  <-  vehicle.analysis  <-  vehicle.studies
           <-  vehicle.presentation, vehicle.fmu  <-  vehicle.cli, vehicle.api

Checked statically on every module (also imports inside functions), and at run time for the
two physics libraries that must stay usable without the vehicle. No two modules import each other,
directly or through others (no import cycle), and the code keeps the sizes that make it readable.
"""
from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
PACKAGES = ("hpsim", "struts", "terrain", "vehicle")

_ORDER = ["hpsim", "struts|terrain", "vehicle.physics|vehicle.numerics", "vehicle.scenario", "vehicle.engines",
          "vehicle.results", "vehicle.analysis", "vehicle.studies", "vehicle.presentation|vehicle.fmu",
          "vehicle.cli|vehicle.api|vehicle"]


def _allowed() -> dict[str, set[str]]:
    """layer -> the layers its modules may import (itself included): every lower rung of _ORDER.
    Siblings on one rung know nothing of each other (struts/terrain; physics/numerics), except the
    top rung (the CLI, the API and the package facade that re-exports it)."""
    out, below = {}, set()
    for rung in _ORDER:
        names = rung.split("|")
        for name in names:
            out[name] = below | {name} | (set(names) if name in ("vehicle.cli", "vehicle.api", "vehicle") else set())
        below |= set(names)
    out["vehicle.physics"] = {"hpsim", "struts", "terrain", "vehicle.physics"}
    out["vehicle.numerics"] = {"hpsim", "vehicle.numerics"}   # solvers receive CasADi functions, no physics
    return out


# layer -> the layers its modules may import (itself included)
ALLOWED = _allowed()


def layer_of(module: str) -> str | None:
    parts = module.split(".")
    if parts[0] not in PACKAGES:
        return None
    if parts[0] == "vehicle" and len(parts) > 1 and f"vehicle.{parts[1]}" in ALLOWED:
        return f"vehicle.{parts[1]}"
    return parts[0]


def module_name(path: Path) -> str:
    rel = path.relative_to(REPO).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def imports_of(path: Path, module: str | None = None) -> list[tuple[int, str]]:
    """(line, imported module) of every import in the file; `module`: the file's module name (default: from its
    place in the source tree), which relative imports are resolved against."""
    tree = ast.parse(path.read_text(), str(path))
    me = module or module_name(path)
    package = me if path.name == "__init__.py" else me.rsplit(".", 1)[0]
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [(node.lineno, a.name) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[:len(base) - (node.level - 1)]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module
            if node.module is None or node.level:
                # `from . import x` may name submodules: check each as a module
                out += [(node.lineno, f"{target}.{a.name}" if node.module is None else target) for a in node.names]
            else:
                out.append((node.lineno, target))
    return out


def source_files():
    for pkg in PACKAGES:
        yield from sorted((REPO / pkg).rglob("*.py"))


@pytest.mark.parametrize("path", list(source_files()), ids=lambda p: str(p.relative_to(REPO)))
def test_module_imports_only_its_own_and_lower_layers(path):
    mine = layer_of(module_name(path))
    bad = []
    for line, target in imports_of(path):
        theirs = layer_of(target)
        if theirs is not None and theirs not in ALLOWED[mine]:
            bad.append(f"{path.relative_to(REPO)}:{line} imports {target} ({theirs}), not allowed from {mine}")
    assert not bad, "\n".join(bad)


def test_the_checker_sees_a_violation(tmp_path):
    """The rule can fail: a physics module importing the running layer is reported. The probe module is written
    outside the source tree (which other test workers hash for the compile cache's keys) and read as if it were
    vehicle.physics._layer_probe."""
    fake = tmp_path / "_layer_probe.py"
    fake.write_text("from vehicle.engines import full\nfrom ..scenario.schema import prepare\n")
    targets = [layer_of(t) for _, t in imports_of(fake, "vehicle.physics._layer_probe")]
    assert targets == ["vehicle.engines", "vehicle.scenario"]
    assert "vehicle.engines" not in ALLOWED["vehicle.physics"]
    assert "vehicle.studies" not in ALLOWED["vehicle.engines"]


@pytest.mark.parametrize("package, forbidden", [("terrain", ("struts", "vehicle")), ("struts", ("terrain", "vehicle"))])
def test_physics_libraries_load_alone(package, forbidden):
    """Importing every module of struts (terrain) loads neither terrain (struts) nor vehicle."""
    mods = sorted(module_name(p) for p in (REPO / package).rglob("*.py"))
    code = (f"import sys, importlib; [importlib.import_module(m) for m in {mods!r}]; "
            f"print([m for m in sys.modules if m.split('.')[0] in {forbidden!r}])")
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=REPO)
    assert res.stdout.strip() == "[]"


# --- no import cycles ---------------------------------------------------------------------------------
def _module_files() -> dict[str, Path]:
    return {module_name(p): p for p in source_files()}


def import_graph(files: dict[str, Path]) -> dict[str, set[str]]:
    """module -> the project modules it imports (module level and inside functions). `from pkg import
    name` counts as an import of the module pkg.name where that is a module, else of pkg."""
    graph = {}
    for mod, path in files.items():
        tree = ast.parse(path.read_text(), str(path))
        package = mod if path.name == "__init__.py" else mod.rsplit(".", 1)[0]
        edges = set()
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                edges |= {a.name for a in node.names}
            elif isinstance(node, ast.ImportFrom):
                if node.level:
                    base = package.split(".")[:len(package.split(".")) - (node.level - 1)]
                    target = ".".join(base + ([node.module] if node.module else []))
                else:
                    target = node.module
                for a in node.names:
                    sub = f"{target}.{a.name}"
                    edges.add(sub if sub in files else target)
        graph[mod] = {e for e in edges if e in files and e != mod}
    return graph


def import_cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan), each a cycle or several."""
    index, low, on_stack, stack, out = {}, {}, set(), [], []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    sys.setrecursionlimit(max(10_000, sys.getrecursionlimit()))
    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def test_no_import_cycle_between_modules():
    cycles = import_cycles(import_graph(_module_files()))
    assert not cycles, "import cycles:\n" + "\n".join(" <-> ".join(c) for c in cycles)


def test_the_cycle_checker_catches_a_cycle():
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}, "e": set()}
    assert import_cycles(graph) == [["a", "b", "c"]]
    assert import_cycles({"a": {"b"}, "b": set()}) == []


def test_the_graph_resolves_submodules_and_packages(tmp_path):
    pkg = tmp_path / "vehicle" / "probe"
    files = {"vehicle.probe.one": pkg / "one.py", "vehicle.probe.two": pkg / "two.py", "vehicle.probe": pkg / "__init__.py"}
    pkg.mkdir(parents=True)
    files["vehicle.probe.one"].write_text("from vehicle.probe import two\n")
    files["vehicle.probe.two"].write_text("def f():\n    from .one import x\n")
    files["vehicle.probe"].write_text("")
    graph = import_graph(files)
    assert graph["vehicle.probe.one"] == {"vehicle.probe.two"}
    assert graph["vehicle.probe.two"] == {"vehicle.probe.one"}
    assert import_cycles(graph) == [["vehicle.probe.one", "vehicle.probe.two"]]


# --- sizes that keep the code readable (issue 19) -----------------------------------------------------
MAX_MODULE_LINES = 700
MAX_FUNCTION_LINES = 120
MAX_LOCAL_IMPORTS = 15          # project imports inside functions under vehicle/, the CLI aside
MAX_PACKAGE_SHARE = 0.30        # of vehicle/'s lines in one sub-package


def test_no_module_or_function_too_long():
    long_modules, long_functions = [], []
    for mod, path in _module_files().items():
        src = path.read_text()
        if len(src.splitlines()) > MAX_MODULE_LINES:
            long_modules.append(f"{path.relative_to(REPO)}: {len(src.splitlines())} lines")
        for node in ast.walk(ast.parse(src)):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                n = node.end_lineno - node.lineno + 1
                if n > MAX_FUNCTION_LINES:
                    long_functions.append(f"{path.relative_to(REPO)}:{node.lineno} {node.name}: {n} lines")
    assert not long_modules and not long_functions, "\n".join(long_modules + long_functions)


def _local_project_imports() -> list[str]:
    out = []
    for mod, path in _module_files().items():
        if not mod.startswith("vehicle.") or mod.startswith("vehicle.cli"):
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                for sub in ast.walk(node):
                    if isinstance(sub, ast.Import) and any(a.name.split(".")[0] in PACKAGES for a in sub.names):
                        out.append(f"{path.relative_to(REPO)}:{sub.lineno}")
                    elif isinstance(sub, ast.ImportFrom) and (sub.level or (sub.module or "").split(".")[0] in PACKAGES):
                        out.append(f"{path.relative_to(REPO)}:{sub.lineno}")
    return sorted(set(out))


def test_few_project_imports_inside_functions():
    local = _local_project_imports()
    assert len(local) <= MAX_LOCAL_IMPORTS, f"{len(local)} project imports inside functions:\n" + "\n".join(local)


def test_no_vehicle_package_holds_too_much():
    lines = {}
    for path in (REPO / "vehicle").rglob("*.py"):
        rel = path.relative_to(REPO / "vehicle")
        key = rel.parts[0] if len(rel.parts) > 1 else "(top)"
        lines[key] = lines.get(key, 0) + len(path.read_text().splitlines())
    total = sum(lines.values())
    big = {k: round(v / total, 3) for k, v in lines.items() if v / total > MAX_PACKAGE_SHARE}
    assert not big, f"packages over {MAX_PACKAGE_SHARE:.0%} of vehicle/: {big}"
