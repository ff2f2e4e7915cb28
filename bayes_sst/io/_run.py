"""A run folder: posterior.nc (ArviZ DataTree), summary.json, summary.txt."""

from __future__ import annotations

import json
from pathlib import Path

from bayes_sst.io._atomic import OutputExistsError, atomic_output_dir, dumps
from bayes_sst.io._errors import SeriesFormatError

POSTERIOR_FILE = "posterior.nc"
SUMMARY_JSON = "summary.json"
SUMMARY_TEXT = "summary.txt"


def check_run_target(path, *, overwrite: bool = False) -> None:
    """Refuse an existing run folder before any work is done, not after."""
    if Path(path).exists() and not overwrite:
        raise OutputExistsError(path, hint="pass --force (overwrite=True) to replace it")


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
        return json.loads(file.read_text())
    except json.JSONDecodeError as exc:
        raise SeriesFormatError(file, f"line {exc.lineno}", f"not valid JSON: {exc.msg}") from None


def read_run_tree(path):
    """The posterior DataTree of a run folder, read fully into memory, its file closed again.

    A lazily opened tree keeps an HDF5 handle until garbage collection, and opening the same
    file again while such handles linger has crashed the netCDF4 library; runs are small.
    """
    import xarray as xr

    file = Path(path) / POSTERIOR_FILE
    if not file.is_file():
        raise SeriesFormatError(path, "", f"not a run folder: {POSTERIOR_FILE} is missing")
    with xr.open_datatree(file, engine="netcdf4") as lazy:
        return lazy.load().copy(deep=True)
