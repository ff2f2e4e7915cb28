"""Reading and writing test-series folders, and the atomic output helpers."""

from __future__ import annotations

import json
from dataclasses import replace
import os
import re
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from bayes_sst import io as sst_io
# Aliased: pytest would try to collect classes whose names start with 'Test'.
from bayes_sst.io import TestRecord as Record
from bayes_sst.io import TestSpec as Spec
from bayes_sst.io import (
    FORMAT_ID,
    OutputExistsError,
    Series,
    SeriesFormatError,
    atomic_output_dir,
    load_series,
    write_json_atomic,
    write_series,
)

FS = 100.0  # Hz
N = 400  # samples: 4 s, so 4 cycles at 1 Hz


def _columns(n=N, fs=FS, f=1.0, extra=True):
    t = np.arange(n) / fs
    u = 0.05 * np.sin(2 * np.pi * f * t)
    cols = {"t": t, "u": u, "F": 1.2e4 * np.cos(2 * np.pi * f * t) + 3.0}
    if extra:
        cols["a"] = -((2 * np.pi * f) ** 2) * u
        cols["u_cmd"] = 0.98 * u
        cols["temperature_c"] = 20.0 + 0.01 * t
    return cols


def make_series(n_tests=3) -> Series:
    kinds = ["sine", "broadband", "triangle"]
    records = []
    for k in range(n_tests):
        kind = kinds[k % 3]
        periodic = kind != "broadband"
        spec = Spec(
            id=f"T{k + 1:02d}",
            file=f"T{k + 1:02d}.csv",
            kind=kind,
            frequency_hz=1.0 if periodic else None,
            amplitude_m=0.05 if periodic else None,
            payload_kg=250.0 * k,
            order=k + 1,
            extra={"operator": "ana", "note": {"valve": "new"}} if k == 0 else {},
        )
        records.append(Record(spec=spec, columns=_columns(extra=k == 0)))
    return Series(
        name="synthetic",
        tests=tuple(records),
        table={"deck_mass_kg": 12000, "strut": {"p0_pa": 1.5e6}},
        extra={"campaign": "2024-spring"},
    )


@pytest.fixture
def folder(tmp_path) -> Path:
    return write_series(make_series(), tmp_path / "series")


def edit_manifest(folder: Path, change) -> None:
    path = folder / "series.json"
    data = json.loads(path.read_text())
    change(data)
    path.write_text(json.dumps(data))


def edit_csv(folder: Path, name: str, change) -> None:
    """Apply `change` to the list of lines of a CSV (index 0 is the header, row 1)."""
    path = folder / name
    lines = path.read_text().splitlines()
    change(lines)
    path.write_text("\n".join(lines) + "\n")


def error_of(path) -> str:
    with pytest.raises(SeriesFormatError) as info:
        load_series(path)
    return str(info.value)


def assert_error(path, file_name: str, where: str, *phrases: str) -> str:
    message = error_of(path)
    assert file_name in message, message
    assert where in message, message
    for phrase in phrases:
        assert phrase in message, message
    return message


# --- round trip -----------------------------------------------------------------------


def test_round_trip_keeps_arrays_specs_and_extras(folder):
    original = make_series()
    for loaded in (load_series(folder), load_series(folder / "series.json"), load_series(str(folder))):
        assert loaded.name == original.name
        assert loaded.table == original.table
        assert loaded.extra == original.extra
        assert loaded.path == folder
        assert len(loaded.tests) == len(original.tests)
        for a, b in zip(original.tests, loaded.tests):
            assert b.spec == a.spec
            assert list(b.columns) == list(a.columns)
            for name, values in a.columns.items():
                got = b.columns[name]
                assert got.dtype == np.float64 and got.shape == values.shape
                np.testing.assert_allclose(got, values, rtol=1e-9, atol=1e-12)
            np.testing.assert_array_equal(b.t, a.t)  # time is written with 15 digits
            assert b.sample_rate_hz == pytest.approx(FS)


def test_written_manifest_omits_none_and_keeps_extras(folder):
    data = json.loads((folder / "series.json").read_text())
    assert data["format"] == FORMAT_ID
    assert data["campaign"] == "2024-spring"
    broadband = data["tests"][1]
    assert "frequency_hz" not in broadband and "amplitude_m" not in broadband
    assert data["tests"][0]["note"] == {"valve": "new"}
    header = (folder / "T01.csv").read_text().splitlines()[0]
    assert header == "t,u,F,a,u_cmd,temperature_c"


def test_table_is_omitted_when_empty(tmp_path):
    series = make_series(1)
    bare = Series(name="bare", tests=series.tests)
    out = write_series(bare, tmp_path / "bare")
    assert "table" not in json.loads((out / "series.json").read_text())
    assert load_series(out).table == {}


def test_unknown_columns_kept_when_numeric_dropped_when_text(folder):
    def add_text_column(lines):
        lines[0] += ",label"
        lines[1:] = [line + ",run-a" for line in lines[1:]]

    edit_csv(folder, "T01.csv", add_text_column)
    record = load_series(folder).tests[0]
    assert "temperature_c" in record.columns
    assert "label" not in record.columns
    assert record.get("label") is None


def test_an_unnamed_column_is_ignored_like_any_unknown_one(folder):
    # pandas' DataFrame.to_csv writes its row index as a first column with an empty name
    original = load_series(folder).tests[1]

    def add_index_column(lines):
        lines[0] = "," + lines[0]
        lines[1:] = [f"{k},{line}" for k, line in enumerate(lines[1:])]

    edit_csv(folder, "T02.csv", add_index_column)
    record = load_series(folder).tests[1]
    assert record.columns["unnamed column 1"][-1] == original.n_samples - 1
    for name in ("t", "u", "F"):
        np.testing.assert_array_equal(record.columns[name], original.columns[name])


def test_blank_lines_are_skipped_and_rows_keep_file_numbers(folder):
    def blank_then_bad(lines):
        lines.insert(5, "")
        lines[10] = lines[10].replace(lines[10].split(",")[1], "oops", 1)

    edit_csv(folder, "T02.csv", blank_then_bad)
    assert_error(folder, "T02.csv", "row 11, column 'u'", "'oops' is not a number")


def test_large_series_loads_fast(tmp_path):
    records = tuple(
        Record(Spec(f"B{k}", f"B{k}.csv", "broadband"), _columns(n=2000, extra=True))
        for k in range(20)
    )
    out = write_series(Series(name="big", tests=records), tmp_path / "big")
    start = time.perf_counter()
    series = load_series(out)
    elapsed = time.perf_counter() - start
    assert series.n_samples == 40_000
    assert elapsed < 1.0


def test_io_does_not_import_heavy_modules():
    code = "import sys, bayes_sst.io; print(sorted(m for m in ('jax', 'numpyro', 'matplotlib') if m in sys.modules))"
    root = Path(__file__).resolve().parents[1]
    env = {**os.environ, "PYTHONPATH": str(root)}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True)
    assert out.stdout.strip() == "[]"


# --- manifest faults --------------------------------------------------------------------


def test_missing_folder(tmp_path):
    assert_error(tmp_path / "nowhere", "nowhere", "no such series folder")


def test_missing_manifest(tmp_path):
    (tmp_path / "empty").mkdir()
    assert_error(tmp_path / "empty", "series.json", "no series.json")


def test_invalid_json_gives_line_and_column(folder):
    (folder / "series.json").write_text('{\n  "format": "sst-series/1",\n  "name": "x",,\n}')
    assert_error(folder, "series.json", "line 3, column", "not valid JSON")


def test_duplicate_json_key(folder):
    (folder / "series.json").write_text('{"format": "sst-series/1", "name": "a", "name": "b", "tests": []}')
    assert_error(folder, "series.json", "key 'name'", "more than once")


def test_top_level_not_object(folder):
    (folder / "series.json").write_text("[1, 2]")
    assert_error(folder, "series.json", "top level", "must be a JSON object")


def test_format_missing(folder):
    edit_manifest(folder, lambda d: d.pop("format"))
    assert_error(folder, "series.json", "format", "is missing", FORMAT_ID)


def test_format_wrong_names_both_strings(folder):
    edit_manifest(folder, lambda d: d.update(format="sst-series/2"))
    assert_error(folder, "series.json", "format", '"sst-series/2"', 'expects "sst-series/1"')


@pytest.mark.parametrize(
    "change, problem",
    [(lambda d: d.pop("name"), "is missing"), (lambda d: d.update(name=7), "must be a string")],
)
def test_bad_name(folder, change, problem):
    edit_manifest(folder, change)
    assert_error(folder, "series.json", "name", problem)


@pytest.mark.parametrize(
    "change, problem",
    [
        (lambda d: d.pop("tests"), "is missing"),
        (lambda d: d.update(tests={"id": "T01"}), "must be a list"),
        (lambda d: d.update(tests=[]), "is empty"),
    ],
)
def test_bad_tests_list(folder, change, problem):
    edit_manifest(folder, change)
    assert_error(folder, "series.json", "tests", problem)


def test_test_entry_not_object(folder):
    edit_manifest(folder, lambda d: d["tests"].append("T09.csv"))
    assert_error(folder, "series.json", "tests[3]", "must be an object")


@pytest.mark.parametrize("key", ["id", "file", "kind"])
def test_test_entry_missing_required_key(folder, key):
    edit_manifest(folder, lambda d: d["tests"][1].pop(key))
    assert_error(folder, "series.json", f"tests[1].{key}", "is missing")


def test_unknown_kind_lists_allowed(folder):
    edit_manifest(folder, lambda d: d["tests"][2].update(kind="chirp"))
    assert_error(folder, "series.json", "tests[2].kind", "'chirp'", "'sine', 'triangle', 'broadband'")


@pytest.mark.parametrize("index", [0, 2])  # a sine and a triangle
@pytest.mark.parametrize("key", ["frequency_hz", "amplitude_m"])
@pytest.mark.parametrize(
    "value, problem",
    [(None, "is missing"), (0, "must be positive"), (-0.5, "must be positive"), ("1 Hz", "must be a number")],
)
def test_periodic_needs_positive_frequency_and_amplitude(folder, index, key, value, problem):
    def change(d):
        if value is None:
            d["tests"][index].pop(key)
        else:
            d["tests"][index][key] = value

    edit_manifest(folder, change)
    assert_error(folder, "series.json", f"tests[{index}].{key}", problem)


@pytest.mark.parametrize(
    "value, problem", [(-10, "must be zero or positive"), ("heavy", "must be a number"), (True, "must be a number")]
)
def test_bad_payload(folder, value, problem):
    edit_manifest(folder, lambda d: d["tests"][1].update(payload_kg=value))
    assert_error(folder, "series.json", "tests[1].payload_kg", problem)


@pytest.mark.parametrize(
    "value, problem", [("first", "must be an integer"), (1.5, "must be an integer"), (-1, "must not be negative")]
)
def test_bad_order(folder, value, problem):
    edit_manifest(folder, lambda d: d["tests"][0].update(order=value))
    assert_error(folder, "series.json", "tests[0].order", problem)


def test_duplicate_ids_name_both_positions(folder):
    edit_manifest(folder, lambda d: d["tests"][2].update(id="T01"))
    assert_error(folder, "series.json", "tests[2].id", "duplicate id 'T01'", "tests[0]")


def test_table_must_be_object(folder):
    edit_manifest(folder, lambda d: d.update(table=[1, 2]))
    assert_error(folder, "series.json", "table", "must be an object")


@pytest.mark.parametrize(
    "file, problem",
    [("/etc/passwd", "absolute path"), ("../outside.csv", "'..'"), ("sub/../../x.csv", "'..'")],
)
def test_file_must_stay_inside_folder(folder, file, problem):
    edit_manifest(folder, lambda d: d["tests"][1].update(file=file))
    assert_error(folder, "series.json", "tests[1].file", problem)


def test_symlink_leaving_folder_is_refused(folder, tmp_path):
    outside = tmp_path / "elsewhere.csv"
    outside.write_text((folder / "T02.csv").read_text())
    try:
        (folder / "link.csv").symlink_to(outside)
    except (OSError, NotImplementedError):
        pytest.skip("symlinks not available")
    edit_manifest(folder, lambda d: d["tests"][1].update(file="link.csv"))
    assert_error(folder, "series.json", "tests[1].file", "outside the series folder")


def test_symlink_inside_folder_is_fine(folder):
    try:
        (folder / "link.csv").symlink_to(folder / "T02.csv")
    except (OSError, NotImplementedError):
        pytest.skip("symlinks not available")
    edit_manifest(folder, lambda d: d["tests"][1].update(file="link.csv"))
    assert load_series(folder).tests[1].n_samples == N


def test_unknown_fields_are_kept(folder):
    def change(d):
        d["lab"] = {"site": "Lisbon"}
        d["tests"][1]["ambient_c"] = 21.5

    edit_manifest(folder, change)
    series = load_series(folder)
    assert series.extra["lab"] == {"site": "Lisbon"}
    assert series.tests[1].spec.extra == {"ambient_c": 21.5}


# --- CSV faults -------------------------------------------------------------------------


def test_csv_missing(folder):
    (folder / "T02.csv").unlink()
    assert_error(folder, "T02.csv", "tests[1].file", "not found")


def test_csv_empty(folder):
    (folder / "T02.csv").write_text("")
    assert_error(folder, "T02.csv", "T02.csv", "empty")


def test_csv_without_header(folder):
    edit_csv(folder, "T02.csv", lambda lines: lines.pop(0))
    message = assert_error(folder, "T02.csv", "row 1", "not a header")
    # the first cells are quoted whole, not cut in the middle of a number
    first = (folder / "T02.csv").read_text().splitlines()[0].split(",")
    assert f"({', '.join(first[:3])}{', ...' if len(first) > 3 else ''})" in message, message


def test_missing_required_column_lists_columns_found(folder):
    def drop_f(lines):
        lines[:] = [",".join(line.split(",")[:2]) for line in lines]

    edit_csv(folder, "T02.csv", drop_f)
    assert_error(folder, "T02.csv", "column 'F'", "missing", "columns found: 't', 'u'")


def test_non_numeric_cell_names_row_column_and_text(folder):
    def spoil(lines):
        cells = lines[16].split(",")  # row 17 of the file
        cells[1] = "12mm"
        lines[16] = ",".join(cells)

    edit_csv(folder, "T01.csv", spoil)
    assert_error(folder, "T01.csv", "row 17, column 'u'", "'12mm' is not a number")


def test_empty_cell(folder):
    def spoil(lines):
        cells = lines[4].split(",")
        cells[2] = ""
        lines[4] = ",".join(cells)

    edit_csv(folder, "T02.csv", spoil)
    assert_error(folder, "T02.csv", "row 5, column 'F'", "empty cell")


@pytest.mark.parametrize("text", ["nan", "inf", "-Infinity"])
def test_non_finite_cell(folder, text):
    def spoil(lines):
        cells = lines[29].split(",")
        cells[2] = text
        lines[29] = ",".join(cells)

    edit_csv(folder, "T02.csv", spoil)
    assert_error(folder, "T02.csv", "row 30, column 'F'", "not finite")


def test_ragged_row(folder):
    edit_csv(folder, "T02.csv", lambda lines: lines.__setitem__(8, lines[8] + ",1.0"))
    assert_error(folder, "T02.csv", "row 9", "has 4 fields", "3 columns", "ragged")


def test_short_row(folder):
    edit_csv(folder, "T02.csv", lambda lines: lines.__setitem__(3, lines[3].rsplit(",", 1)[0]))
    assert_error(folder, "T02.csv", "row 4", "has 2 fields", "ragged")


def test_fewer_than_two_rows(folder):
    edit_csv(folder, "T02.csv", lambda lines: lines.__delitem__(slice(2, None)))
    assert_error(folder, "T02.csv", "rows", "1 data row", "at least 2")


def test_header_only(folder):
    edit_csv(folder, "T02.csv", lambda lines: lines.__delitem__(slice(1, None)))
    assert_error(folder, "T02.csv", "rows", "0 data row", "at least 2")


def test_time_not_increasing(folder):
    def swap(lines):
        lines[20], lines[21] = lines[21], lines[20]

    edit_csv(folder, "T02.csv", swap)
    assert_error(folder, "T02.csv", "row 22, column 't'", "strictly increase")


def test_time_repeated(folder):
    def repeat(lines):
        cells = lines[41].split(",")
        cells[0] = lines[40].split(",")[0]
        lines[41] = ",".join(cells)

    edit_csv(folder, "T02.csv", repeat)
    assert_error(folder, "T02.csv", "row 42, column 't'", "does not come after")


def test_time_not_uniform_gives_values(folder):
    def jitter(lines):
        cells = lines[50].split(",")
        cells[0] = "0.493"  # sample 49 is at 0.49 s; the step from 0.48 becomes 0.013 s
        lines[50] = ",".join(cells)

    edit_csv(folder, "T02.csv", jitter)
    assert_error(folder, "T02.csv", "row 51, column 't'", "time step 0.013", "median step 0.01",
                 "more than 20%", "uniform")


def test_time_far_from_zero_is_printed_with_the_digits_that_tell_the_samples_apart(folder):
    def shift(lines):
        for k in range(1, len(lines)):
            cells = lines[k].split(",")
            if cells[0].strip():
                cells[0] = repr(1e9 + float(cells[0]))
                lines[k] = ",".join(cells)
        cells = lines[50].split(",")
        cells[0] = repr(1e9 + 0.493)
        lines[50] = ",".join(cells)

    edit_csv(folder, "T02.csv", shift)
    assert_error(folder, "T02.csv", "row 51, column 't'", "from t = 1000000000.48 to 1000000000.49", "uniform")


@pytest.mark.parametrize("decimals", [6, 4])
def test_time_printed_with_few_decimals_at_a_binary_rate_loads_with_its_exact_rate(tmp_path, decimals):
    # At 1024 Hz a step is 0.0009765625 s: printed with 6 decimals, single steps differ by
    # 0.1 % (the rule before, every step within 0.1 % of the median, refused such a file);
    # with 4 decimals by 10 %. Each stamp is still within 0.05 step of the uniform grid.
    fs = 1024.0
    series = make_series(1)
    columns = dict(_columns(n=4096, fs=fs, extra=False))
    columns["t"] = np.round(columns["t"], decimals)
    steps = np.diff(columns["t"])
    assert np.ptp(steps) > 1e-3 * np.median(steps)
    record = Record(spec=series.tests[0].spec, columns=columns)
    folder = write_series(Series(name="rounded", tests=(record,)), tmp_path / "rounded")
    loaded = load_series(folder)
    assert loaded.tests[0].sample_rate_hz == fs
    np.testing.assert_allclose(loaded.tests[0].t, columns["t"], rtol=0, atol=0.51 * 10.0 ** -decimals)


def test_a_clock_that_changes_rate_within_the_record_is_refused(folder):
    # From row 202 on the steps are 1 % longer: no single step is far off the median, but
    # by the end the stamps run 2 steps past the grid the first half follows.
    def stretch(lines):
        for k in range(202, len(lines)):
            cells = lines[k].split(",")
            if cells[0].strip():
                t = float(cells[0])
                cells[0] = repr(2.0 + 1.01 * (t - 2.0))
                lines[k] = ",".join(cells)

    edit_csv(folder, "T02.csv", stretch)
    message = assert_error(folder, "T02.csv", "column 't'", "steps off the uniform grid", "rate changes",
                           "uniform")
    assert "differs from the median step" not in message


def test_gap_in_time(folder):
    edit_csv(folder, "T02.csv", lambda lines: lines.__delitem__(100))  # drops t = 0.99 s
    assert_error(folder, "T02.csv", "row 101, column 't'", "time step 0.02", "from t = 0.98 to 1", "uniform")


@pytest.mark.parametrize("index, name", [(0, "T01.csv"), (2, "T03.csv")])
def test_periodic_needs_three_cycles(folder, index, name):
    edit_manifest(folder, lambda d: d["tests"][index].update(frequency_hz=0.5))  # 4 s: 2 cycles
    assert_error(folder, name, "column 't'", "2.00 cycles", f"tests[{index}].frequency_hz", "at least 3")


def test_exactly_three_cycles_is_enough(folder):
    edit_manifest(folder, lambda d: d["tests"][0].update(frequency_hz=0.75))  # 4 s: 3 cycles
    assert load_series(folder).tests[0].spec.frequency_hz == 0.75


def test_a_frequency_the_sampling_cannot_hold_is_refused(folder):
    # at 100 Hz the record holds at most 50 Hz; a time column in milliseconds looks like this
    edit_manifest(folder, lambda d: d["tests"][2].update(frequency_hz=60.0))
    assert_error(folder, "T03.csv", "column 't'", "tests[2].frequency_hz = 60 Hz", "half the sampling rate",
                 "50 Hz", "seconds")


def test_sample_rate_is_read_over_the_record_and_snapped_to_whole_hertz():
    from bayes_sst.io._series import sample_rate_of

    # time stamps far from zero, written with 6 decimals: single steps are off in the last digits
    t = np.round(12.5 + np.arange(4001) / 200.0, 6)
    assert 1.0 / (t[1] - t[0]) != 200.0
    assert sample_rate_of(t) == 200.0
    t = np.round(1.7e9 + np.arange(5001) / 1000.0, 6)
    assert sample_rate_of(t) == 1000.0
    # a rate that is not a whole number of Hz stays what it is
    assert sample_rate_of(np.arange(1000) / 199.9) == pytest.approx(199.9, rel=1e-12)
    assert sample_rate_of(np.arange(1000) * 0.003) == pytest.approx(1000.0 / 3.0, rel=1e-12)


def test_two_tests_cannot_share_a_file(folder):
    edit_manifest(folder, lambda d: d["tests"][2].update(file=d["tests"][0]["file"]))
    assert_error(folder, "series.json", "tests[2].file", "'T01.csv' is already the file of tests[0]")


def test_broadband_has_no_cycle_rule(folder):
    edit_csv(folder, "T02.csv", lambda lines: lines.__delitem__(slice(11, None)))
    assert load_series(folder).tests[1].n_samples == 10


def test_error_is_a_value_error_with_parts(folder):
    edit_manifest(folder, lambda d: d["tests"][0].update(amplitude_m=-1))
    with pytest.raises(ValueError) as info:
        load_series(folder)
    err = info.value
    assert isinstance(err, SeriesFormatError)
    assert err.path.endswith("series.json") and err.where == "tests[0].amplitude_m"


# --- writing ----------------------------------------------------------------------------


def test_write_refuses_existing_folder(folder):
    before = (folder / "series.json").read_text()
    with pytest.raises(OutputExistsError) as info:
        write_series(make_series(1), folder)
    assert isinstance(info.value, FileExistsError)
    assert str(folder) in str(info.value) and "overwrite" in str(info.value)
    assert (folder / "series.json").read_text() == before


def test_write_overwrite_replaces(folder):
    write_series(make_series(1), folder, overwrite=True)
    assert [t.id for t in load_series(folder).tests] == ["T01"]
    assert not (folder / "T02.csv").exists()
    assert sorted(p.name for p in folder.parent.iterdir()) == ["series"]


def _fail_on_second_csv(monkeypatch):
    real = sst_io._write.write_csv
    calls = []

    def flaky(path, columns):
        calls.append(path)
        if len(calls) == 2:
            real(path, columns)  # leave a complete file behind
            raise OSError("disk full")
        real(path, columns)

    monkeypatch.setattr(sst_io._write, "write_csv", flaky)


def test_interrupted_write_leaves_nothing(tmp_path, monkeypatch):
    _fail_on_second_csv(monkeypatch)
    with pytest.raises(OSError, match="disk full"):
        write_series(make_series(), tmp_path / "out")
    assert list(tmp_path.iterdir()) == []


def test_interrupted_overwrite_keeps_old_folder(folder, monkeypatch):
    before = {p.name: p.read_bytes() for p in folder.iterdir()}
    _fail_on_second_csv(monkeypatch)
    with pytest.raises(OSError, match="disk full"):
        write_series(make_series(2), folder, overwrite=True)
    after = {p.name: p.read_bytes() for p in folder.iterdir()}
    assert after == before
    assert sorted(p.name for p in folder.parent.iterdir()) == ["series"]


def test_column_that_fails_to_convert_leaves_nothing(tmp_path):
    class Exploding:
        shape = (N,)

        def __array__(self, dtype=None, copy=None):
            raise RuntimeError("sensor lost")

        def __len__(self):
            return N

    series = make_series()
    bad = dict(series.tests[2].columns, F=Exploding())
    tests = series.tests[:2] + (Record(series.tests[2].spec, bad),)
    with pytest.raises(RuntimeError, match="sensor lost"):
        write_series(Series(name="x", tests=tests), tmp_path / "out")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    "mutate, where",
    [
        (lambda r: (Record(Spec("A", "../a.csv", "broadband"), r.columns),), "tests[0].file"),
        (lambda r: (r, Record(Spec("B", r.spec.file, "broadband"), r.columns)), "tests[1].file"),
        (lambda r: (Record(r.spec, {"t": r.t, "u": r.u}),), "column 'F'"),
        (lambda r: (Record(r.spec, dict(r.columns, F=r.F[:-1])),), "differ in length"),
    ],
)
def test_write_refuses_invalid_series(tmp_path, mutate, where):
    record = make_series(1).tests[0]
    with pytest.raises(SeriesFormatError, match=re.escape(where)):
        write_series(Series(name="x", tests=mutate(record)), tmp_path / "out")
    assert list(tmp_path.iterdir()) == []


# --- atomic helpers ---------------------------------------------------------------------


def test_atomic_output_dir_success_and_failure(tmp_path):
    target = tmp_path / "runs" / "r1"
    with atomic_output_dir(target) as tmp:
        assert tmp.parent == target.parent and tmp != target
        (tmp / "a.txt").write_text("ok")
        assert not target.exists()
    assert (target / "a.txt").read_text() == "ok"

    with pytest.raises(OutputExistsError):
        with atomic_output_dir(target):
            pass

    with pytest.raises(KeyboardInterrupt):
        with atomic_output_dir(target, overwrite=True) as tmp:
            (tmp / "b.txt").write_text("half")
            raise KeyboardInterrupt
    assert sorted(p.name for p in target.iterdir()) == ["a.txt"]
    assert sorted(p.name for p in target.parent.iterdir()) == ["r1"]

    with atomic_output_dir(target, overwrite=True) as tmp:
        (tmp / "b.txt").write_text("new")
    assert sorted(p.name for p in target.iterdir()) == ["b.txt"]
    assert sorted(p.name for p in target.parent.iterdir()) == ["r1"]


def test_write_json_atomic(tmp_path):
    path = tmp_path / "summary.json"
    write_json_atomic(path, {"x": np.float64(1.5), "n": np.int64(3), "v": np.arange(3)})
    assert json.loads(path.read_text()) == {"x": 1.5, "n": 3, "v": [0, 1, 2]}
    write_json_atomic(path, {"x": 2})
    assert json.loads(path.read_text()) == {"x": 2}
    # a value the computation could not give is null, not the NaN or Infinity that JSON lacks
    write_json_atomic(path, {"x": float("nan"), "y": [np.inf, 1.0], "z": {"w": -np.inf}})
    assert json.loads(path.read_text()) == {"x": None, "y": [None, 1.0], "z": {"w": None}}
    write_json_atomic(path, {"x": 2})
    with pytest.raises(TypeError):
        write_json_atomic(path, {"x": object()})
    assert json.loads(path.read_text()) == {"x": 2}
    # a series manifest keeps refusing them: its fields must be numbers
    from bayes_sst.io._atomic import dumps

    with pytest.raises(ValueError):
        dumps({"frequency_hz": float("nan")}, non_finite_as_null=False)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["summary.json"]


def test_write_series_refuses_a_nan_in_the_manifest(tmp_path):
    series = make_series()
    spec = replace(series.tests[0].spec, frequency_hz=float("nan"))
    bad = replace(series, tests=(replace(series.tests[0], spec=spec),) + series.tests[1:])
    with pytest.raises(ValueError):
        write_series(bad, tmp_path / "out")
    assert not (tmp_path / "out").exists()


def test_symlink_loop_is_reported(folder):
    try:
        (folder / "loop.csv").symlink_to(folder / "loop.csv")
    except (OSError, NotImplementedError):
        pytest.skip("symlinks not available")
    edit_manifest(folder, lambda d: d["tests"][1].update(file="loop.csv"))
    assert_error(folder, "series.json", "tests[1].file", "loop.csv")


def test_huge_integer_frequency(folder):
    edit_manifest(folder, lambda d: d["tests"][0].update(frequency_hz=10**400))
    assert_error(folder, "series.json", "tests[0].frequency_hz", "must be positive and finite")


def test_manifest_path_in_missing_folder(tmp_path):
    message = assert_error(tmp_path / "gone" / "series.json", "gone", "no such series folder")
    assert "series.json" not in message


# --- leaving tests out -------------------------------------------------------------------


def test_excluded_tests_are_not_read_and_are_recorded(folder):
    full = load_series(folder)
    (folder / "T02.csv").write_text("t,u,F\n0,1\n")  # a broken file the exclusion must not read
    assert "T02.csv" in error_of(folder)
    series = load_series(folder, exclude=["T02"])
    assert load_series(folder, exclude="T02").left_out == ("T02",)  # one id as a string
    assert [t.id for t in series.tests] == [t.id for t in full.tests if t.id != "T02"]
    assert series.left_out == ("T02",)
    kept = series.tests[0]
    assert np.array_equal(kept.F, full.test(kept.id).F)


def test_excluding_an_unknown_id_names_it_and_the_known_ones(folder):
    with pytest.raises(SeriesFormatError) as info:
        load_series(folder, exclude=["T02", "T9"])
    message = str(info.value)
    assert "series.json" in message and "'T9'" in message and "T01, T02" in message, message
    assert "'T02'" not in message, message


def test_excluding_every_test_is_refused(folder):
    ids = [t.id for t in load_series(folder).tests]
    with pytest.raises(SeriesFormatError, match="every test is left out"):
        load_series(folder, exclude=ids)


def test_series_without_drops_tests_and_extends_left_out(folder):
    series = load_series(folder, exclude=["T01"])
    fewer = series.without(["T02", "absent"])
    assert [t.id for t in fewer.tests] == [t.id for t in series.tests if t.id != "T02"]
    assert fewer.left_out == ("T01", "T02")
    assert series.without("absent") is series
