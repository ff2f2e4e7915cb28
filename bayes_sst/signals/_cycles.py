"""Locating the whole steady-state cycles of a periodic test."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from bayes_sst.io._series import sample_rate_of


class CycleWindow(NamedTuple):
    """Whole steady cycles: samples [start, stop) hold n_cycles periods of the test frequency.

    Cycle m begins at start + m*period_samples, where the fundamental of u crosses zero
    going up, so u is positive over the first half of every cycle.
    """

    start: int
    stop: int
    n_cycles: int
    period_samples: float
    amplitude: float


def fourier_columns(phase, harmonics: int) -> np.ndarray:
    """(n, 2K+1) columns [1, cos(phi), sin(phi), ..., cos(K phi), sin(K phi)] at the fundamental's
    phase phi (radians, n samples)."""
    phase = np.asarray(phase, dtype=float)
    columns = [np.ones_like(phase)]
    for k in range(1, harmonics + 1):
        columns += [np.cos(k * phase), np.sin(k * phase)]
    return np.column_stack(columns)


def fundamental_phase(x, t, frequency_hz: float) -> tuple[float, float]:
    """Amplitude A and phase phi of the best fit x ~ A*sin(2*pi*f*t + phi) + offset."""
    omega = 2.0 * np.pi * frequency_hz
    design = np.column_stack([np.sin(omega * t), np.cos(omega * t), np.ones_like(t)])
    (s, c, _), *_ = np.linalg.lstsq(design, x, rcond=None)
    return float(np.hypot(s, c)), float(np.arctan2(c, s))


def steady_cycles(
    u_filtered,
    t,
    frequency_hz: float,
    *,
    tolerance: float = 0.025,
    skip_cycles: int = 0,
    keep_at_least: int | None = None,
) -> CycleWindow | None:
    """The longest run of whole cycles whose amplitude is within `tolerance` of the plateau.

    The plateau amplitude is the median half peak-to-peak of the cycles that reach at least
    90 % of the largest one, so ramp-in and ramp-out cycles (smaller) fall outside the run.
    Returns None when not a single steady cycle is found.

    keep_at_least: a run that begins with the record's first whole cycle (no ramp-in before it)
    loses that cycle, and one that ends with the record's last loses that one, as long as this
    many cycles remain. Why: a table started at full amplitude settles over its first cycle,
    and the zero-phase filter's edge transient lies there too; a series of ten tests without
    ramps kept them, and 744 of 2000 NUTS transitions hit the tree-depth limit (step size
    0.024, against 0.51 for the same tests with ramps).
    """
    u_filtered = np.asarray(u_filtered, dtype=float)
    t = np.asarray(t, dtype=float)
    fs = sample_rate_of(t)
    period = fs / frequency_hz
    if period < 2.0:
        return None  # a fundamental at or above half the sampling rate: no cycle is in the record
    _, phase = fundamental_phase(u_filtered, t, frequency_hz)
    # first upward crossing of sin(omega*t + phase) at or after t[0]; a crossing within half
    # a sample of t[0] counts as at t[0] (rounding must not push it a whole period late)
    omega = 2.0 * np.pi * frequency_hz
    first = ((-phase - omega * t[0]) % (2.0 * np.pi)) / omega * fs
    if first > period - 0.5:
        first -= period
    first = max(first, 0.0)
    starts = first + period * np.arange(int((len(t) - first) // period) + 1)
    starts = starts[starts + period <= len(t)]
    if len(starts) == 0:
        return None
    begin = np.rint(starts).astype(int)
    end = np.minimum(np.rint(starts + period).astype(int), len(t))
    amplitudes = np.array([0.5 * np.ptp(u_filtered[b:e]) for b, e in zip(begin, end)])
    # the plateau from the near-largest cycles only: ramp cycles stay well below 90 %
    large = amplitudes >= 0.9 * amplitudes.max()
    plateau = float(np.median(amplitudes[large]))
    steady = np.abs(amplitudes - plateau) <= tolerance * plateau
    best_start, best_len, run_start = 0, 0, None
    for i, ok in enumerate(np.append(steady, False)):
        if ok and run_start is None:
            run_start = i
        elif not ok and run_start is not None:
            if i - run_start > best_len:
                best_start, best_len = run_start, i - run_start
            run_start = None
    best_start += skip_cycles
    best_len -= skip_cycles
    if keep_at_least is not None:
        if best_start == 0 and best_len > keep_at_least:
            best_start, best_len = 1, best_len - 1
        if best_start + best_len == len(starts) and best_len > keep_at_least:
            best_len -= 1
    if best_len <= 0:
        return None
    first_sample = begin[best_start]
    last_sample = end[best_start + best_len - 1]
    return CycleWindow(int(first_sample), int(last_sample), int(best_len), float(period), plateau)


# a cycle shift counts as whole when it is this close to a whole number of samples
WHOLE_SAMPLE_TOLERANCE = 1e-3


def periodic_component(x, window: CycleWindow) -> np.ndarray:
    """The cycle-synchronous average of x over the window's n whole cycles of T samples, read
    only where another cycle lies a whole number of samples away:

        x_p(t0 + o) = mean over m in M(o) of x(t0 + o + (m - c(o)) T),   c(o) = floor(o / T),
        M(o) = {m in 0..n-1 : (m - c(o)) T is a whole number of samples},

    so each sample is averaged with the samples at exactly the same phase, itself included.
    Why not read between samples: the friction jump at each reversal falls between two samples
    at a different fraction in every cycle, any interpolation smears it differently from the
    force's, and that put Ke 4 % off on a nearly noise-free twin series. When T is whole
    (200 Hz and 0.25, 0.5, 1, 2 Hz) every cycle counts; T = 800/3 samples (0.75 Hz) averages
    cycles three apart; T with no whole multiple in the window leaves x unchanged.
    What repeats every period passes unchanged; noise that does not repeat keeps 1/|M| of its
    variance. Returns x_p over [start, stop); x may carry leading axes (time last).
    """
    x = np.asarray(x, dtype=float)
    period = window.period_samples
    n = window.n_cycles
    offsets = np.arange(window.stop - window.start)
    cycle = np.minimum(np.floor(offsets / period).astype(int), n - 1)
    total = np.zeros(x.shape[:-1] + (len(offsets),))
    count = np.zeros(len(offsets))
    for lag in range(-(n - 1), n):
        shift = lag * period
        whole = int(round(shift))
        if abs(shift - whole) > WHOLE_SAMPLE_TOLERANCE:
            continue
        members = (cycle + lag >= 0) & (cycle + lag < n)
        position = np.clip(window.start + offsets + whole, 0, x.shape[-1] - 1)
        total[..., members] += x[..., position[members]]
        count[members] += 1.0
    return total / count
