"""Test plans: which periodic tests a simulated campaign runs, and the presets' default plans."""

from __future__ import annotations

import math
from typing import Any, Iterable, Mapping, NamedTuple

import numpy as np

from bayes_sst.twin._command import Command
from bayes_sst.twin._truth import TableTruth

PLAN_KINDS = ("sine", "triangle")


class PlanItem(NamedTuple):
    """One planned test: kind ('sine' or 'triangle'), frequency (Hz), amplitude (m), payload (kg).

    id is the test's name in the series; None lets simulate() number it (S01, T02, ...).
    """

    kind: str
    frequency_hz: float
    amplitude_m: float
    payload_kg: float = 0.0
    id: str | None = None


def _field(item: Any, name: str, default: Any = None) -> Any:
    if isinstance(item, Mapping):
        return item.get(name, default)
    return getattr(item, name, default)


def as_plan_item(item: Any) -> PlanItem:
    """A PlanItem from a dict, a PlanItem, a TestSpec or any object with the same attributes."""
    kind = _field(item, "kind")
    if kind not in PLAN_KINDS:
        raise ValueError(f"the twin simulates {PLAN_KINDS} tests, got kind {kind!r}")
    frequency = _field(item, "frequency_hz")
    amplitude = _field(item, "amplitude_m")
    if frequency is None or amplitude is None:
        raise ValueError(f"a {kind} test needs frequency_hz and amplitude_m, got {item!r}")
    frequency, amplitude = float(frequency), float(amplitude)
    payload = float(_field(item, "payload_kg", 0.0) or 0.0)
    if not (math.isfinite(frequency) and frequency > 0.0):
        raise ValueError(f"frequency_hz must be positive, got {frequency!r}")
    if not (math.isfinite(amplitude) and amplitude > 0.0):
        raise ValueError(f"amplitude_m must be positive, got {amplitude!r}")
    if not (math.isfinite(payload) and payload >= 0.0):
        raise ValueError(f"payload_kg must be non-negative, got {payload!r}")
    test_id = _field(item, "id")
    return PlanItem(kind, frequency, amplitude, payload, None if test_id is None else str(test_id))


def as_plan(plan: Iterable[Any]) -> list[PlanItem]:
    items = [as_plan_item(item) for item in plan]
    if not items:
        raise ValueError("the plan holds no tests")
    return items


def check_limits(item: PlanItem, command: Command, truth: TableTruth) -> None:
    """Refuse a command that leaves the table's stroke or exceeds its velocity limit."""
    # A whisker of slack so that a plan written at exactly the limit is accepted.
    slack = 1.0 + 1e-6
    peak_u = float(np.max(np.abs(command.u)))
    peak_v = float(np.max(np.abs(command.v)))
    if peak_u > truth.stroke * slack:
        raise ValueError(f"{item.kind} {item.frequency_hz} Hz x {item.amplitude_m} m: peak displacement "
                         f"{peak_u:.4g} m exceeds the stroke +/-{truth.stroke} m")
    if peak_v > truth.max_velocity * slack:
        raise ValueError(f"{item.kind} {item.frequency_hz} Hz x {item.amplitude_m} m: peak velocity "
                         f"{peak_v:.4g} m/s exceeds the limit {truth.max_velocity} m/s")


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
