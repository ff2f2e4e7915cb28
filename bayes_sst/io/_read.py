"""Load a test-series folder into a checked, in-memory Series."""

from __future__ import annotations

from pathlib import Path

from ._csv import CsvTable, format_number, check_time, read_csv
from ._errors import SeriesFormatError
from ._manifest import MANIFEST_NAME, csv_path_of, read_manifest
from ._series import Series, TestRecord, TestSpec

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


def load_series(path) -> Series:
    """Read and check a test series.

    Parameters
    ----------
    path : str or Path
        The series folder, or its ``series.json``.

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
    records = []
    for index, spec in enumerate(manifest.specs):
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
    )
