"""`hpsim` command line: the one console entry point and every sub-command, all in this package.

    hpsim strut ...                                  strut.py     (rig, characteristic, fit, gas)
    hpsim road ...                                   road.py      (generate, psd, plot)
    hpsim vehicle ... / run / report / compare / sweep / plot   drives.py
    hpsim calibrate                                  calibrate.py

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
    from . import road, strut

    strut.register(sub)
    road.register(sub)
    from . import calibrate, drives, uq

    drives.register(sub)
    calibrate.register(sub)
    uq.register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    # everything inside the handlers, parser and imports included: a Ctrl-C in the first second
    # is one line and exit code 130 like any other
    command = "hpsim"
    try:
        parser = build_parser()
        args = parser.parse_args(argv)
        command = f"hpsim {args.command}"
        code = args.func(args)
    except UserInputError as exc:
        sys.stderr.write(f"{command}: error: {exc}\n")
        return 2
    except SimulationError as exc:
        sys.stderr.write(f"{command}: simulation stopped: {exc}\n")
        return 3
    except KeyboardInterrupt:
        sys.stderr.write(f"{command}: interrupted\n")
        return 130
    except RecursionError:
        sys.stderr.write(f"{command}: error: input nested too deeply\n")
        return 2
    except MemoryError:
        sys.stderr.write(f"{command}: error: out of memory (the input asks for more work than fits)\n")
        return 2
    except OSError as exc:     # the environment: a file or folder that cannot be read or written
        where = f"{exc.filename}: " if getattr(exc, "filename", None) else ""
        sys.stderr.write(f"{command}: error: {where}{exc.strerror or exc.__class__.__name__}\n")
        return 2
    return int(code or 0)


if __name__ == "__main__":
    sys.exit(main())
