"""`hpsim` command line: one entry point, sub-commands contributed by each package.

    hpsim strut ...    (struts.cli)
    hpsim road ...     (terrain.cli)
    hpsim vehicle ... / run / report / compare / sweep / plot   (vehicle)

User errors (bad argument, bad file) print one line and exit with code 2.
"""
from __future__ import annotations

import argparse
import sys

from hpsim.errors import SimulationError, UserInputError


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # one line, exit code 2 (argparse's convention)
        self.exit(2, f"{self.prog}: error: {message}\n")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="hpsim", description=__doc__.splitlines()[0])
    from hpsim import __version__

    parser.add_argument("--version", action="version", version=f"hpsim {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    import struts.cli
    import terrain.cli

    struts.cli.register(sub)
    terrain.cli.register(sub)
    try:
        from . import commands
    except ImportError:  # vehicle commands not built yet
        commands = None
    if commands is not None:
        commands.register(sub)
    from . import calibration

    calibration.register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        code = args.func(args)
    except UserInputError as exc:
        sys.stderr.write(f"hpsim {args.command}: error: {exc}\n")
        return 2
    except SimulationError as exc:
        sys.stderr.write(f"hpsim {args.command}: simulation stopped: {exc}\n")
        return 3
    except KeyboardInterrupt:
        sys.stderr.write(f"hpsim {args.command}: interrupted\n")
        return 130
    return int(code or 0)


if __name__ == "__main__":
    sys.exit(main())
