"""Reading input files safely: regular files only, with a size limit, text as loggers and spreadsheets write it.

An input path may name anything: a FIFO with no writer (opening it blocks for ever), a device such as
/dev/zero (reading never ends), a directory. `read_regular_bytes` opens without blocking
(O_NONBLOCK), checks on the open descriptor that it is a regular file (no race between a check and the
open), and reads at most `max_bytes`; anything else is a one-line `UserInputError` naming the path and
what it is. `read_csv_text` adds what CSV writers do: a UTF-8 byte-order mark (Excel's "CSV UTF-8")
is dropped and CRLF or CR line ends become LF.
"""
from __future__ import annotations

import os
import stat
from pathlib import Path

from .errors import UserInputError

# the largest data file read whole (a road profile of 1000 km at 5 cm is about 20 M lines of ~35 bytes)
MAX_DATA_FILE_BYTES = 1 << 30

_KINDS = ((stat.S_ISDIR, "a directory"), (stat.S_ISFIFO, "a FIFO (named pipe)"), (stat.S_ISCHR, "a character device"),
          (stat.S_ISBLK, "a block device"), (stat.S_ISSOCK, "a socket"))


def kind_of(mode: int) -> str:
    """'a FIFO (named pipe)', 'a character device', ... for a stat mode that is not a regular file."""
    return next((name for test, name in _KINDS if test(mode)), "not a regular file")


def read_regular_bytes(path: str | Path, max_bytes: int = MAX_DATA_FILE_BYTES, what: str = "a file") -> bytes:
    """The bytes of a regular file of at most max_bytes; UserInputError for a missing file, a directory, a
    device, a pipe or socket, or a larger file (never blocks, never reads more than max_bytes + 1)."""
    path = Path(path)
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0))
    except FileNotFoundError:
        raise UserInputError(f"{path}: file not found") from None
    except IsADirectoryError:
        raise UserInputError(f"{path}: is a directory, expected {what}") from None
    except OSError as exc:
        raise UserInputError(f"{path}: cannot read ({exc.strerror or exc.__class__.__name__})") from None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            raise UserInputError(f"{path}: is {kind_of(st.st_mode)}, expected {what} (a regular file)")
        if st.st_size > max_bytes:
            raise UserInputError(f"{path}: {st.st_size / 2**20:.1f} MB, larger than the limit of "
                                 f"{max_bytes / 2**20:.0f} MB for {what}")
        chunks, n = [], 0
        while n <= max_bytes:
            try:
                chunk = os.read(fd, min(1 << 20, max_bytes + 1 - n))
            except OSError as exc:
                raise UserInputError(f"{path}: cannot read ({exc.strerror or exc.__class__.__name__})") from None
            if not chunk:
                break
            chunks.append(chunk)
            n += len(chunk)
    finally:
        os.close(fd)
    if n > max_bytes:                       # grew while being read
        raise UserInputError(f"{path}: larger than the limit of {max_bytes / 2**20:.0f} MB for {what}")
    return b"".join(chunks)


def decode_text(data: bytes, name: str) -> str:
    """UTF-8 bytes (an optional BOM is dropped) -> str; anything else is a one-line error."""
    if data.startswith((b"\xff\xfe", b"\xfe\xff")):
        raise UserInputError(f"{name}: the file is UTF-16 text; save it as UTF-8")
    if data.startswith(b"\xef\xbb\xbf"):
        data = data[3:]
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = data[:exc.start].count(b"\n") + 1
        raise UserInputError(f"{name}:{line}: not UTF-8 text (byte 0x{data[exc.start]:02x} at offset {exc.start}); "
                             "save the file as UTF-8") from None
    if "\x00" in text:
        line = text[:text.index("\x00")].count("\n") + 1
        raise UserInputError(f"{name}:{line}: a NUL byte: this is a binary file, not text")
    return text


def read_csv_text(path: str | Path, max_bytes: int = MAX_DATA_FILE_BYTES, what: str = "a CSV file") -> str:
    """The text of a CSV file as `read_regular_bytes` reads it: UTF-8 with an optional byte-order mark (dropped),
    line ends normalised to LF; UserInputError for another encoding (naming the line)."""
    text = decode_text(read_regular_bytes(path, max_bytes, what), f"{path} ({what})")
    return text.replace("\r\n", "\n").replace("\r", "\n")
