"""Fixtures shared by every test folder (tests/helpers.py has the functions behind them)."""
from __future__ import annotations

import pytest

from tests import helpers


@pytest.fixture
def write_scenario(tmp_path):
    """write_scenario(name="scenario.yaml", text=None, **changes) -> a scenario file in this test's folder."""
    def write(name: str = "scenario.yaml", text: str | None = None, **changes):
        return helpers.write_scenario(tmp_path, name, text, **changes)
    return write


@pytest.fixture
def hpsim():
    """hpsim(args, cwd=None, timeout=300, env=None) -> CompletedProcess of `hpsim ARGS` in a new process."""
    return helpers.run_hpsim
