"""In-memory form of a test series (see docs/data_format.md)."""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import cached_property
from pathlib import Path
from typing import Any, Mapping

import numpy as np

FORMAT_ID = "sst-series/1"
TEST_KINDS = ("sine", "triangle", "broadband")
PERIODIC_KINDS = ("sine", "triangle")
REQUIRED_COLUMNS = ("t", "u", "F")
OPTIONAL_COLUMNS = ("a", "v", "u_cmd", "a_cmd")
# a rate within this relative distance of a whole number of Hz is that number
WHOLE_HZ_RTOL = 1e-6


def uniform_grid(t) -> tuple[float, float]:
    """The straight line that a time column follows, t_i ~ t_0 + offset + step*i (least squares
    over the sample number i). Returns (offset, step).

    Why least squares rather than the end points or single steps: time stamps are rounded when
    they are printed (t with 6 decimals at 1024 Hz rounds each stamp by up to 5e-7 s, half a
    part in a thousand of a step), and over the whole column that rounding averages out."""
    t = np.asarray(t, dtype=float)
    n = t.shape[0]
    if n < 2:
        raise ValueError("a time column needs at least two samples to have a step")
    since_start = t - t[0]
    # sum_i (i - m)^2 = n(n^2 - 1)/12 with m = (n - 1)/2, so only one index vector is built
    mean_index = 0.5 * (n - 1)
    total = float(since_start.sum())
    step = (float(np.dot(np.arange(n, dtype=float), since_start)) - mean_index * total) / (n * (n * n - 1) / 12.0)
    offset = total / n - step * mean_index
    return offset, step


def sample_rate_of(t) -> float:
    """The sampling rate of a uniform time column, fs = 1/step with the step of the column's
    least-squares line (`uniform_grid`), snapped to a whole number of Hz within WHOLE_HZ_RTOL.
    Why not 1/(t[1] - t[0]): a clock far from zero rounds each time stamp in its last digits
    (t from 12.5 s at 200 Hz gave 199.99999999997 Hz, and the decimation, a whole number of
    samples, came out 49 instead of 50), and so does a time column printed with few decimals;
    over the record the rounding averages out."""
    _, step = uniform_grid(t)
    rate = 1.0 / step
    whole = round(rate)
    return float(whole) if whole > 0 and abs(rate - whole) <= WHOLE_HZ_RTOL * rate else rate


@dataclass(frozen=True)
class TestSpec:
    """One entry of the manifest's ``tests`` list (SI units)."""

    __test__ = False  # not a pytest test class, despite the name

    id: str
    file: str
    kind: str
    frequency_hz: float | None = None
    amplitude_m: float | None = None
    payload_kg: float = 0.0
    order: int | None = None
    extra: Mapping[str, Any] = field(default_factory=dict)

    @property
    def is_periodic(self) -> bool:
        return self.kind in PERIODIC_KINDS


@dataclass(frozen=True)
class TestRecord:
    """A test's manifest entry and its sampled columns, each a float64 array of equal length."""

    __test__ = False  # not a pytest test class, despite the name

    spec: TestSpec
    columns: Mapping[str, np.ndarray]

    @property
    def id(self) -> str:
        return self.spec.id

    @property
    def t(self) -> np.ndarray:
        return self.columns["t"]

    @property
    def u(self) -> np.ndarray:
        return self.columns["u"]

    @property
    def F(self) -> np.ndarray:
        return self.columns["F"]

    def get(self, name: str) -> np.ndarray | None:
        """A column by name, or None when the test did not record it."""
        return self.columns.get(name)

    @cached_property
    def sample_rate_hz(self) -> float:
        # cached: read over the whole column, and asked for several times per test
        return sample_rate_of(self.t)

    @property
    def n_samples(self) -> int:
        return int(self.t.shape[0])


def as_test_ids(test_ids) -> list[str]:
    """A test id, or an iterable of them, as a list (a lone string is one id, not its letters)."""
    return [test_ids] if isinstance(test_ids, str) else list(test_ids)


@dataclass(frozen=True)
class Series:
    """A named campaign of tests on one table, with the table's nominal description."""

    name: str
    tests: tuple[TestRecord, ...]
    table: Mapping[str, Any] = field(default_factory=dict)
    path: Path | None = None
    extra: Mapping[str, Any] = field(default_factory=dict)
    # ids of the manifest's tests left out when it was read (load_series(..., exclude=...))
    left_out: tuple[str, ...] = ()

    @property
    def periodic_tests(self) -> tuple[TestRecord, ...]:
        return tuple(t for t in self.tests if t.spec.is_periodic)

    def test(self, test_id: str) -> TestRecord:
        for record in self.tests:
            if record.id == test_id:
                return record
        raise KeyError(test_id)

    @property
    def n_samples(self) -> int:
        return sum(t.n_samples for t in self.tests)

    def without(self, test_ids) -> "Series":
        """This series less the tests with these ids (ids it lacks are ignored); they join
        ``left_out``."""
        drop = set(as_test_ids(test_ids))
        dropped = tuple(t.id for t in self.tests if t.id in drop)
        if not dropped:
            return self
        return replace(self, tests=tuple(t for t in self.tests if t.id not in drop),
                       left_out=self.left_out + dropped)
