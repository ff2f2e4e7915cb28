"""Test-series input and all-or-nothing output (see docs/data_format.md).

Light on purpose: numpy only, no jax, numpyro or matplotlib, so that the command line can
check a series without paying for the inference stack.
"""

from __future__ import annotations

from ._atomic import OutputExistsError, atomic_output_dir, write_json_atomic
from ._errors import SeriesFormatError
from ._read import load_series
from ._run import OutputTargetError, check_run_target, read_run_summary, read_run_tree, write_run
from ._table import positive_or_none, table_number
from ._series import (
    FORMAT_ID,
    OPTIONAL_COLUMNS,
    PERIODIC_KINDS,
    REQUIRED_COLUMNS,
    TEST_KINDS,
    Series,
    TestRecord,
    TestSpec,
)
from ._write import write_series

__all__ = [
    "FORMAT_ID",
    "OPTIONAL_COLUMNS",
    "PERIODIC_KINDS",
    "REQUIRED_COLUMNS",
    "TEST_KINDS",
    "OutputExistsError",
    "OutputTargetError",
    "Series",
    "SeriesFormatError",
    "TestRecord",
    "TestSpec",
    "atomic_output_dir",
    "check_run_target",
    "read_run_summary",
    "positive_or_none",
    "read_run_tree",
    "table_number",
    "write_run",
    "load_series",
    "write_json_atomic",
    "write_series",
]
