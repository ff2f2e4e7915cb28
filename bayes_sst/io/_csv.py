"""Read one test's CSV into float64 columns and check its time axis.

Reading has two passes. The fast one hands the whole body to numpy's C parser; it succeeds
on every well-formed file. Only when it fails does a slow, row-by-row pass run, whose job is
to find the first bad row and column and say what is wrong there (numpy's own message counts
data rows from 0 and does not know the column names). Rows are numbered as a text editor
would show them: the header is row 1.
"""

from __future__ import annotations

import re
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ._errors import SeriesFormatError
from ._series import OPTIONAL_COLUMNS, REQUIRED_COLUMNS, uniform_grid

KNOWN_COLUMNS = REQUIRED_COLUMNS + OPTIONAL_COLUMNS
# How far, in steps, a time stamp may lie off the straight line the time column follows.
# Printing rounds stamps (6 decimals at 1024 Hz: 0.0005 of a step; 4 decimals: 0.05) while the
# samples themselves stay uniform, and only the line's step is used downstream. Were the
# sampling itself that irregular, a tenth of a step would still be small: it moves a signal's
# top analysis frequency (4f) by 2 pi * 4f * 0.1 / fs in phase, 0.06 rad at 40 samples per
# cycle, at random from sample to sample. A dropped or doubled sample, or a clock that changes
# rate part-way, is half a step off or more.
TIME_GRID_TOLERANCE = 0.1

# What a careful reader accepts as a number: a plain decimal or scientific literal, nan or
# inf. Stricter than float(), which also takes "1_000".
_NUMBER = re.compile(
    r"\s*[+-]?(?:(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?|nan|inf(?:inity)?)\s*", re.IGNORECASE
)


def format_number(x: float) -> str:
    """A float for an error message: exact enough to find it in the file, short enough to read."""
    return f"{x:.10g}"


def format_pair(x: float, y: float) -> tuple[str, str]:
    """Two floats for one message, with as many digits as it takes to tell them apart (a time
    axis far from zero, t = 1e12 + 0.005, would print both as 1e+12 at ten digits)."""
    for digits in range(10, 18):
        first, second = f"{x:.{digits}g}", f"{y:.{digits}g}"
        if first != second:
            break
    return first, second


@dataclass
class CsvTable:
    """Columns of one CSV, with the map from sample index back to row number in the file."""

    path: Path
    columns: dict[str, np.ndarray]
    lines: list[str] = field(repr=False)
    _rows: np.ndarray | None = field(default=None, repr=False)

    def row_of(self, index: int) -> int:
        """Row number in the file (header = 1) of sample `index`."""
        if self._rows is None:
            # Built only for error messages; blank lines are skipped by both readers, so
            # sample i is not always on row i + 2.
            self._rows = np.array(
                [n for n, line in enumerate(self.lines[1:], start=2) if line.strip()]
            )
        return int(self._rows[index])

    @property
    def n_rows(self) -> int:
        return int(next(iter(self.columns.values())).shape[0])


def _read_text(path: Path) -> str:
    try:
        return path.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError as exc:
        raise SeriesFormatError(path, f"byte {exc.start}", "not UTF-8 text") from None
    except OSError as exc:
        raise SeriesFormatError(path, "", f"cannot be read: {exc.strerror or exc}") from None


def _header(path: Path, line: str) -> list[str]:
    # Spreadsheet exports often quote the names; the names themselves never contain quotes.
    names = [cell.strip().strip('"').strip() for cell in line.split(",")]
    if not line.strip():
        raise SeriesFormatError(path, "row 1", "is empty; expected the header row naming the columns")
    if all(_NUMBER.fullmatch(name) for name in names):
        raise SeriesFormatError(
            path, "row 1", f"holds numbers ({', '.join(names[:3])}{', ...' if len(names) > 3 else ''}), "
                           "not a header naming the columns"
        )
    # A column without a name is one the format does not define, so it is ignored like any
    # other: pandas' to_csv writes its row index so unless told index=False.
    names = [name or f"unnamed column {k + 1}" for k, name in enumerate(names)]
    for k, name in enumerate(names):
        if name in names[:k]:
            raise SeriesFormatError(path, f"column {name!r}", "is named twice in the header")
    found = ", ".join(repr(n) for n in names)
    for name in REQUIRED_COLUMNS:
        if name not in names:
            raise SeriesFormatError(
                path, f"column {name!r}", f"required column is missing; columns found: {found}"
            )
    return names


def _fast(body: list[str], n_columns: int) -> np.ndarray | None:
    try:
        with warnings.catch_warnings():
            # An all-blank body makes loadtxt warn; the row count is checked later anyway.
            warnings.simplefilter("ignore")
            data = np.loadtxt(body, delimiter=",", comments=None, ndmin=2, dtype=np.float64)
    except ValueError:
        return None
    if data.shape[0] and data.shape[1] != n_columns:
        return None
    return data.reshape(-1, n_columns)


def _careful(path: Path, lines: list[str], names: list[str]) -> dict[str, np.ndarray]:
    n = len(names)
    values: list[list[float]] = [[] for _ in names]
    text_columns: set[int] = set()
    for row, line in enumerate(lines[1:], start=2):
        if not line.strip():
            continue
        cells = line.split(",")
        if len(cells) != n:
            raise SeriesFormatError(
                path, f"row {row}",
                f"has {len(cells)} fields but the header names {n} columns (ragged row)",
            )
        for k, cell in enumerate(cells):
            if k in text_columns:
                continue
            if _NUMBER.fullmatch(cell):
                values[k].append(float(cell))
            elif names[k] in KNOWN_COLUMNS:
                what = "empty cell" if not cell.strip() else f"{cell.strip()!r} is not a number"
                raise SeriesFormatError(path, f"row {row}, column {names[k]!r}", what)
            else:
                # Columns the format does not define are ignored, so text in them is no fault.
                text_columns.add(k)
    return {
        name: np.asarray(values[k], dtype=np.float64)
        for k, name in enumerate(names)
        if k not in text_columns
    }


def read_csv(path: Path) -> CsvTable:
    """Read a test's CSV and check its header, cells and the finiteness of known columns.

    Parameters
    ----------
    path : Path
        The CSV file.

    Returns
    -------
    CsvTable
        One float64 array per numeric column, all of equal length.

    Raises
    ------
    SeriesFormatError
        Empty file, no header, missing required column, ragged row, non-numeric cell in a
        known column, NaN or infinity in a known column, or fewer than 2 rows.
    """
    lines = _read_text(path).splitlines()
    if not any(line.strip() for line in lines):
        raise SeriesFormatError(path, "", "the file is empty; expected a header row and data rows")
    names = _header(path, lines[0])
    data = _fast(lines[1:], len(names))
    if data is None:
        columns = _careful(path, lines, names)
    else:
        # One contiguous array per column rather than strided views into the row-major block.
        block = np.ascontiguousarray(data.T)
        columns = {name: block[k] for k, name in enumerate(names)}
    table = CsvTable(path, columns, lines)
    if table.n_rows < 2:
        raise SeriesFormatError(
            path, "rows", f"has {table.n_rows} data row(s); at least 2 are needed"
        )
    for name in KNOWN_COLUMNS:
        column = columns.get(name)
        if column is None:
            continue
        bad = np.flatnonzero(~np.isfinite(column))
        if bad.size:
            i = int(bad[0])
            raise SeriesFormatError(
                path, f"row {table.row_of(i)}, column {name!r}",
                f"value {format_number(column[i])} is not finite ({bad.size} such cell(s) in the column)",
            )
    return table


def check_time(table: CsvTable) -> float:
    """Check that time strictly increases at a uniform rate; return the step in s.

    Uniform means: every time stamp lies within TIME_GRID_TOLERANCE of a step of the
    column's least-squares line t_0 + offset + step*i (`uniform_grid`). Single steps may differ
    by more, as they do when the stamps were rounded in printing; the returned step is the
    line's, which that rounding does not bias.

    Raises
    ------
    SeriesFormatError
        A step is zero or negative, or a time stamp lies off the line by more than the
        tolerance. The message names the first step that is off by more than twice the
        tolerance (a dropped sample, a glitch), or else the stamp farthest off (a clock that
        runs at another rate in part of the record).
    """
    t = table.columns["t"]
    steps = np.diff(t)
    backwards = np.flatnonzero(steps <= 0)
    if backwards.size:
        i = int(backwards[0]) + 1
        later, earlier = format_pair(t[i], t[i - 1])
        raise SeriesFormatError(
            table.path, f"row {table.row_of(i)}, column 't'",
            f"time {later} does not come after {earlier} on row "
            f"{table.row_of(i - 1)}; time must strictly increase",
        )
    offset, step = uniform_grid(t)
    off_grid = (t - t[0]) - (offset + step * np.arange(t.shape[0]))
    if np.max(np.abs(off_grid)) <= TIME_GRID_TOLERANCE * step:
        return step
    median = float(np.median(steps))
    uneven = np.flatnonzero(np.abs(steps - median) > 2 * TIME_GRID_TOLERANCE * median)
    if uneven.size:
        i = int(uneven[0]) + 1
        start, end = format_pair(t[i - 1], t[i])
        raise SeriesFormatError(
            table.path, f"row {table.row_of(i)}, column 't'",
            f"time step {format_number(steps[i - 1])} s (from t = {start} to {end}) "
            f"differs from the median step {format_number(median)} s by more than "
            f"{2 * TIME_GRID_TOLERANCE:.0%}; sampling must be uniform",
        )
    i = int(np.argmax(np.abs(off_grid)))
    raise SeriesFormatError(
        table.path, f"row {table.row_of(i)}, column 't'",
        f"time {format_number(t[i])} lies {abs(off_grid[i]) / step:.2f} steps off the uniform grid "
        f"that the column follows (step {format_number(step)} s, least squares over the record; "
        f"{TIME_GRID_TOLERANCE:.0%} of a step is allowed): the clock's rate changes within the "
        "record; sampling must be uniform",
    )
