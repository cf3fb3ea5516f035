"""Measured profiles: CSV reading (with line-exact error messages), resampling, writing.

File format: comma-separated, one header line naming the columns, then one row
per point; distances and heights in metres. Required columns (case-insensitive):
`distance_m`, `left_m`, `right_m` (or `distance`, `left`, `right`). Other columns
are ignored; lines starting with `#` are comments. Distance must increase
strictly; all values must be finite.

Error messages name the file, the line and the column, never the file's content: the path may
be any file (`road: {csv: /etc/passwd}`), and its text is not ours to print.
"""
from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from hpsim.errors import UserInputError
from hpsim.files import read_csv_text

CSV_COLUMNS = ("distance_m", "left_m", "right_m")
UNIFORM_TOLERANCE = 1e-6  # relative deviation of a step from the mean step still called "uniform"


MAX_ROAD_POINTS = 25_000_000


def check_road_points(length_m: float, spacing_m: float, where: str = "") -> int:
    """Number of grid points of a road; refuses more than MAX_ROAD_POINTS before anything is allocated."""
    n = length_m / spacing_m + 1
    if not n <= MAX_ROAD_POINTS:
        raise UserInputError(f"{where}spacing {spacing_m:g} m over {length_m:g} m is {n:.3g} grid points, "
                             f"at most {MAX_ROAD_POINTS:,} (e.g. {MAX_ROAD_POINTS * 0.05 / 1e3:g} km at 50 mm); "
                             "use a coarser spacing or a shorter road")
    return int(n)


def _header(path: Path, lines: list[str]) -> tuple[int, list[str]]:
    """(line number of the header, lower-case column names)."""
    for lineno, line in enumerate(lines, start=1):
        text = line.strip()
        if text and not text.startswith("#"):
            return lineno, [c.strip().lower() for c in text.split(",")]
    raise UserInputError(f"{path}: empty file; expected a header {','.join(CSV_COLUMNS)} and data rows")


def _column_indices(path: Path, header_line: int, names: list[str]) -> list[int]:
    out = []
    for col in CSV_COLUMNS:
        alias = col[:-2]
        found = [k for k, n in enumerate(names) if n in (col, alias)]
        if len(found) > 1:
            raise UserInputError(f"{path}:{header_line}: column '{col}' appears {len(found)} times in the header "
                                 "line; which one is meant is ambiguous")
        if not found:
            raise UserInputError(f"{path}:{header_line}: missing column '{col}' in the header line ({len(names)} "
                                 f"column(s)); expected a header {','.join(CSV_COLUMNS)}")
        out.append(found[0])
    return out


def _data_lines(lines: list[str], header_line: int):
    """Yield (line number, stripped text) of the data lines (slow path, used for error messages)."""
    for lineno, line in enumerate(lines, start=1):
        text = line.strip()
        if lineno <= header_line or not text or text.startswith("#"):
            continue
        yield lineno, text


def _find_bad_line(path: Path, lines: list[str], header_line: int, names: list[str], cols: list[int]) -> str:
    for lineno, text in _data_lines(lines, header_line):
        fields = [f.strip() for f in text.split(",")]
        if len(fields) <= max(cols):
            return f"{path}:{lineno}: {len(fields)} fields, expected {len(names)}"
        for c, col in zip(cols, CSV_COLUMNS):
            try:
                float(fields[c])
            except ValueError:
                return f"{path}:{lineno}: the {col} field is not a number"
    return f"{path}: cannot parse the data rows"


def _line_of_row(lines: list[str], header_line: int, row: int) -> int:
    for i, (lineno, _) in enumerate(_data_lines(lines, header_line)):
        if i == row:
            return lineno
    return -1


def read_profile_csv(path: str | Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(distance, left, right) [m] as read; raises UserInputError naming file and line. The file is read once,
    as a regular file of bounded size (hpsim.files: never a FIFO or device), with an optional UTF-8 byte-order
    mark and CRLF line ends (as spreadsheets write them)."""
    path = Path(path)
    text = read_csv_text(path, what=f"a CSV file {','.join(CSV_COLUMNS)}")
    lines = text.split("\n")
    header_line, names = _header(path, lines)
    cols = _column_indices(path, header_line, names)
    try:
        data = np.loadtxt(io.StringIO(text), delimiter=",", skiprows=header_line, usecols=cols, comments="#",
                          ndmin=2, dtype=float)
    except ValueError:
        raise UserInputError(_find_bad_line(path, lines, header_line, names, cols)) from None
    if data.shape[0] < 2:
        raise UserInputError(f"{path}: {data.shape[0]} data row(s); at least 2 are needed")
    bad = ~np.isfinite(data)
    if bad.any():
        row, c = np.argwhere(bad)[0]
        line = _line_of_row(lines, header_line, int(row))
        raise UserInputError(f"{path}:{line}: {CSV_COLUMNS[c]} = {data[row, c]} is not a finite number")
    d = data[:, 0]
    steps = np.diff(d)
    if (steps <= 0).any():
        row = int(np.argmax(steps <= 0)) + 1
        line = _line_of_row(lines, header_line, row)
        raise UserInputError(f"{path}:{line}: distance {d[row]:.9g} m does not increase "
                             f"(previous row {d[row - 1]:.9g} m); distance must increase strictly")
    return d, data[:, 1], data[:, 2]


def is_uniform(distance_m: np.ndarray) -> bool:
    steps = np.diff(distance_m)
    mean = (distance_m[-1] - distance_m[0]) / (distance_m.size - 1)
    return bool(np.max(np.abs(steps - mean)) <= UNIFORM_TOLERANCE * mean)


def resample(distance_m: np.ndarray, height_m: np.ndarray, spacing_m: float, n_points: int) -> np.ndarray:
    """Heights on the grid s_i = distance_m[0] + i·spacing_m (i < n_points).

    Finer or equal target spacing: linear interpolation. Coarser target spacing: the
    average of the piecewise-linear profile over [s_i - Δ/2, s_i + Δ/2] (exact, from its
    cumulative integral), an anti-aliasing box filter before decimation; the window is
    narrowed symmetrically at the two ends of the data.
    """
    d = np.asarray(distance_m, dtype=float)
    z = np.asarray(height_m, dtype=float)
    grid = d[0] + spacing_m * np.arange(n_points)
    grid[-1] = min(grid[-1], d[-1])
    median_step = float(np.median(np.diff(d)))
    if spacing_m <= median_step * (1.0 + UNIFORM_TOLERANCE):
        return np.interp(grid, d, z)
    # cumulative integral of the piecewise-linear profile, and its (exact, piecewise-quadratic) value anywhere
    cum = np.concatenate([[0.0], np.cumsum(0.5 * (z[1:] + z[:-1]) * np.diff(d))])

    def integral(x):
        x = np.clip(x, d[0], d[-1])
        i = np.clip(np.searchsorted(d, x, side="right") - 1, 0, d.size - 2)
        h = x - d[i]
        slope = (z[i + 1] - z[i]) / (d[i + 1] - d[i])
        return cum[i] + z[i] * h + 0.5 * slope * h * h

    # symmetric window, narrowed at the ends of the data (so a linear profile stays exact)
    half = np.minimum(0.5 * spacing_m, np.minimum(grid - d[0], d[-1] - grid))
    out = np.interp(grid, d, z)
    wide = half > 1e-9 * spacing_m
    lo, hi = grid[wide] - half[wide], grid[wide] + half[wide]
    out[wide] = (integral(hi) - integral(lo)) / (hi - lo)
    return out


def write_profile_csv(path: str | Path, distance_m: np.ndarray, left_m: np.ndarray, right_m: np.ndarray) -> None:
    """Write the CSV format read by `read_profile_csv` (header distance_m,left_m,right_m)."""
    path = Path(path)
    data = np.column_stack([distance_m, left_m, right_m])
    try:
        np.savetxt(path, data, delimiter=",", header=",".join(CSV_COLUMNS), comments="",
                   fmt=("%.6f", "%.10g", "%.10g"))
    except OSError as exc:
        raise UserInputError(f"{path}: cannot write ({exc.strerror})") from None
