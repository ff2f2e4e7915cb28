"""Candidate tests for the design and the table limits they must respect.

A candidate is a periodic test (kind, frequency f, amplitude A). Its commanded motion is the
one the virtual table runs (bayes_sst.twin): a sine u = A sin(w t), or a rounded triangle
u = A asin(k sin(w t))/asin(k), k = sqrt(1 - r^2), with corner rounding r, w = 2 pi f.
Peaks of the steady motion:

    sine:      |u| = A,  |v| = A w,                    |a| = A w^2
    triangle:  |u| = A,  |v| = A w k/asin(k),          |a| = A w^2 k/(r asin(k))

and the actuator force F = Me a + Ke u + (Ce |v|^alpha + Fmu) sign(v), whose peak over a
cycle is found numerically on that waveform with the posterior mean coefficients.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterable, Mapping, NamedTuple

import numpy as np

PERIODIC_KINDS = ("sine", "triangle")
# the twin's corner rounding (bayes_sst.twin._command.DEFAULT_CORNER_ROUNDING); a lab whose
# triangles are rounded differently passes its own candidates
TRIANGLE_ROUNDING = 0.15
DEFAULT_FREQUENCIES_HZ = (0.25, 0.5, 0.75, 1.0, 1.5, 2.0, 2.5, 3.0, 4.0)
DEFAULT_AMPLITUDE_FRACTIONS = (0.2, 0.4, 0.6, 0.8, 1.0)


class Candidate(NamedTuple):
    """One test the lab could run next: kind ('sine' or 'triangle'), frequency (Hz), amplitude (m)."""

    kind: str
    frequency_hz: float
    amplitude_m: float

    def describe(self) -> str:
        return f"{self.kind} {self.frequency_hz:g} Hz x {self.amplitude_m * 1000:.3g} mm"

    def to_json(self) -> dict[str, Any]:
        return {"kind": self.kind, "frequency_hz": float(self.frequency_hz), "amplitude_m": float(self.amplitude_m)}


@dataclass(frozen=True)
class TableLimits:
    """The table's limits, SI; None where unknown (that limit is then not checked).

    stroke_m: half stroke (largest |u|); velocity_m_s, acceleration_m_s2: largest |v|, |a|;
    force_n: largest actuator force |F_A|.
    """

    stroke_m: float | None = None
    velocity_m_s: float | None = None
    acceleration_m_s2: float | None = None
    force_n: float | None = None

    def to_json(self) -> dict[str, float | None]:
        return {"stroke_m": self.stroke_m, "velocity_m_s": self.velocity_m_s,
                "acceleration_m_s2": self.acceleration_m_s2, "force_n": self.force_n}


_LIMIT_KEYS = {
    "stroke_m": ("stroke_m", "stroke"),
    "velocity_m_s": ("velocity_m_s", "max_velocity", "velocity"),
    "acceleration_m_s2": ("acceleration_m_s2", "max_acceleration", "acceleration"),
    "force_n": ("force_n", "max_force", "force"),
}
# the design command's option for each limit, for the message that refuses its value
LIMIT_OPTIONS = {"stroke_m": "--stroke", "velocity_m_s": "--max-velocity",
                 "acceleration_m_s2": "--max-acceleration", "force_n": "--max-force"}


def _positive_number(value, where: str) -> float | None:
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value <= 0:
        raise ValueError(f"{where}: must be a positive number of SI units, got {value!r}")
    return float(value)


def table_limits(table: Mapping[str, Any] | None, **overrides: float | None) -> TableLimits:
    """Limits from the series' `table` description (its `limits` object, as the virtual table
    writes it: stroke_m, velocity_m_s, acceleration_m_s2, force_n), replaced by any override
    that is not None (command-line options)."""
    limits = (table or {}).get("limits") or {}
    if not isinstance(limits, Mapping):
        raise ValueError(f"series table.limits: must be an object, got {type(limits).__name__}")
    values = {}
    for field, keys in _LIMIT_KEYS.items():
        found = next((limits[k] for k in keys if k in limits), None)
        values[field] = _positive_number(found, f"series table.limits.{field}")
        if overrides.get(field) is not None:
            values[field] = _positive_number(overrides[field], LIMIT_OPTIONS[field])
    return TableLimits(**values)


def waveform(kind: str, phase: np.ndarray, rounding: float = TRIANGLE_ROUNDING):
    """Unit waveform y(phase) and its first two phase-derivatives (see the module docstring)."""
    if kind == "sine":
        s = np.sin(phase)
        return s, np.cos(phase), -s
    if kind == "triangle":
        k = math.sqrt(1.0 - rounding**2)
        scale = 1.0 / math.asin(k)
        s, c = np.sin(phase), np.cos(phase)
        root = np.sqrt(1.0 - (k * s) ** 2)
        return scale * np.arcsin(k * s), scale * k * c / root, -scale * k * (1.0 - k * k) * s / root**3
    raise ValueError(f"candidate kind {kind!r}: the design proposes periodic tests, one of {PERIODIC_KINDS}")


def peak_motion(kind: str, frequency_hz: float, amplitude_m: float) -> tuple[float, float, float]:
    """Peaks (|u|, |v|, |a|) of the steady command (module docstring)."""
    w = 2.0 * math.pi * frequency_hz
    if kind == "sine":
        return amplitude_m, amplitude_m * w, amplitude_m * w * w
    k = math.sqrt(1.0 - TRIANGLE_ROUNDING**2)
    return (amplitude_m, amplitude_m * w * k / math.asin(k),
            amplitude_m * w * w * k / (TRIANGLE_ROUNDING * math.asin(k)))


def peak_force(kind: str, frequency_hz: float, amplitude_m: float, coefficients: Mapping[str, float]) -> float:
    """max |F_A| over a steady cycle with the given Me, Ke, Ce, alpha, Fmu (SI)."""
    phase = np.linspace(0.0, 2.0 * math.pi, 721)
    w = 2.0 * math.pi * frequency_hz
    y, dy, d2y = waveform(kind, phase)
    u, v, a = amplitude_m * y, amplitude_m * w * dy, amplitude_m * w * w * d2y
    force = (coefficients["Me"] * a + coefficients["Ke"] * u
             + (coefficients["Ce"] * np.abs(v) ** coefficients["alpha"] + coefficients["Fmu"]) * np.sign(v))
    return float(np.max(np.abs(force)))


def limit_violations(candidate: Candidate, limits: TableLimits, coefficients: Mapping[str, float]) -> list[str]:
    """What of `limits` the candidate exceeds, in words (empty when it fits)."""
    u, v, a = peak_motion(candidate.kind, candidate.frequency_hz, candidate.amplitude_m)
    slack = 1.0 + 1e-6  # a test written exactly at a limit is allowed
    out = []
    for value, limit, what, unit in ((u, limits.stroke_m, "displacement", "m"),
                                     (v, limits.velocity_m_s, "velocity", "m/s"),
                                     (a, limits.acceleration_m_s2, "acceleration", "m/s^2")):
        if limit is not None and value > limit * slack:
            out.append(f"peak {what} {value:.4g} {unit} > limit {limit:.4g} {unit}")
    if limits.force_n is not None:
        force = peak_force(candidate.kind, candidate.frequency_hz, candidate.amplitude_m, coefficients)
        if force > limits.force_n * slack:
            out.append(f"peak actuator force {force:.4g} N > limit {limits.force_n:.4g} N")
    return out


def max_amplitude(kind: str, frequency_hz: float, limits: TableLimits, coefficients: Mapping[str, float]) -> float:
    """Largest amplitude inside every limit at this kind and frequency (m); inf when unlimited."""
    u1, v1, a1 = peak_motion(kind, frequency_hz, 1.0)
    bounds = [math.inf]
    for per_metre, limit in ((u1, limits.stroke_m), (v1, limits.velocity_m_s), (a1, limits.acceleration_m_s2)):
        if limit is not None:
            bounds.append(limit / per_metre)
    amplitude = min(bounds)
    if limits.force_n is not None and math.isfinite(amplitude):
        # the force grows monotonically with amplitude: bisect on it
        if peak_force(kind, frequency_hz, amplitude, coefficients) > limits.force_n:
            lo, hi = 0.0, amplitude
            for _ in range(50):
                mid = 0.5 * (lo + hi)
                lo, hi = (mid, hi) if peak_force(kind, frequency_hz, mid, coefficients) <= limits.force_n else (lo, mid)
            amplitude = lo
    return amplitude


def candidate_grid(
    limits: TableLimits,
    coefficients: Mapping[str, float],
    *,
    kinds: Iterable[str] = PERIODIC_KINDS,
    frequencies_hz: Iterable[float] = DEFAULT_FREQUENCIES_HZ,
    amplitude_fractions: Iterable[float] = DEFAULT_AMPLITUDE_FRACTIONS,
) -> list[Candidate]:
    """Every kind x frequency x (fraction of the largest allowed amplitude there).

    Without a stroke limit the amplitudes are fractions of the velocity-, acceleration- or
    force-limited one; a grid needs at least one finite bound."""
    out = []
    for kind in kinds:
        waveform(kind, np.zeros(1))  # validates the kind
        for f in frequencies_hz:
            top = max_amplitude(kind, float(f), limits, coefficients)
            if not math.isfinite(top):
                raise ValueError(
                    "no table limits known (series table.limits is absent): give --stroke and "
                    "--max-velocity, or a --candidates file")
            for fraction in amplitude_fractions:
                # rounded down to the micrometre, so the largest stays inside the limit
                out.append(Candidate(kind, float(f), math.floor(float(fraction) * top * 1e6) / 1e6))
    return out


def read_candidates(path) -> list[Candidate]:
    """Candidates from a JSON file: a list of {kind, frequency_hz, amplitude_m}, or an object
    with such a list under "candidates"."""
    path = Path(path)
    try:
        data = json.loads(path.read_text())
    except OSError as exc:
        raise ValueError(f"{path}: cannot read the candidates file: {exc.strerror}") from None
    except json.JSONDecodeError as exc:
        raise ValueError(f"{path}: line {exc.lineno}, column {exc.colno}: not valid JSON: {exc.msg}") from None
    items = data.get("candidates") if isinstance(data, Mapping) else data
    if not isinstance(items, list) or not items:
        raise ValueError(f"{path}: expected a non-empty list of {{kind, frequency_hz, amplitude_m}} "
                         "(or an object with one under 'candidates')")
    out = []
    for i, item in enumerate(items):
        where = f"{path}: candidates[{i}]"
        if not isinstance(item, Mapping):
            raise ValueError(f"{where}: must be an object, got {type(item).__name__}")
        kind = item.get("kind")
        if kind not in PERIODIC_KINDS:
            raise ValueError(f"{where}.kind: {kind!r} is not one of {PERIODIC_KINDS}")
        f = _positive_number(item.get("frequency_hz"), f"{where}.frequency_hz")
        a = _positive_number(item.get("amplitude_m"), f"{where}.amplitude_m")
        if f is None or a is None:
            raise ValueError(f"{where}: needs frequency_hz and amplitude_m")
        out.append(Candidate(kind, f, a))
    return out
