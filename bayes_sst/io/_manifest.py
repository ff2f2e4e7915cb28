"""Read and check ``series.json``, the manifest of a test series."""

from __future__ import annotations

import json
import os
import math
from dataclasses import dataclass
from pathlib import Path, PurePosixPath, PureWindowsPath
from typing import Any, NoReturn

from ._errors import SeriesFormatError
from ._series import FORMAT_ID, PERIODIC_KINDS, TEST_KINDS, TestSpec

MANIFEST_NAME = "series.json"
TOP_LEVEL_KEYS = ("format", "name", "table", "tests")
TEST_KEYS = ("id", "file", "kind", "frequency_hz", "amplitude_m", "payload_kg", "order")


@dataclass(frozen=True)
class Manifest:
    """The checked content of a manifest, before any CSV is read."""

    path: Path
    name: str
    table: dict
    extra: dict
    specs: tuple[TestSpec, ...]


class _DuplicateKey(Exception):
    def __init__(self, key: str):
        self.key = key


def _no_duplicate_keys(pairs: list[tuple[str, Any]]) -> dict:
    # json keeps the last of repeated keys silently; a repeated field is almost always a
    # copy-paste slip that would make the file mean something else than it seems to.
    seen = {}
    for key, value in pairs:
        if key in seen:
            raise _DuplicateKey(key)
        seen[key] = value
    return seen


def _describe(value: Any) -> str:
    text = json.dumps(value) if not isinstance(value, float) else repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


def _is_number(value: Any) -> bool:
    # bool is an int in Python but `true` is no frequency.
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _is_finite(value: int | float) -> bool:
    # JSON integers are unbounded; one too large for a float is as unusable as infinity.
    try:
        return math.isfinite(value)
    except OverflowError:
        return False


class FieldChecker:
    """Raise SeriesFormatError for a manifest field; holds the manifest path for messages."""

    def __init__(self, path: Path):
        self.path = path

    def fail(self, where: str, problem: str) -> NoReturn:
        raise SeriesFormatError(self.path, where, problem)

    def positive(self, entry: dict, key: str, where: str, kind: str) -> float | None:
        value = entry.get(key)
        if value is None:
            if kind in PERIODIC_KINDS:
                state = "is missing" if key not in entry else "is null"
                self.fail(where, f"{state}; a {kind} test needs a positive {key}")
            return None
        if not _is_number(value):
            self.fail(where, f"must be a number, found {_describe(value)}")
        if not (_is_finite(value) and value > 0):
            self.fail(where, f"must be positive and finite, found {_describe(value)}")
        return float(value)

    def payload(self, entry: dict, where: str) -> float:
        value = entry.get("payload_kg")
        if value is None:
            return 0.0
        if not _is_number(value):
            self.fail(where, f"must be a number of kilograms, found {_describe(value)}")
        if not (_is_finite(value) and value >= 0):
            self.fail(where, f"must be zero or positive and finite, found {_describe(value)}")
        return float(value)

    def order(self, entry: dict, where: str) -> int | None:
        value = entry.get("order")
        if value is None:
            return None
        integral = (isinstance(value, int) and not isinstance(value, bool)) or (
            isinstance(value, float) and value.is_integer()
        )
        if not integral:
            self.fail(where, f"must be an integer position, found {_describe(value)}")
        if value < 0:
            self.fail(where, f"must not be negative, found {_describe(value)}")
        return int(value)

    def text(self, entry: dict, key: str, where: str) -> str:
        if key not in entry:
            self.fail(where, "is missing")
        value = entry[key]
        if not isinstance(value, str):
            self.fail(where, f"must be a string, found {_describe(value)}")
        if not value.strip():
            self.fail(where, "must not be empty")
        return value

    def relative_file(self, value: str, where: str) -> None:
        # Checked on the text, not on the resolved path, so the rule does not depend on
        # what happens to exist on disk; symlinks are checked when the file is opened.
        if "\x00" in value:
            self.fail(where, f"{value!r} contains a NUL character")
        posix, windows = PurePosixPath(value), PureWindowsPath(value)
        if posix.is_absolute() or windows.is_absolute() or windows.drive or windows.root:
            self.fail(where, f"{value!r} is an absolute path; it must be relative to the series folder")
        if ".." in windows.parts:
            self.fail(where, f"{value!r} contains '..'; the file must stay inside the series folder")


def _read_json(path: Path) -> Any:
    if not path.is_file():
        folder = path.parent
        if not folder.is_dir():
            raise SeriesFormatError(folder, "", "no such series folder")
        raise SeriesFormatError(path, "", f"no {MANIFEST_NAME} in the series folder")
    try:
        text = path.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError as exc:
        raise SeriesFormatError(path, f"byte {exc.start}", "not UTF-8 text") from None
    except OSError as exc:
        raise SeriesFormatError(path, "", f"cannot be read: {exc.strerror or exc}") from None
    try:
        return json.loads(text, object_pairs_hook=_no_duplicate_keys)
    except json.JSONDecodeError as exc:
        raise SeriesFormatError(
            path, f"line {exc.lineno}, column {exc.colno}", f"not valid JSON: {exc.msg}"
        ) from None
    except _DuplicateKey as exc:
        raise SeriesFormatError(
            path, f"key {exc.key!r}", "appears more than once in the same object"
        ) from None
    except RecursionError:
        raise SeriesFormatError(path, "", "not valid JSON: nested too deeply") from None


def _test_spec(check: FieldChecker, entry: Any, i: int) -> TestSpec:
    at = f"tests[{i}]"
    if not isinstance(entry, dict):
        check.fail(at, f"must be an object, found {_describe(entry)}")
    test_id = check.text(entry, "id", f"{at}.id")
    file = check.text(entry, "file", f"{at}.file")
    check.relative_file(file, f"{at}.file")
    kind = check.text(entry, "kind", f"{at}.kind")
    if kind not in TEST_KINDS:
        allowed = ", ".join(repr(k) for k in TEST_KINDS)
        check.fail(f"{at}.kind", f"unknown kind {kind!r}; allowed kinds are {allowed}")
    return TestSpec(
        id=test_id,
        file=file,
        kind=kind,
        frequency_hz=check.positive(entry, "frequency_hz", f"{at}.frequency_hz", kind),
        amplitude_m=check.positive(entry, "amplitude_m", f"{at}.amplitude_m", kind),
        payload_kg=check.payload(entry, f"{at}.payload_kg"),
        order=check.order(entry, f"{at}.order"),
        extra={k: v for k, v in entry.items() if k not in TEST_KEYS},
    )


def read_manifest(path: Path) -> Manifest:
    """Parse and check a manifest.

    Parameters
    ----------
    path : Path
        The ``series.json`` file.

    Returns
    -------
    Manifest
        Name, table, unknown top-level fields and one TestSpec per test, in file order.

    Raises
    ------
    SeriesFormatError
        The file is missing, is not JSON, or breaks a rule of the format.
    """
    data = _read_json(path)
    check = FieldChecker(path)
    if not isinstance(data, dict):
        check.fail("top level", f"must be a JSON object, found {type(data).__name__}")
    if "format" not in data:
        check.fail("format", f"is missing; expected {_describe(FORMAT_ID)}")
    if data["format"] != FORMAT_ID:
        check.fail(
            "format",
            f"is {_describe(data['format'])} but this reader expects {_describe(FORMAT_ID)}",
        )
    name = check.text(data, "name", "name")
    table = data.get("table", {})
    if not isinstance(table, dict):
        check.fail("table", f"must be an object, found {_describe(table)}")
    tests = data.get("tests")
    if "tests" not in data:
        check.fail("tests", "is missing; expected a non-empty list of tests")
    if not isinstance(tests, list):
        check.fail("tests", f"must be a list, found {_describe(tests)}")
    if not tests:
        check.fail("tests", "is empty; a series needs at least one test")
    specs = tuple(_test_spec(check, entry, i) for i, entry in enumerate(tests))
    # one record under two ids would count its data twice, or, under another test's frequency,
    # be cut into cycles that are not its own
    first_seen: dict[str, int] = {}
    file_seen: dict[str, int] = {}
    for i, spec in enumerate(specs):
        if spec.id in first_seen:
            check.fail(
                f"tests[{i}].id",
                f"duplicate id {spec.id!r}, already used by tests[{first_seen[spec.id]}]",
            )
        first_seen[spec.id] = i
        file = os.path.normpath(spec.file)
        if file in file_seen:
            check.fail(
                f"tests[{i}].file",
                f"{spec.file!r} is already the file of tests[{file_seen[file]}]; each test needs its own record",
            )
        file_seen[file] = i
    return Manifest(
        path=path,
        name=name,
        table=table,
        extra={k: v for k, v in data.items() if k not in TOP_LEVEL_KEYS},
        specs=specs,
    )


def csv_path_of(manifest: Manifest, index: int) -> Path:
    """The CSV of test `index`, checked to exist and to lie inside the series folder.

    Raises
    ------
    SeriesFormatError
        The file is missing, is not a regular file, or (through a symlink) lies outside.
    """
    spec = manifest.specs[index]
    folder = manifest.path.parent
    where = f"tests[{index}].file"
    csv_path = folder / spec.file
    try:
        root = folder.resolve()
        target = csv_path.resolve()
    except (OSError, RuntimeError) as exc:  # a symlink loop, depending on the Python version
        raise SeriesFormatError(manifest.path, where, f"cannot resolve {spec.file!r}: {exc}") from None
    if not target.is_relative_to(root):
        raise SeriesFormatError(
            manifest.path, where,
            f"{spec.file!r} resolves to {target}, outside the series folder {root}",
        )
    if not csv_path.exists():
        raise SeriesFormatError(manifest.path, where, f"CSV file not found: {csv_path}")
    if not csv_path.is_file():
        raise SeriesFormatError(manifest.path, where, f"{csv_path} is not a regular file")
    return csv_path
