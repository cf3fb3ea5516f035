"""Every repository path cited in README.md and docs/*.md exists (a glob such as `docs/figures/yin2023_*.png`
matches at least one file), so a reader sent to a file finds it."""
from __future__ import annotations

import re

import pytest

from tests.helpers import REPO

TOP_FOLDERS = ("hpsim", "struts", "terrain", "vehicle", "tests", "benchmarks", "docs", "scenarios", "examples",
               "constraints", ".ci")
# a top folder, a slash, then path characters (a glob's * included), not inside a longer word or path
CITED = re.compile(r"(?<![\w/.~-])((?:" + "|".join(re.escape(t) for t in TOP_FOLDERS) + r")/[\w./*-]*[\w*])")
# sections of a document left out of the check (none: every page is checked)
OWNED_ELSEWHERE: set[str] = set()
# pages cited before they exist (none)
NOT_YET_MERGED: set[str] = set()


def _documents():
    return [REPO / "README.md"] + sorted((REPO / "docs").glob("*.md"))


def _text_outside_owned(path) -> str:
    """The document's text less the sections listed in OWNED_ELSEWHERE."""
    rel = path.relative_to(REPO).as_posix()
    if rel in OWNED_ELSEWHERE:
        return ""
    text = path.read_text(encoding="utf-8")
    for owned in OWNED_ELSEWHERE:
        doc, _, section = owned.partition("#")
        if doc == rel and section:
            text = re.sub(rf"(?ms)^## {section}\..*?(?=^## |\Z)", "", text)
    return text


def cited_paths(text: str) -> set[str]:
    """Repository paths named in a Markdown text (trailing punctuation left off)."""
    return {m.group(1).rstrip(".") for m in CITED.finditer(text)}


def test_the_citation_pattern_finds_paths_and_globs_and_leaves_words():
    text = ("see tests/unit/test_x.py, `docs/figures/a_*.png` and (vehicle/api.py). Not ~/.cache/hpsim, "
            "nor results/mileage_106km.h5 nor my-docs/x.md")
    assert cited_paths(text) == {"tests/unit/test_x.py", "docs/figures/a_*.png", "vehicle/api.py"}


@pytest.mark.parametrize("document", _documents(), ids=lambda p: p.name)
def test_every_cited_path_exists(document):
    missing = sorted(p for p in cited_paths(_text_outside_owned(document))
                     if p not in NOT_YET_MERGED and not (any(REPO.glob(p)) if "*" in p else (REPO / p).exists()))
    assert not missing, f"{document.relative_to(REPO)} cites paths that do not exist: {missing}"
