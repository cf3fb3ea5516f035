"""Command-line options shared by the commands that write files."""
from __future__ import annotations

OVERWRITE_HELP = "replace an existing output file (without it an existing file is refused, never written over)"


def add_overwrite(p) -> None:
    """`--overwrite` on a command that writes output files (hpsim.outputs.check_output_file)."""
    p.add_argument("--overwrite", action="store_true", help=OVERWRITE_HELP)
