"""How the parts meet, read from the source (docs/CONTRIBUTING.md, "... an engine"; /work/shared/STYLE.md): no object
reads or writes another object's private attributes in the engines and the results, no engine subclasses another,
production code replaces no function or attribute of another module at run time, and few functions are long."""
from __future__ import annotations

import ast
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
PACKAGES = ("hpsim", "struts", "terrain", "vehicle")
ENCAPSULATED = ("vehicle/engines", "vehicle/results")
# private-looking names of the standard library that are its public interface or its only one: os._exit (documented:
# leave without clean-up, in a forked worker), ProcessPoolExecutor._processes (the pool's one handle on its
# workers, to signal them when a run is stopped)
STANDARD_LIBRARY_PRIVATE = {"os._exit", "pool._processes"}
# the interpreter's hooks, documented as replaceable: a warning's format, errors raised where no caller can catch them
INTERPRETER_HOOKS = {"warnings.showwarning", "sys.excepthook", "sys.unraisablehook"}
LONG_FUNCTION_LINES = 60
MAX_LONG_FUNCTIONS = 8


def _modules(*folders: str) -> dict[Path, ast.Module]:
    return {p: ast.parse(p.read_text()) for folder in folders for p in sorted((REPO / folder).rglob("*.py"))}


def private_accesses(tree: ast.Module) -> list[tuple[int, str]]:
    """(line, expression) of every `x._name` (not a dunder) where x is not `self` or `cls`."""
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and node.attr.startswith("_") and not node.attr.startswith("__"):
            if not (isinstance(node.value, ast.Name) and node.value.id in ("self", "cls")):
                out.append((node.lineno, ast.unparse(node)))
    return out


def run_time_replacements(tree: ast.Module) -> list[tuple[int, str]]:
    """(line, target) of every assignment to an attribute of an imported module (`module.name = ...`, `+=` too) and
    every setattr/delattr on anything but `self` or `cls`."""
    imported = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            imported |= {(a.asname or a.name).split(".")[0] for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            imported |= {a.asname or a.name for a in node.names}
    out = []
    for node in ast.walk(tree):
        targets = node.targets if isinstance(node, ast.Assign) else \
            [node.target] if isinstance(node, (ast.AugAssign, ast.AnnAssign)) else []
        for t in [e for t in targets for e in (t.elts if isinstance(t, ast.Tuple) else [t])]:
            if isinstance(t, ast.Attribute) and isinstance(t.value, ast.Name) and t.value.id in imported:
                out.append((node.lineno, ast.unparse(t)))
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in ("setattr", "delattr"):
            first = node.args[0] if node.args else None
            if not (isinstance(first, ast.Name) and first.id in ("self", "cls")):
                out.append((node.lineno, ast.unparse(node)))
    return out


def long_functions(tree: ast.Module) -> list[tuple[int, str, int]]:
    return [(n.lineno, n.name, n.end_lineno - n.lineno + 1) for n in ast.walk(tree)
            if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef))
            and n.end_lineno - n.lineno + 1 > LONG_FUNCTION_LINES]


def test_the_checks_find_what_they_look_for():
    """Each check flags its pattern in a sample and leaves the allowed forms alone (so a pass means something)."""
    sample = ast.parse("import sys\nimport os as o\nfrom a import b\n"
                       "class C:\n    def f(self, other):\n        self._x = other._y\n        cls._z\n"
                       "        o.path = 1\n        b.g += 1\n        setattr(other, 'k', 1)\n        setattr(self, 'k', 1)\n"
                       "        sys.argv, other.v = [], 2\n        def g():\n" + "            pass\n" * 70)
    assert private_accesses(sample) == [(6, "other._y")]
    assert sorted(run_time_replacements(sample)) == [(8, "o.path"), (9, "b.g"), (10, "setattr(other, 'k', 1)"),
                                                      (12, "sys.argv")]
    assert [(name, n) for _, name, n in long_functions(sample)] == [("f", 79), ("g", 71)]


def test_no_private_attribute_of_another_object_in_engines_and_results():
    found = [f"{p.relative_to(REPO)}:{line} {expr}" for p, tree in _modules(*ENCAPSULATED).items()
             for line, expr in private_accesses(tree) if expr not in STANDARD_LIBRARY_PRIVATE]
    assert not found, "reads or writes another object's private attribute:\n" + "\n".join(found)


def test_no_run_time_replacement_of_another_modules_names():
    found = [f"{p.relative_to(REPO)}:{line} {target}" for p, tree in _modules(*PACKAGES).items()
             for line, target in run_time_replacements(tree) if target not in INTERPRETER_HOOKS]
    assert not found, "replaces another module's name at run time:\n" + "\n".join(found)


def test_no_engine_inherits_from_another_engines_module():
    """A class in vehicle/engines has no base class defined in vehicle/engines (the contracts are Protocols, which
    engines fulfil without naming them)."""
    trees = _modules("vehicle/engines")
    defined = {node.name for tree in trees.values() for node in ast.walk(tree) if isinstance(node, ast.ClassDef)}
    found = [f"{p.relative_to(REPO)}:{node.lineno} {node.name}({', '.join(ast.unparse(b) for b in node.bases)})"
             for p, tree in trees.items() for node in ast.walk(tree) if isinstance(node, ast.ClassDef)
             if any(ast.unparse(b).split(".")[-1] in defined for b in node.bases)]
    assert not found, "\n".join(found)


def test_at_most_a_few_long_functions():
    found = sorted(((n, f"{p.relative_to(REPO)}:{line} {name}") for p, tree in _modules(*PACKAGES).items()
                    for line, name, n in long_functions(tree)), reverse=True)
    assert len(found) <= MAX_LONG_FUNCTIONS, \
        f"{len(found)} functions over {LONG_FUNCTION_LINES} lines:\n" + "\n".join(f"{n} {w}" for n, w in found)
