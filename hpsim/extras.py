"""How to install an optional feature's packages (the extras of pyproject.toml), said in error messages.

hpsim is installed from its checkout: `pip install "hpsim[...]"` would fetch an unrelated project of that
name from the public index, so every hint names the editable install of the checkout.
"""
from __future__ import annotations


def install_hint(extra: str) -> str:
    """The command that installs the packages of `extra` (e.g. "crg") into hpsim's environment."""
    return f'pip install -e ".[{extra}]" (in the hpsim checkout)'
