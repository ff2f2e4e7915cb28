"""Test plans: which tests a simulated campaign runs, and the presets' default plans.

Periodic tests ('sine', 'triangle') are given by frequency and amplitude; broadband tests
('broadband') by their signal ('noise' or 'earthquake', see _broadband.py), the peak of the
commanded acceleration and the signal's duration.
"""

from __future__ import annotations

import math
from typing import Any, Iterable, Mapping, NamedTuple

import numpy as np

from bayes_sst.twin._broadband import (
    BROADBAND_SIGNALS,
    DEFAULT_BROADBAND_DURATION_S,
    DEFAULT_PEAK_ACCELERATION,
)
from bayes_sst.twin._command import Command
from bayes_sst.twin._truth import TableTruth

PERIODIC_PLAN_KINDS = ("sine", "triangle")
PLAN_KINDS = PERIODIC_PLAN_KINDS + ("broadband",)


class PlanItem(NamedTuple):
    """One planned test.

    kind: 'sine', 'triangle' or 'broadband'; frequency_hz (Hz) and amplitude_m (m): the
    periodic command, None for a broadband test; payload_kg (kg); id: the test's name in the
    series, None lets simulate() number it (S01, T02, B03, ...).

    Broadband tests only: signal ('noise' or 'earthquake'), duration_s (s, the signal
    without the rests before and after), peak_acceleration_m_s2 (max |a_cmd|, m/s^2).
    sample_rate_hz: this test's output rate, None for simulate()'s default of its kind.
    """

    kind: str
    frequency_hz: float | None
    amplitude_m: float | None
    payload_kg: float = 0.0
    id: str | None = None
    signal: str | None = None
    duration_s: float | None = None
    peak_acceleration_m_s2: float | None = None
    sample_rate_hz: float | None = None

    @property
    def is_broadband(self) -> bool:
        return self.kind == "broadband"

    def describe(self) -> str:
        if self.is_broadband:
            return f"broadband {self.signal} ({self.peak_acceleration_m_s2} m/s^2 peak)"
        return f"{self.kind} {self.frequency_hz} Hz x {self.amplitude_m} m"


_MISSING = object()


def _field(item: Any, name: str, default: Any = None) -> Any:
    if isinstance(item, Mapping):
        return item.get(name, default)
    value = getattr(item, name, _MISSING)
    if value is not _MISSING:
        return value
    # A TestSpec keeps the fields the format does not name (signal, duration_s, ...) in extra.
    extra = getattr(item, "extra", None)
    if isinstance(extra, Mapping):
        return extra.get(name, default)
    return default


def _positive_or_none(item: Any, name: str) -> float | None:
    value = _field(item, name)
    if value is None:
        return None
    value = float(value)
    if not (math.isfinite(value) and value > 0.0):
        raise ValueError(f"{name} must be positive, got {value!r}")
    return value


def _broadband_item(item: Any, payload: float, test_id: str | None, rate: float | None) -> PlanItem:
    signal = _field(item, "signal")
    if signal not in BROADBAND_SIGNALS:
        raise ValueError(f"a test of kind 'broadband' needs a signal, one of {BROADBAND_SIGNALS}; "
                         f"got {signal!r} in {item!r}")
    for name in ("frequency_hz", "amplitude_m"):
        if _field(item, name) is not None:
            raise ValueError(f"a broadband test takes no {name}; scale it with peak_acceleration_m_s2 "
                             f"and set its length with duration_s (got {item!r})")
    duration = _positive_or_none(item, "duration_s") or DEFAULT_BROADBAND_DURATION_S[signal]
    peak = _positive_or_none(item, "peak_acceleration_m_s2") or DEFAULT_PEAK_ACCELERATION[signal]
    return PlanItem("broadband", None, None, payload, test_id, signal, duration, peak, rate)


def as_plan_item(item: Any) -> PlanItem:
    """A PlanItem from a dict, a PlanItem, a TestSpec or any object with the same attributes."""
    kind = _field(item, "kind")
    if kind not in PLAN_KINDS:
        raise ValueError(f"the twin simulates {PLAN_KINDS} tests, got kind {kind!r}")
    payload = float(_field(item, "payload_kg", 0.0) or 0.0)
    if not (math.isfinite(payload) and payload >= 0.0):
        raise ValueError(f"payload_kg must be non-negative, got {payload!r}")
    test_id = _field(item, "id")
    test_id = None if test_id is None else str(test_id)
    rate = _positive_or_none(item, "sample_rate_hz")
    if kind == "broadband":
        return _broadband_item(item, payload, test_id, rate)
    frequency = _field(item, "frequency_hz")
    amplitude = _field(item, "amplitude_m")
    if frequency is None or amplitude is None:
        raise ValueError(f"a {kind} test needs frequency_hz and amplitude_m, got {item!r}")
    frequency, amplitude = float(frequency), float(amplitude)
    if not (math.isfinite(frequency) and frequency > 0.0):
        raise ValueError(f"frequency_hz must be positive, got {frequency!r}")
    if not (math.isfinite(amplitude) and amplitude > 0.0):
        raise ValueError(f"amplitude_m must be positive, got {amplitude!r}")
    return PlanItem(kind, frequency, amplitude, payload, test_id, sample_rate_hz=rate)


def as_plan(plan: Iterable[Any]) -> list[PlanItem]:
    items = [as_plan_item(item) for item in plan]
    if not items:
        raise ValueError("the plan holds no tests")
    return items


def check_limits(item: PlanItem, command: Command, truth: TableTruth) -> None:
    """Refuse a command that leaves the table's stroke or exceeds its velocity limit (and, for a
    broadband test, whose acceleration exceeds the table's limit)."""
    # A whisker of slack so that a plan written at exactly the limit is accepted.
    slack = 1.0 + 1e-6
    peak_u = float(np.max(np.abs(command.u)))
    peak_v = float(np.max(np.abs(command.v)))
    if peak_u > truth.stroke * slack:
        raise ValueError(f"{item.describe()}: peak displacement "
                         f"{peak_u:.4g} m exceeds the stroke +/-{truth.stroke} m")
    if peak_v > truth.max_velocity * slack:
        raise ValueError(f"{item.describe()}: peak velocity "
                         f"{peak_v:.4g} m/s exceeds the limit {truth.max_velocity} m/s")
    peak_a = float(np.max(np.abs(command.a)))
    if item.is_broadband and peak_a > truth.max_acceleration * slack:
        raise ValueError(f"{item.describe()}: peak acceleration "
                         f"{peak_a:.4g} m/s^2 exceeds the limit {truth.max_acceleration} m/s^2")


# The reference campaign: sines from 0.25 to 3 Hz, each frequency at amplitudes spread up to
# the stroke (0.1 m) or the velocity limit (0.6 m/s), then four slow triangles whose constant
# velocity plateaus isolate friction and damping. 16 + 4 tests, about 204 s (40,800 samples
# at 200 Hz) with 6 steady cycles.
_SST_PAPER_SINES = (
    (0.25, (0.06,)),
    (0.5, (0.03, 0.08)),
    (0.75, (0.02, 0.05, 0.10)),
    (1.0, (0.01, 0.04, 0.08)),
    (1.5, (0.02, 0.05)),
    (2.0, (0.01, 0.03, 0.045)),
    (3.0, (0.01, 0.03)),
)
_SST_PAPER_TRIANGLES = ((0.5, 0.05), (0.5, 0.09), (1.0, 0.04), (1.5, 0.02))


def default_plan(preset: str = "sst-paper") -> list[PlanItem]:
    """The default campaign of a preset, in the order it is run."""
    if preset != "sst-paper":
        raise ValueError(f"no default plan for preset {preset!r}; known: ['sst-paper']")
    plan = [PlanItem("sine", f, a) for f, amplitudes in _SST_PAPER_SINES for a in amplitudes]
    plan += [PlanItem("triangle", f, a) for f, a in _SST_PAPER_TRIANGLES]
    return plan


def broadband_plan(payloads_kg: Iterable[float] = (0.0,), signals: Iterable[str] = ("noise",),
                   **fields: Any) -> list[PlanItem]:
    """Broadband tests, one per signal at each payload (payload-major order).

    fields: duration_s, peak_acceleration_m_s2, sample_rate_hz, applied to every test.
    """
    items = [{"kind": "broadband", "signal": signal, "payload_kg": float(payload), **fields}
             for payload in payloads_kg for signal in signals]
    return as_plan(items)
