# PYTHON_ARGCOMPLETE_OK  (shell completion: eval "$(register-python-argcomplete hpsim)")
"""`hpsim` command line: the one console entry point and every sub-command, all in this package.

    hpsim strut ...                                  strut.py     (rig, characteristic, fit, gas)
    hpsim road ...                                   road.py      (generate, psd, plot)
    hpsim vehicle ... / run / report / compare / sweep / plot   drives.py
    hpsim calibrate                                  calibrate.py
    hpsim optimize                                   optimize.py

User errors (bad argument, bad file) print one line and exit with code 2. SIGTERM ends a command with
one line and exit code 143 after stopping what it started (compilers, study workers). -v / -q (before or after
the command) set how much is logged to stderr (`logging`, logger "hpsim"): -q only warnings and
errors, no progress bar; -v also debug details. Output cut short by its reader (`hpsim report x.h5
| head`) ends quietly with exit code 141, like any Unix tool killed by SIGPIPE.
"""
from __future__ import annotations

import argparse
import atexit
import contextlib
import logging
import os
import re
import signal
import sys
import warnings

from hpsim.errors import SimulationError, Terminated, UserInputError
from hpsim.threads import one_blas_thread
from vehicle.cli import stages


class _Parser(argparse.ArgumentParser):
    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        # a negative quantity with its unit ("--dt -1ms", "--temperatures -20degC") is a value, not an option: the
        # value's own check then names the allowed range (argparse's pattern takes bare numbers only)
        self._negative_number_matcher = re.compile(r"^-\.?\d")

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
    from . import calibrate, drives, export, optimize, uq, validate

    drives.register(sub)
    calibrate.register(sub)
    uq.register(sub)
    optimize.register(sub)
    export.register(sub)
    validate.register(sub)
    from . import examples

    examples.apply(parser)
    for _, p in [("hpsim", parser)] + list(examples.commands(parser)):
        _add_verbosity(p, top=p is parser)
    return parser


def _add_verbosity(p: argparse.ArgumentParser, top: bool) -> None:
    # on the sub-commands the options only count when given (SUPPRESS): their defaults must not
    # overwrite what was given before the command
    default = 0 if top else argparse.SUPPRESS
    p.add_argument("-v", "--verbose", action="count", default=default, help="log more (debug details) to stderr")
    p.add_argument("-q", "--quiet", action="count", default=default,
                   help="log only warnings and errors; no progress bar")


class _LevelFormatter(logging.Formatter):
    def format(self, record):
        text = record.getMessage()
        return text if record.levelno < logging.WARNING else f"{record.levelname.lower()}: {text}"


def setup_logging(verbosity: int) -> None:
    """Logger "hpsim" to stderr: -q WARNING, default INFO, -v DEBUG."""
    level = logging.WARNING if verbosity < 0 else (logging.INFO if verbosity == 0 else logging.DEBUG)
    log = logging.getLogger("hpsim")
    log.handlers.clear()
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(_LevelFormatter())
    log.addHandler(handler)
    log.setLevel(level)
    log.propagate = False
    warnings.showwarning = _warning_line


def _warning_line(message, category, filename, lineno, file=None, line=None) -> None:
    """A Python warning as one logged line "warning: ..." (not a file name, line number and source line)."""
    logging.getLogger("hpsim").warning(str(message))


def _stdout_gone() -> int:
    """The reader of stdout went away (`| head`): drop what is left unwritten, exit like SIGPIPE."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError):
        pass
    return 141


@contextlib.contextmanager
def _sigint_deferred():
    """SIGINT only noted (in the yielded list) inside the block; the previous handler is back after it."""
    noted: list[int] = []
    try:
        previous = signal.signal(signal.SIGINT, lambda signum, frame: noted.append(signum))
    except ValueError:          # not the main thread: signals are not ours to handle
        previous = None
    try:
        yield noted
    finally:
        if previous is not None:
            signal.signal(signal.SIGINT, previous)


def _raise_terminated(signum, frame):
    raise Terminated


@contextlib.contextmanager
def _sigterm_raises():
    """SIGTERM raises hpsim.errors.Terminated inside the block (its default would end the process at once and leave
    the compilers of a build running in their own session); the previous handler is back after it."""
    try:
        previous = signal.signal(signal.SIGTERM, _raise_terminated)
    except ValueError:          # not the main thread
        previous = None
    try:
        yield
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)


def main(argv: list[str] | None = None) -> int:
    """The command line `argv` (default sys.argv[1:]); its exit code. Its wall time counts from this call, or from
    the process start when the process is the command (`entry`; `stages.command_called`)."""
    stages.command_called()
    with _sigterm_raises():
        return _main(argv)


def entry() -> None:
    """The `hpsim` command (the console script, `python -m vehicle.cli`): `main`, then the process ends without
    Python's teardown of every module and object. What must happen at exit still does: the output streams are
    flushed and the atexit handlers run (logging, temporary folders, multiprocessing's children, a private compile
    cache). Freeing the objects of numpy, SciPy, CasADi, h5py and hpsim one by one, which the operating system does
    at once when the process ends, is skipped: it is a noticeable part of a short command's time (the same reason
    as Instagram's `atexit.register(os._exit, 0)`). An error that `main` does not handle (a bug) ends as Python ends: traceback,
    exit code 1. The BLAS library is asked for one thread (`hpsim.threads.one_blas_thread`)."""
    one_blas_thread()
    stages.process_is_the_command()
    try:
        code = main()
    except SystemExit as exc:             # argparse's --help, --version and usage errors
        code = exc.code
    if code is not None and not isinstance(code, int):
        sys.stderr.write(f"{code}\n")
        code = 1
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):     # a reader gone (`| head`) or a stream closed: nothing more to write
            pass
    atexit._run_exitfuncs()
    os._exit(code or 0)


def _main(argv: list[str] | None) -> int:
    # everything inside the handlers, parser and imports included: a Ctrl-C in the first second
    # is one line and exit code 130 like any other
    command = "hpsim"
    try:
        # a Ctrl-C while the command modules are imported is held until they are in: raised inside a
        # C extension's import it would surface as an ImportError (numpy: "PyCapsule_Import could not
        # import module datetime"), not as an interrupt
        with _sigint_deferred() as interrupted:
            parser = build_parser()
            try:
                import argcomplete

                argcomplete.autocomplete(parser)
            except ImportError:
                pass
            args = parser.parse_args(argv)
        command = f"hpsim {args.command}"
        if interrupted:
            raise KeyboardInterrupt
        args.verbosity = args.verbose - args.quiet
        setup_logging(args.verbosity)
        code = args.func(args)
        sys.stdout.flush()            # a closed pipe shows here, not at interpreter exit
    except BrokenPipeError:
        return _stdout_gone()
    except UserInputError as exc:
        sys.stderr.write(f"{command}: error: {exc}\n")
        return 2
    except SimulationError as exc:
        sys.stderr.write(f"{command}: simulation stopped: {exc}\n")
        return 3
    except KeyboardInterrupt:
        sys.stderr.write(f"{command}: interrupted\n")
        return 130
    except Terminated:
        sys.stderr.write(f"{command}: terminated (SIGTERM)\n")
        return 143
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
    entry()
