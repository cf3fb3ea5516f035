"""The README's "What a run costs" figures are docs/performance.md's, as benchmarks/performance.py wrote them:
quoting the table again changes nothing (a figure typed into the README by hand would be overwritten)."""
from __future__ import annotations

import importlib.util
import sys

from tests.helpers import REPO


def _generator():
    spec = importlib.util.spec_from_file_location("performance", REPO / "benchmarks" / "performance.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules.setdefault("performance", module)       # its dataclasses look their module up
    spec.loader.exec_module(module)
    return module


def test_the_readme_quotes_the_generated_table_unchanged():
    P = _generator()
    readme = (REPO / "README.md").read_text(encoding="utf-8")
    assert P.quote((REPO / "docs" / "performance.md").read_text(encoding="utf-8"), readme) == readme


def test_a_quote_carries_every_row_with_its_wall_and_ratio_and_the_machine():
    P = _generator()
    cases = [P.Case("main job, cache warm (reference)", "hpsim run a.yaml -o warm.h5", 20.0),
             P.Case("multiscale mode, cache warm", "hpsim run b.yaml -o ms.h5", 2.5, "error against the full run: 0.1 K")]
    info = {"cpu": "CPU X", "cpus": 2, "flags": "avx2", "load": "0.1 before, 0.2 after", "system": "Linux",
            "python": "3.11", "commit": "c0ffee1", "date": "2026-01-01 00:00 UTC"}

    class Args:
        distance_km, samples = None, 40
    text = P.quote(P.table(cases, info, Args), f"a\n{P.QUOTE_START}\nold\n{P.QUOTE_END}\nb\n")
    assert "| multiscale mode, cache warm | 2.5 s | 0.12 |" in text and "| 20.0 s | 1.00 |" in text
    assert "CPU X, 2 CPUs" in text and "c0ffee1" in text and "old" not in text
    assert text.startswith("a\n") and text.endswith("\nb\n")
