"""Comments and docstrings explain the code, not its history: no issue numbers, commit hashes or timings
(those belong in CHANGELOG.md and the generated docs/performance.md), and no docstring sentence a reader
must parse twice (over MAX_SENTENCE_WORDS words). Scans every module of the packages (CHECKED)."""
from __future__ import annotations

import ast
import io
import re
import tokenize
from pathlib import Path

import pytest

from tests.helpers import REPO

MAX_SENTENCE_WORDS = 60
# every module of hpsim's packages (benchmarks/ name the units they print, us/step, in their docstrings)
CHECKED = sorted(p.relative_to(REPO).as_posix() for folder in ("hpsim", "struts", "terrain", "vehicle")
                 for p in (REPO / folder).rglob("*.py"))

HISTORY = {
    "an issue number": re.compile(r"\bissues? #?\d+", re.I),
    "a commit hash": re.compile(r"\b(?=[0-9a-f]*\d)(?=[0-9a-f]*[a-f])[0-9a-f]{7,40}\b"),
    "a time per step": re.compile(r"\b(?:us|µs|ns|ms)/step\b"),
    "an instruction count": re.compile(r"\binstructions per\b", re.I),
    "a measurement": re.compile(r"\bmeasured\b[^.;]*?\d+(?:\.\d+)?\s*(?:us|µs|ms|s|%|x)\b"
                                r"|\d+(?:\.\d+)?\s*(?:us|µs|ms|s|x)\b[^.;]*?\bmeasured\b", re.I),
}


def comments_and_docstrings(source: str):
    """(line, kind, text) of every comment and docstring of a module's source."""
    for tok in tokenize.generate_tokens(io.StringIO(source).readline):
        if tok.type == tokenize.COMMENT:
            yield tok.start[0], "comment", tok.string.lstrip("#").strip()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
            doc = ast.get_docstring(node, clean=True)
            if doc:
                line = node.body[0].lineno
                yield line, "docstring", doc


def sentences(text: str) -> list[str]:
    """A docstring's sentences: split at a full stop, question or exclamation mark before white space and a
    capital, and at blank lines, indented blocks (examples, equations), list items and parameter entries
    ("name: what it is")."""
    paragraphs = re.split(r"\n\s*\n|\n(?=\s{2,}|\s*[-*] |\s*\d+\. |[\w`]+(?:, [\w`]+)*: )", text)
    return [s for p in paragraphs for s in re.split(r"(?<=[.!?])\s+(?=[A-Z`(])", " ".join(p.split())) if s]


def findings(source: str) -> list[str]:
    out = []
    for line, kind, text in comments_and_docstrings(source):
        for what, pattern in HISTORY.items():
            m = pattern.search(text)
            if m:
                out.append(f"line {line}: {kind} holds {what}: {m.group(0)!r}")
        if kind == "docstring":
            for s in sentences(text):
                if len(s.split()) > MAX_SENTENCE_WORDS:
                    out.append(f"line {line}: a docstring sentence of {len(s.split())} words: {s[:80]!r}...")
    return out


def test_the_checker_finds_history_and_long_sentences_and_passes_explanations():
    bad = ('"""Fast (issue 11, commit 18a58c4).\n\nOne sentence ' + "word " * 61 + 'end."""\n'
           "x = 1  # 13.6k instead of 14.6k instructions per step, 6.7 us/step\n"
           "y = 2  # 6.3 vs 7.2 us measured\n")
    found = " ".join(findings(bad))
    for what in ("an issue number", "a commit hash", "an instruction count", "a time per step", "a measurement",
                 "a docstring sentence of 6"):
        assert what in found, what
    good = ('"""The pivots are the diagonal of a matrix close to I: no pivoting is needed.\n\n'
            '    x = solve(A, b)   # 2 ms steps\n"""\n'
            "z = 3  # the measured drive rate of this machine; the 2nd axle (0.65 per worker)\n"
            "w = 4  # seed 000 §4.4, ISO 8608, 4 ms steps, ab12 def0 cafe\n")
    assert findings(good) == []


@pytest.mark.parametrize("module", CHECKED)
def test_comments_and_docstrings_explain_the_code_not_its_history(module):
    found = findings((REPO / module).read_text(encoding="utf-8"))
    assert not found, f"{module}:\n" + "\n".join(found)
