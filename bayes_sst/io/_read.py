"""Load a test-series folder into a checked, in-memory Series."""

from __future__ import annotations

from pathlib import Path
from typing import Iterable

from ._csv import CsvTable, format_number, check_time, read_csv
from ._errors import SeriesFormatError
from ._manifest import MANIFEST_NAME, csv_path_of, read_manifest
from ._series import Series, TestRecord, TestSpec, as_test_ids

# A steady-state cycle is taken after the start-up transient, so fewer cycles than this
# leave nothing to identify from.
MIN_PERIODIC_CYCLES = 3


def _manifest_path(path: Path) -> Path:
    # A folder, or the manifest itself; a path that does not exist is taken as a folder so
    # that the error names what the user typed.
    if path.is_file():
        return path
    if path.name == MANIFEST_NAME and not path.is_dir():
        return path
    return path / MANIFEST_NAME


def _check_cycles(table: CsvTable, spec: TestSpec, index: int, step: float) -> None:
    # Each sample stands for one step, so n samples cover n * step seconds; a record of
    # exactly three periods then counts as three cycles, not three minus one step.
    duration = table.n_rows * step
    cycles = duration * spec.frequency_hz
    if cycles < MIN_PERIODIC_CYCLES:
        raise SeriesFormatError(
            table.path, "column 't'",
            f"the record lasts {format_number(duration)} s, only {cycles:.2f} cycles at "
            f"tests[{index}].frequency_hz = {format_number(spec.frequency_hz)} Hz; a {spec.kind} test "
            f"needs at least {MIN_PERIODIC_CYCLES} cycles",
        )


def _check_sampled(table: CsvTable, spec: TestSpec, index: int, step: float) -> None:
    # A fundamental at or above half the sampling rate cannot be in the record; most often the
    # time column is not in seconds (milliseconds, sample numbers).
    nyquist = 0.5 / step
    if spec.frequency_hz >= nyquist:
        raise SeriesFormatError(
            table.path, "column 't'",
            f"tests[{index}].frequency_hz = {format_number(spec.frequency_hz)} Hz is at or above half the "
            f"sampling rate ({format_number(nyquist)} Hz for a time step of {format_number(step)} s), so the "
            "record cannot hold it; is t in seconds?",
        )


def load_series(path, exclude: Iterable[str] = ()) -> Series:
    """Read and check a test series.

    Parameters
    ----------
    path : str or Path
        The series folder, or its ``series.json``.
    exclude : iterable of str
        Ids of tests to leave out: their CSV files are neither read nor checked (a test the
        analysis refuses, or a recording known to be bad, without editing the manifest). The
        Series records them in ``left_out``.

    Returns
    -------
    Series
        The tests in manifest order, each with its spec and float64 columns; unknown
        manifest fields in ``Series.extra`` and ``TestSpec.extra``, unknown numeric CSV
        columns alongside the known ones.

    Raises
    ------
    SeriesFormatError
        Anything that breaks the format (see docs/data_format.md). The message names the
        file, the field, row or column, and what is wrong there.
    """
    manifest = read_manifest(_manifest_path(Path(path)))
    left_out = _checked_exclusions(manifest, exclude)
    records = []
    for index, spec in enumerate(manifest.specs):
        if spec.id in left_out:
            continue
        table = read_csv(csv_path_of(manifest, index))
        step = check_time(table)
        if spec.is_periodic:
            _check_sampled(table, spec, index, step)
            _check_cycles(table, spec, index, step)
        records.append(TestRecord(spec=spec, columns=table.columns))
    return Series(
        name=manifest.name,
        tests=tuple(records),
        table=manifest.table,
        path=manifest.path.parent,
        extra=manifest.extra,
        left_out=left_out,
    )


def manifest_test_ids(path) -> list[str]:
    """The test ids a series' manifest lists, in its order (no CSV is read)."""
    return [spec.id for spec in read_manifest(_manifest_path(Path(path))).specs]


def _checked_exclusions(manifest, exclude) -> tuple[str, ...]:
    """The ids to leave out, in manifest order; an id the manifest lacks, or leaving out every
    test, is an error."""
    wanted = as_test_ids(exclude)
    known = [spec.id for spec in manifest.specs]
    unknown = [x for x in wanted if x not in known]
    if unknown:
        raise SeriesFormatError(manifest.path, "tests", f"no test with id {', '.join(map(repr, unknown))} to leave "
                                f"out; the manifest's ids are {', '.join(known)}")
    left_out = tuple(x for x in known if x in wanted)
    if left_out and len(left_out) == len(known):
        raise SeriesFormatError(manifest.path, "tests", "every test is left out; nothing remains to read")
    return left_out
