"""How the `hpsim` process ends (`vehicle.cli.entry`): with main's exit code, its output flushed through a pipe and
the atexit handlers run, but without Python's teardown of every module (issue 26: 0.12-0.2 s of every command); a bug
still ends with its traceback and exit code 1."""
from __future__ import annotations

import subprocess
import sys

from vehicle import cli


def _python(code: str, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", code, *args], capture_output=True, text=True, timeout=120)


def test_the_command_ends_with_its_code_its_whole_output_and_the_atexit_handlers(tmp_path, capsys):
    marker = tmp_path / "atexit_ran"
    code = ("import atexit, sys; from vehicle import cli; "
            f"atexit.register(lambda: open({str(marker)!r}, 'w').write('yes')); "
            "sys.argv = ['hpsim'] + sys.argv[1:]; cli.entry()")
    p = _python(code, "run", "--help")
    assert p.returncode == 0, p.stderr
    assert marker.read_text() == "yes"
    try:                                                 # the same text as main() writes in this process
        cli.main(["run", "--help"])
    except SystemExit:
        pass
    assert p.stdout == capsys.readouterr().out and len(p.stdout) > 1000
    bad = _python(code, "run", "--no-such-option")        # argparse's usage error: exit code 2, one message
    assert bad.returncode == 2 and "error: " in bad.stderr and "Traceback" not in bad.stderr
    missing = _python(code, "run", str(tmp_path / "nothing.yaml"), "-o", str(tmp_path / "x.h5"))
    assert missing.returncode == 2 and "nothing.yaml" in missing.stderr


def test_a_bug_still_ends_with_its_traceback():
    p = _python("from vehicle import cli; cli.main = lambda: 1 / 0; cli.entry()")
    assert p.returncode == 1 and "ZeroDivisionError" in p.stderr and "Traceback" in p.stderr
