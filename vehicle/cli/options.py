"""Command-line options shared by the commands that write files."""
from __future__ import annotations

OVERWRITE_HELP = "replace an existing output file (without it an existing file is refused, never written over)"


def add_overwrite(p) -> None:
    """`--overwrite` on a command that writes output files (hpsim.outputs.check_output_file)."""
    p.add_argument("--overwrite", action="store_true", help=OVERWRITE_HELP)


def add_ensemble(p, what: str = "drives") -> None:
    """`--ensemble K` of the commands that run many drives (sweep, uq, optimize: vehicle.engines.ensemble)."""
    p.add_argument("--ensemble", type=int, default=None, metavar="K",
                   help=f"step K {what} in lockstep in one vector engine, full or multiscale mode (1: off; default: "
                        "one vector's lanes (8 with AVX-512, 4 with AVX2) when there are more drives than workers)")
