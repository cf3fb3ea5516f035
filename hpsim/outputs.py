"""The one way a command writes an output file: checked before any work starts, written whole or not at all.

`check_output_file` and `check_output_dir` raise `UserInputError` (one line, exit code 2) naming
the option and the path when the file or folder cannot be written. That is a directory where a file
is expected, a file where a folder is expected, a missing or read-only folder, a figure type the
plotting library does not know, one of the command's own inputs, or an existing file without
`--overwrite`. Writability is tested by creating (and at once removing) a uniquely named empty
file in the folder: permission bits alone do not tell (root, read-only mounts, /sys).

`atomic_output(path)` is where the bytes go: a unique temporary name beside `path` (never a fixed
`x.tmp` a user's file could carry), renamed onto `path` when the block completes and removed when it
raises, a Ctrl-C (KeyboardInterrupt) and SIGTERM (`hpsim.errors.Terminated`) included. The old
output stays intact until the new one is complete; a full disk is one line naming the output.
"""
from __future__ import annotations

import contextlib
import errno
import functools
import os
import tempfile
from collections.abc import Iterable, Iterator
from pathlib import Path

from .errors import UserInputError


@functools.lru_cache(maxsize=1)
def figure_suffixes() -> tuple[str, ...]:
    """File types matplotlib can write (".png", ".pdf", ".svg", ...)."""
    from matplotlib.backend_bases import FigureCanvasBase

    return tuple(sorted(f".{ext}" for ext in FigureCanvasBase.get_supported_filetypes()))


def _nearest_existing(path: Path) -> Path:
    p = path
    while not p.exists() and p != p.parent:
        p = p.parent
    return p


def _probe_writable(folder: Path, where: str, path: Path) -> None:
    try:
        fd, probe = tempfile.mkstemp(prefix=".hpsim-write-test-", dir=folder)
    except OSError as exc:
        raise UserInputError(f"{where}: cannot write {path}: folder {folder} is not writable "
                             f"({exc.strerror or exc.__class__.__name__})") from None
    os.close(fd)
    os.unlink(probe)


def _check_folder(folder: Path, where: str, path: Path, make_parents: bool) -> None:
    existing = _nearest_existing(folder)
    if not existing.is_dir():
        raise UserInputError(f"{where}: cannot write {path}: {existing} is a file, not a folder")
    if existing != folder and not make_parents:
        raise UserInputError(f"{where}: cannot write {path}: folder {folder} does not exist")
    _probe_writable(existing, where, path)


def _not_empty(path, where: str) -> None:
    if not str(path).strip():
        raise UserInputError(f"{where}: empty path; give a file or folder name")


def _same_file(a: Path, b: Path) -> bool:
    try:
        return os.path.samefile(a, b)
    except OSError:                 # either one missing or unreadable: compare the paths as written
        return a.resolve() == b.resolve()


def check_not_input(path: str | Path, where: str, inputs: Iterable[str | Path | None]) -> None:
    """UserInputError when `path` names one of `inputs` (the same file through any link or spelling)."""
    p = Path(path)
    for given in inputs:
        if given is not None and str(given).strip() and _same_file(p, Path(given)):
            raise UserInputError(f"{where}: {path} is also an input of this command ({given}); "
                                 "give another output file")


def check_output_file(path: str | Path, where: str, *, suffixes: tuple[str, ...] | None = None,
                      make_parents: bool = False, inputs: Iterable[str | Path | None] = (),
                      overwrite: bool = True) -> Path:
    """`path` can be written as a file (created, or replaced when `overwrite`).

    Parameters
    ----------
    suffixes : allowed file types (an empty suffix is allowed too).
    make_parents : the command creates missing folders.
    inputs : the command's input files (None entries and built-in names that are no file are ignored):
        an output naming one of them is refused.
    overwrite : the command's `--overwrite`; without it an existing file is refused.
    """
    _not_empty(path, where)
    p = Path(path)
    if str(path).endswith(os.sep) or p.is_dir():
        raise UserInputError(f"{where}: {path} is a directory; give a file name"
                             + (f", e.g. {p / ('out' + suffixes[0])}" if suffixes else ""))
    check_not_input(p, where, inputs)
    if suffixes is not None and p.suffix and p.suffix.lower() not in suffixes:
        raise UserInputError(f"{where}: {path}: unknown file type {p.suffix!r}; allowed: {', '.join(suffixes)}")
    if (p.exists() or p.is_symlink()) and not overwrite:
        raise UserInputError(f"{where}: {path} exists (--overwrite replaces it)")
    if p.exists() and not os.access(p, os.W_OK):
        raise UserInputError(f"{where}: {path} exists and is not writable")
    _check_folder(p.parent if str(p.parent) else Path("."), where, p, make_parents)
    return p


def check_figure_file(path: str | Path, where: str, *, make_parents: bool = False,
                      inputs: Iterable[str | Path | None] = (), overwrite: bool = True) -> Path:
    """A figure path: writable and of a file type matplotlib knows (the rest as `check_output_file`)."""
    return check_output_file(path, where, suffixes=figure_suffixes(), make_parents=make_parents, inputs=inputs,
                             overwrite=overwrite)


# errors of the disk rather than of the input: reported naming the output, whose old version is kept
_DISK_FULL = (errno.ENOSPC, errno.EDQUOT, errno.EFBIG)


def _umask() -> int:
    """The process's umask, read without changing it where the system tells it (Linux /proc): setting it to read
    it back would be seen by any thread creating a file at that moment."""
    try:
        with open("/proc/self/status") as fh:
            return int(next(ln for ln in fh if ln.startswith("Umask:")).split()[1], 8)
    except (OSError, StopIteration, ValueError, IndexError):
        umask = os.umask(0o022)
        os.umask(umask)
        return umask


def _new_file_mode(replaced: Path) -> int:
    """The mode the output gets: the replaced file's, else what the umask gives a new file (mkstemp's is 0600)."""
    try:
        return replaced.stat().st_mode & 0o7777
    except OSError:
        return 0o666 & ~_umask()


@contextlib.contextmanager
def atomic_output(path: str | Path) -> Iterator[Path]:
    """A temporary path beside `path` to write the output to; renamed onto `path` when the block completes.

    The temporary name is unique (`tempfile.mkstemp`) and keeps the suffix, so writers that choose the
    format by it (matplotlib, movie writers) still do. When the block raises (any exception, Ctrl-C and
    SIGTERM included) the temporary file is removed and `path` is left as it was. A full disk, a quota or a
    file-size limit (ENOSPC, EDQUOT, EFBIG), or any error of the temporary file, is a `UserInputError` naming
    `path`. Missing folders are created.
    """
    path = Path(path)
    folder = path.parent if str(path.parent) else Path(".")
    folder.mkdir(parents=True, exist_ok=True)
    try:
        fd, name = tempfile.mkstemp(prefix=f".{path.stem[:60]}-", suffix=path.suffix, dir=folder)
    except OSError as exc:
        raise UserInputError(f"{path}: cannot write ({exc.strerror or exc.__class__.__name__})") from None
    os.close(fd)
    tmp = Path(name)
    try:
        yield tmp
        os.chmod(tmp, _new_file_mode(path))
        os.replace(tmp, path)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        if exc.errno in _DISK_FULL or exc.filename in (name, str(path)):
            raise UserInputError(f"{path}: cannot write ({exc.strerror or exc.__class__.__name__}); "
                                 "nothing was written over") from None
        raise
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def check_output_dir(path: str | Path, where: str) -> Path:
    """`path` is (or can be created as) a writable folder."""
    _not_empty(path, where)
    p = Path(path)
    if p.exists() and not p.is_dir():
        raise UserInputError(f"{where}: {path} exists and is not a folder")
    if p.is_dir():
        _probe_writable(p, where, p)
    else:
        _check_folder(p, where, p, make_parents=True)
    return p
