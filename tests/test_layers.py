"""The layers import one way only (README "How the code is laid out", docs/CONTRIBUTING.md):

    hpsim  <-  struts, terrain  <-  vehicle.physics, vehicle.numerics  <-  vehicle.runs
           <-  vehicle.presentation  <-  vehicle.cli

Checked statically on every module (also imports inside functions), and at run time for the
two physics libraries that must stay usable without the vehicle.
"""
from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
PACKAGES = ("hpsim", "struts", "terrain", "vehicle")

# layer -> the layers its modules may import (itself included)
ALLOWED = {
    "hpsim": {"hpsim"},
    "struts": {"hpsim", "struts"},
    "terrain": {"hpsim", "terrain"},
    "vehicle.physics": {"hpsim", "struts", "terrain", "vehicle.physics"},
    "vehicle.numerics": {"hpsim", "vehicle.numerics"},
    # the new packages of the split of vehicle.runs (scenario <- engines <- results <- analysis <- studies); until the
    # split is done, vehicle.runs and they import each other
    "vehicle.scenario": {"hpsim", "struts", "terrain", "vehicle.physics", "vehicle.numerics", "vehicle.scenario"},
    "vehicle.results": {"hpsim", "struts", "terrain", "vehicle.physics", "vehicle.numerics", "vehicle.scenario",
                        "vehicle.runs", "vehicle.results"},
    "vehicle.studies": {"hpsim", "struts", "terrain", "vehicle.physics", "vehicle.numerics", "vehicle.scenario",
                        "vehicle.runs", "vehicle.results", "vehicle.studies"},
    "vehicle.runs": {"hpsim", "struts", "terrain", "vehicle.physics", "vehicle.numerics", "vehicle.runs",
                     "vehicle.scenario", "vehicle.results", "vehicle.studies"},
    "vehicle.presentation": {"hpsim", "struts", "terrain", "vehicle.physics", "vehicle.numerics", "vehicle.runs",
                             "vehicle.scenario", "vehicle.results", "vehicle.studies", "vehicle.presentation"},
    "vehicle.cli": {"hpsim", "struts", "terrain", "vehicle.physics", "vehicle.numerics", "vehicle.runs",
                    "vehicle.scenario", "vehicle.results", "vehicle.studies", "vehicle.presentation", "vehicle.cli",
                    "vehicle"},
    # the package facade (vehicle/__init__.py: Simulation, open_results) re-exports the public API
    "vehicle": {"hpsim", "struts", "terrain", "vehicle.physics", "vehicle.numerics", "vehicle.runs",
                "vehicle.scenario", "vehicle.results", "vehicle.studies", "vehicle.presentation", "vehicle"},
}


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


def imports_of(path: Path) -> list[tuple[int, str]]:
    tree = ast.parse(path.read_text(), str(path))
    me = module_name(path)
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
    """The rule can fail: a physics module importing the running layer is reported."""
    fake = REPO / "vehicle" / "physics" / "_layer_probe.py"
    fake.write_text("from vehicle.runs import drive\nfrom ..runs.scenario import prepare\n")
    try:
        targets = [layer_of(t) for _, t in imports_of(fake)]
    finally:
        fake.unlink()
    assert targets == ["vehicle.runs", "vehicle.runs"]
    assert "vehicle.runs" not in ALLOWED["vehicle.physics"]


@pytest.mark.parametrize("package, forbidden", [("terrain", ("struts", "vehicle")), ("struts", ("terrain", "vehicle"))])
def test_physics_libraries_load_alone(package, forbidden):
    """Importing every module of struts (terrain) loads neither terrain (struts) nor vehicle."""
    mods = sorted(module_name(p) for p in (REPO / package).rglob("*.py"))
    code = (f"import sys, importlib; [importlib.import_module(m) for m in {mods!r}]; "
            f"print([m for m in sys.modules if m.split('.')[0] in {forbidden!r}])")
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=REPO)
    assert res.stdout.strip() == "[]"
