"""Displacement commands of periodic tests, with their analytic velocity and acceleration.

A test's command is u_cmd(t) = A*e(t)*y(phi), phi = 2*pi*f*(t - t0), where y is the unit
waveform and e a raised-cosine envelope that ramps the amplitude in over `ramp_cycles`,
holds it for `n_cycles` steady cycles and ramps it out again; the table rests for `rest_s`
before and after. Velocity and acceleration follow by the product rule,

    v_cmd = A*(e'*y + e*y'*w),   a_cmd = A*(e''*y + 2*e'*y'*w + e*y''*w^2),   w = 2*pi*f,

so the servo loop's feed-forward and the recorded a_cmd are exact, not differenced.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

DEFAULT_RAMP_CYCLES = 1.0
DEFAULT_REST_S = 0.5
DEFAULT_CORNER_ROUNDING = 0.15


class Command(NamedTuple):
    """A command sampled at times t: displacement u (m), velocity v (m/s), acceleration a (m/s^2)."""

    t: np.ndarray
    u: np.ndarray
    v: np.ndarray
    a: np.ndarray


def raised_cosine_envelope(t, t_ramp: float, t_hold: float):
    """e(t) rising as 0.5*(1 - cos(pi*t/t_ramp)) on [0, t_ramp], 1 for t_hold, falling back to 0.

    Returns e, de/dt, d2e/dt2. e and de/dt are continuous, so the command starts and ends
    at rest without a velocity step.
    """
    t = np.asarray(t, dtype=float)
    k = math.pi / t_ramp
    t_down = t_ramp + t_hold
    rising = (t >= 0.0) & (t < t_ramp)
    holding = (t >= t_ramp) & (t <= t_down)
    falling = (t > t_down) & (t <= t_down + t_ramp)
    tr = np.where(rising, t, 0.0)
    tf = np.where(falling, t - t_down, 0.0)
    e = np.where(rising, 0.5 * (1.0 - np.cos(k * tr)), 0.0)
    e = np.where(holding, 1.0, e)
    e = np.where(falling, 0.5 * (1.0 + np.cos(k * tf)), e)
    de = np.where(rising, 0.5 * k * np.sin(k * tr), 0.0)
    de = np.where(falling, -0.5 * k * np.sin(k * tf), de)
    d2e = np.where(rising, 0.5 * k * k * np.cos(k * tr), 0.0)
    d2e = np.where(falling, -0.5 * k * k * np.cos(k * tf), d2e)
    return e, de, d2e


def sine_wave(phi):
    """y = sin(phi) and its first two derivatives in phi."""
    s = np.sin(phi)
    return s, np.cos(phi), -s


def rounded_triangle_wave(phi, rounding: float = DEFAULT_CORNER_ROUNDING):
    """y = arcsin(k*sin(phi))/arcsin(k), k = sqrt(1 - rounding^2), and its derivatives in phi.

    A unit triangle wave (same phase as sin) whose corners are rounded over roughly
    `rounding` radians of phase, so that the commanded acceleration stays finite: its peak
    is k/(rounding*arcsin(k)) times A*w^2 (4.6 for rounding = 0.15). The straight flanks run
    at k/arcsin(k) (0.70 for 0.15) times A*w instead of 2/pi.
    """
    if not 0.0 < rounding < 1.0:
        raise ValueError(f"corner rounding must lie in (0, 1), got {rounding!r}")
    k = math.sqrt(1.0 - rounding**2)
    scale = 1.0 / math.asin(k)
    s, c = np.sin(phi), np.cos(phi)
    root = np.sqrt(1.0 - (k * s) ** 2)
    y = scale * np.arcsin(k * s)
    dy = scale * k * c / root
    d2y = -scale * k * (1.0 - k * k) * s / root**3
    return y, dy, d2y


def periodic_command(
    kind: str,
    frequency_hz: float,
    amplitude_m: float,
    t,
    *,
    n_cycles: int,
    ramp_cycles: float = DEFAULT_RAMP_CYCLES,
    rest_s: float = DEFAULT_REST_S,
    corner_rounding: float = DEFAULT_CORNER_ROUNDING,
) -> Command:
    """The command of a `sine` or `triangle` test, evaluated at times t (s); zero outside the test."""
    if frequency_hz <= 0.0 or amplitude_m < 0.0:
        raise ValueError(f"need frequency_hz > 0 and amplitude_m >= 0, got {frequency_hz!r}, {amplitude_m!r}")
    t = np.asarray(t, dtype=float)
    period = 1.0 / frequency_hz
    w = 2.0 * math.pi * frequency_hz
    local = t - rest_s
    e, de, d2e = raised_cosine_envelope(local, ramp_cycles * period, n_cycles * period)
    if kind == "sine":
        y, dy, d2y = sine_wave(w * local)
    elif kind == "triangle":
        y, dy, d2y = rounded_triangle_wave(w * local, corner_rounding)
    else:
        raise ValueError(f"no periodic command for kind {kind!r}; use 'sine' or 'triangle'")
    u = amplitude_m * e * y
    v = amplitude_m * (de * y + e * dy * w)
    a = amplitude_m * (d2e * y + 2.0 * de * dy * w + e * d2y * w * w)
    return Command(t, u, v, a)


def command_duration(frequency_hz: float, *, n_cycles: int, ramp_cycles: float = DEFAULT_RAMP_CYCLES,
                     rest_s: float = DEFAULT_REST_S) -> float:
    """Length of a periodic test's record: rest, ramp-in, n_cycles, ramp-out, rest, s."""
    return 2.0 * rest_s + (n_cycles + 2.0 * ramp_cycles) / frequency_hz
