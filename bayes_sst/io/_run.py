"""A run folder: posterior.nc (ArviZ DataTree), summary.json, summary.txt."""

from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path

from bayes_sst.io._atomic import OutputExistsError, atomic_output_dir, dumps
from bayes_sst.io._errors import SeriesFormatError

POSTERIOR_FILE = "posterior.nc"
SUMMARY_JSON = "summary.json"
SUMMARY_TEXT = "summary.txt"


# what summary.json must hold for summary, report and design to read it (format_summary's keys)
SUMMARY_KEYS = ("parameters", "between_test_spread", "n_tests", "n_samples", "divergences", "max_r_hat",
                "min_ess_bulk", "converged", "warnings")


class OutputTargetError(ValueError):
    """An output path that cannot or must not be written: said before any work is done."""


def check_run_target(path, *, overwrite: bool = False) -> None:
    """Refuse an output folder before any work is done, not after: an existing one (unless
    overwrite), an existing file in its place (a file is never replaced by a folder), and one
    whose parent cannot be written (found by creating and removing a hidden folder in its nearest
    existing ancestor: folders that do not exist yet are made only when the output is written, so
    a run refused later leaves none behind)."""
    target = Path(path)
    if str(path).strip() == "":
        raise OutputTargetError("the output path is empty")
    if os.path.lexists(target) and not target.is_dir():
        raise OutputTargetError(f"{path} exists and is not a folder; outputs are folders, and a file is never "
                                "replaced by one (--force included): choose another path")
    if target.exists() and not overwrite:
        raise OutputExistsError(path, hint="pass --force (overwrite=True) to replace it")
    ancestor = target.absolute().parent
    while not os.path.lexists(ancestor) and ancestor != ancestor.parent:
        ancestor = ancestor.parent
    if not ancestor.is_dir():
        raise OutputTargetError(f"cannot write {path}: {ancestor} is not a folder")
    try:
        os.rmdir(tempfile.mkdtemp(prefix=f".{target.name}.probe-", dir=ancestor))
    except OSError as exc:
        raise OutputTargetError(f"cannot write {path}: {exc.strerror or exc} ({exc.filename or ancestor})") from None


def write_run(path, tree, summary: dict, text: str, *, overwrite: bool = False) -> Path:
    """Write the three files of a run atomically: all of them appear, or none."""
    with atomic_output_dir(path, overwrite=overwrite) as tmp:
        tree.to_netcdf(tmp / POSTERIOR_FILE, engine="netcdf4")
        (tmp / SUMMARY_JSON).write_text(dumps(summary))
        (tmp / SUMMARY_TEXT).write_text(text + "\n")
    return Path(path)


def read_run_summary(path) -> dict:
    """summary.json of a run folder, with a clear error when it is not one."""
    file = Path(path) / SUMMARY_JSON
    if not file.is_file():
        raise SeriesFormatError(path, "", f"not a run folder: {SUMMARY_JSON} is missing")
    try:
        summary = json.loads(file.read_text(encoding="utf-8"))
    except json.JSONDecodeError as exc:
        raise SeriesFormatError(file, f"line {exc.lineno}", f"not valid JSON: {exc.msg}") from None
    except UnicodeDecodeError as exc:
        raise SeriesFormatError(file, f"byte {exc.start}", "not UTF-8 text") from None
    if not isinstance(summary, dict):
        kind = {list: "an array", str: "a string", bool: "true or false", int: "a number", float: "a number",
                type(None): "null"}.get(type(summary), type(summary).__name__)
        raise SeriesFormatError(file, "", f"not a run summary: {kind}, not a JSON object")
    missing = [key for key in SUMMARY_KEYS if key not in summary]
    if missing:
        raise SeriesFormatError(file, "", f"not a run summary: {', '.join(missing)} missing")
    if not isinstance(summary["parameters"], dict) or not all(isinstance(v, dict) for v in summary["parameters"].values()):
        raise SeriesFormatError(file, "parameters", "not an object of parameter summaries")
    return summary


def read_run_tree(path):
    """The posterior DataTree of a run folder, read fully into memory, its file closed again.

    A lazily opened tree keeps an HDF5 handle until garbage collection, and opening the same
    file again while such handles linger has crashed the netCDF4 library; runs are small.
    """
    import xarray as xr

    file = Path(path) / POSTERIOR_FILE
    if not file.is_file():
        raise SeriesFormatError(path, "", f"not a run folder: {POSTERIOR_FILE} is missing")
    try:
        with xr.open_datatree(file, engine="netcdf4") as lazy:
            return lazy.load().copy(deep=True)
    except (OSError, ValueError, KeyError) as exc:
        raise SeriesFormatError(file, "", f"cannot be read as a run's posterior (netCDF): {exc}") from None
