"""The command line around the commands: examples in every --help, -v/-q verbosity, shell completion,
and output cut short by its reader (`hpsim report x.h5 | head`)."""
from __future__ import annotations

import io
import logging
import os
import subprocess
import sys

import pytest

from vehicle import cli
from vehicle.cli import examples


def _commands():
    return list(examples.commands(cli.build_parser()))


def test_every_command_has_examples_and_verbosity_options():
    cmds = _commands()
    assert len(cmds) >= 17
    missing = [path for path, p in cmds if "examples:" not in (p.epilog or "")]
    assert missing == []
    for path, p in cmds:
        text = p.format_help()
        assert f"hpsim {path.split()[0]}" in text.split("examples:")[1], path     # examples name the command
        assert "-q, --quiet" in text and "-v, --verbose" in text, path


@pytest.mark.parametrize("argv", [["report", "--help"], ["vehicle", "response", "--help"], ["strut", "fit", "--help"]])
def test_help_exits_0_with_examples(argv, capsys):
    with pytest.raises(SystemExit) as exc:
        cli.main(argv)
    assert exc.value.code == 0
    assert "examples:\n  hpsim " in capsys.readouterr().out


def test_verbosity_before_or_after_the_command():
    parser = cli.build_parser()
    for argv, expected in ((["-q", "report", "x.h5"], -1), (["report", "x.h5", "-q"], -1),
                           (["-vv", "report", "x.h5"], 2), (["-v", "report", "x.h5", "-q"], 0),
                           (["report", "x.h5"], 0)):
        a = parser.parse_args(argv)
        assert a.verbose - a.quiet == expected, argv
    for verbosity, level in ((-1, logging.WARNING), (0, logging.INFO), (1, logging.DEBUG)):
        cli.setup_logging(verbosity)
        assert logging.getLogger("hpsim").level == level


def test_quiet_keeps_warnings_and_drops_information(capsys):
    cli.setup_logging(-1)
    log = logging.getLogger("hpsim")
    log.info("resuming at 3 km")
    log.warning("F0 is not identified")
    err = capsys.readouterr().err
    assert err == "warning: F0 is not identified\n"
    cli.setup_logging(0)


def test_shell_completion(tmp_path):
    """argcomplete completes sub-commands and options (bash calls hpsim with these variables)."""
    out = tmp_path / "completions"
    env = {**os.environ, "_ARGCOMPLETE": "1", "COMP_LINE": "hpsim vehicle response --fri", "COMP_POINT": "28",
           "_ARGCOMPLETE_STDOUT_FILENAME": str(out)}
    code = ("import sys; from vehicle.cli import main; sys.exit(main())")
    proc = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    assert out.read_text().split() == ["--friction-velocity"]


class _ClosedPipe(io.TextIOBase):
    """stdout whose reader has gone: every write fails as a closed pipe does."""

    def writable(self):
        return True

    def write(self, text):
        raise BrokenPipeError(32, "Broken pipe")

    def fileno(self):
        raise io.UnsupportedOperation("no file descriptor")


def test_reader_gone_ends_quietly(monkeypatch, capsys):
    monkeypatch.setattr(sys, "stdout", _ClosedPipe())
    code = cli.main(["vehicle", "equilibrium", "--json"])
    assert code == 141
    assert capsys.readouterr().err == ""
