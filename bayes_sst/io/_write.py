"""Write a Series as a series folder (manifest plus one CSV per test), all or nothing."""

from __future__ import annotations

from pathlib import Path
from typing import Mapping

import numpy as np

from ._atomic import atomic_output_dir, dumps
from ._manifest import MANIFEST_NAME, TOP_LEVEL_KEYS, TEST_KEYS, FieldChecker
from ._series import FORMAT_ID, OPTIONAL_COLUMNS, REQUIRED_COLUMNS, Series, TestSpec

# Time gets 15 significant digits so that a step of 1e-4 s stays uniform to far better than
# the reader's 1e-3 tolerance even after hours of record; 10 digits are far below the noise
# of any measured signal.
TIME_FORMAT = "%.15g"
SIGNAL_FORMAT = "%.10g"


def _column_order(columns: Mapping[str, np.ndarray]) -> list[str]:
    known = [c for c in REQUIRED_COLUMNS + OPTIONAL_COLUMNS if c in columns]
    return known + [c for c in columns if c not in known]


def _spec_entry(spec: TestSpec) -> dict:
    entry = {key: getattr(spec, key) for key in TEST_KEYS}
    entry = {k: v for k, v in entry.items() if v is not None}
    entry.update({k: v for k, v in spec.extra.items() if k not in TEST_KEYS and v is not None})
    return entry


def manifest_dict(series: Series) -> dict:
    """The JSON content of ``series.json`` for `series`, without None values."""
    data: dict = {"format": FORMAT_ID, "name": series.name}
    if series.table:
        data["table"] = dict(series.table)
    data.update({k: v for k, v in series.extra.items() if k not in TOP_LEVEL_KEYS and v is not None})
    data["tests"] = [_spec_entry(record.spec) for record in series.tests]
    return data


def _check_writable(series: Series, manifest: Path) -> None:
    # Refuse what the reader would refuse, before anything touches the disk.
    check = FieldChecker(manifest)
    ids: dict[str, int] = {}
    files: dict[str, int] = {}
    for i, record in enumerate(series.tests):
        spec = record.spec
        check.relative_file(spec.file, f"tests[{i}].file")
        for seen, key, what in ((ids, spec.id, "id"), (files, spec.file, "file")):
            if key in seen:
                check.fail(f"tests[{i}].{what}", f"duplicate {what} {key!r}, already used by tests[{seen[key]}]")
            seen[key] = i
        lengths = set()
        for name in REQUIRED_COLUMNS:
            if name not in record.columns:
                check.fail(f"tests[{i}] column {name!r}", "required column is missing")
        for name, values in record.columns.items():
            if not name or any(c in name for c in ',"\r\n') or name != name.strip():
                check.fail(f"tests[{i}] column {name!r}", "a column name must be non-empty, "
                           "without commas, quotes, line breaks or surrounding spaces")
            shape = np.shape(values)
            if len(shape) != 1:
                check.fail(f"tests[{i}] column {name!r}", f"must be one-dimensional, has shape {shape}")
            lengths.add(shape[0])
        if len(lengths) != 1:
            check.fail(f"tests[{i}]", f"columns differ in length: {sorted(lengths)}")


def write_csv(path: Path, columns: Mapping[str, np.ndarray]) -> None:
    """Write one test's columns to `path`: a header row, then one row per sample."""
    names = _column_order(columns)
    block = np.column_stack([np.asarray(columns[name], dtype=np.float64) for name in names])
    formats = [TIME_FORMAT if name == "t" else SIGNAL_FORMAT for name in names]
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", encoding="utf-8", newline="\n") as handle:
        np.savetxt(handle, block, fmt=formats, delimiter=",", header=",".join(names), comments="")


def write_series(series: Series, path, *, overwrite: bool = False) -> Path:
    """Write `series` as a series folder that `load_series` reads back.

    Parameters
    ----------
    series : Series
        The series to write; each test's CSV goes to its ``spec.file``.
    path : str or Path
        The folder to create.
    overwrite : bool, default False
        Replace an existing folder, but only once the new one is completely written.

    Returns
    -------
    Path
        The folder written.

    Raises
    ------
    OutputExistsError
        `path` exists and `overwrite` is False.
    SeriesFormatError
        The series cannot be written as a valid folder (file outside the folder, duplicate
        id or file, missing required column, columns of unequal length, bad column name).

    Notes
    -----
    Everything is written into a hidden temporary sibling folder which is renamed to `path`
    at the end, so an interrupted call leaves either the old folder or the new one, never a
    mixture, and no temporary folder.
    """
    path = Path(path)
    _check_writable(series, path / MANIFEST_NAME)
    text = dumps(manifest_dict(series), non_finite_as_null=False)
    with atomic_output_dir(path, overwrite=overwrite) as tmp:
        for record in series.tests:
            write_csv(tmp / record.spec.file, record.columns)
        (tmp / MANIFEST_NAME).write_text(text, encoding="utf-8")
    return path
