"""Pre-sliding friction: samples still inside the friction's turn after a reversal left out.

The base model's friction Fmu*sign(v) flips at once at a velocity reversal. Real contacts
(bearings, seals, the struts' hinges) first deform elastically: after a reversal the friction
turns over a travel, the pre-sliding distance delta, not at an instant. Dahl's law, the
slow-motion limit of LuGre's bristles (sigma0 = Fmu/delta), gives from a reversal

    F = Fmu*(1 - 2*exp(-x/delta)),   x the travel since the reversal,

so the friction is within 4 % of its kinetic level only after x = 4*delta (PRESLIDING_TRAVELS).
A test of amplitude A is a travel x past its reversal at |v|/v_peak = sqrt(1 - (1 - x/A)^2),
about sqrt(2x/A): with delta = 100 um the friction reaches 80 % of its kinetic level only at
49 % of the peak speed of a 2 mm test, far outside the reversal band. The seventh independent
simulator (benchmarks/seventh_generator.py; LuGre bristles of 30-150 um) read Fmu 18 % low and
Me 2.5 % low with the reversal band alone (delta = 106 um; regenerated with 20, 40 and 70 um:
Fmu -0.4, -3.3, -10.7 %). Leaving out, besides the band, every sample within 4*delta of travel
after a reversal (a raised-cosine weight from 4 to 6 delta, applied before the low-pass like the
reversal weight) read it at Fmu -0.5 %, Me 0.0 %; at 160 um, 50 % over the truth, -0.3 % and
+0.1 %. Modelling the turn instead, with Dahl's shape in place of sign(v), was tried and is not
used: LuGre's bristle damping and Stribeck curve make the turn another shape, the column traded
with the damping term, and at the true delta Fmu came out -59 % and alpha -0.33.

`presliding_profile` reads delta from a series: each test is fitted by least squares with the
Dahl column for delta on a grid, and with a rival whose friction turns over a time instead of a
travel (the same law with |dx| replaced by dt: a lagging valve, a recorder's anti-alias filter or
the oil column ringing after each friction step act over a time, pre-sliding over a travel).
Delta is taken only where the Dahl column gains PRESLIDING_GAIN_NATS over sign(v), beats the
best time rival by PRESLIDING_RIVAL_NATS, and peaks between the grid's first travel and
PRESLIDING_MAX_M. Why the last: on the valve generator's clean series, which have no
pre-sliding but ring at the oil column after every friction step, the gain peaked at 320-640 um
(+42 to +195 nats, beating the time rival by 15-92), while the seventh simulator's pre-sliding
of 82-123 um peaked at 80-160 um; a contact's pre-sliding is microns to a hundred or so. The
profile only locates the turn; the shape's fit is not used for anything else.
"""

from __future__ import annotations

from typing import NamedTuple, Sequence

import numpy as np

from bayes_sst.signals._filters import raised_cosine_step

# the travels (m) and times (s) the profile reads
PRESLIDING_GRID_M = (10e-6, 20e-6, 40e-6, 80e-6, 160e-6, 320e-6, 640e-6)
# the longest travel taken: the grid goes on beyond it to see whether the gain keeps rising
PRESLIDING_MAX_M = 160e-6
# the travel after a reversal left out, in pre-sliding distances (the weight ramps up over half
# as much again)
PRESLIDING_TRAVELS = 4.0
TURNOVER_GRID_S = (0.002, 0.005, 0.01, 0.02, 0.04)
# measured 2026-12-01 (docs/measurements.md, pre-sliding): the seventh simulator's clean series
# with delta 82-123 um gained 145-358 nats at their best travel; series of the other simulators
# whose best travel lies in the accepted range gained at most 4 (sixth, seed 300: 6 at 60 um)
PRESLIDING_GAIN_NATS = 20.0
PRESLIDING_RIVAL_NATS = 10.0
# a series leans to a turn where its best gain at travels up to a floor is at least this: too
# weak to read the turn's length, enough to leave the floor's travel out (prepare_series,
# SignalOptions.presliding_floor; docs/measurements.md, 2026-12-01)
LEANING_GAIN_NATS = 2.0


def dahl_shape(velocity: np.ndarray, sample_rate_hz: float, presliding_m: float) -> np.ndarray:
    """s = F/Fmu of Dahl's law driven by a velocity record (1-D, in time):

        s_(n+1) = d_n + (s_n - d_n)*exp(-|dx_n|/delta),   dx_n = v_n/fs,   d_n = sign(dx_n),

    exact for a velocity held over each sample; started at sign(v_0) (the first sample moving
    on its kinetic level). Within a run of one sign the travel since the run began, X, gives
    s = d + (s_start - d)*exp(-X/delta) in closed form; only the runs' starting values are
    carried from run to run. presliding_m <= 0 returns sign(v).
    """
    velocity = np.asarray(velocity, dtype=float)
    if presliding_m <= 0.0:
        return np.sign(velocity)
    if velocity.size == 0:
        return np.zeros(0)
    held, starts, run, since_start, run_travel = _run_travel(velocity, sample_rate_hz)
    run_direction = held[starts]
    start_value = np.empty(len(starts))
    value = run_direction[0] if run_direction[0] != 0.0 else 1.0
    for k, d in enumerate(run_direction):
        start_value[k] = value
        if d != 0.0:
            value = d + (value - d) * np.exp(-run_travel[k] / presliding_m)
    d = run_direction[run]
    return np.where(d != 0.0, d + (start_value[run] - d) * np.exp(-since_start / presliding_m), start_value[run])


def turnover_shape(velocity: np.ndarray, sample_rate_hz: float, time_s: float) -> np.ndarray:
    """The rival: friction that turns over a time, s = d + (s_start - d)*exp(-t/tau) from the
    start of each run of one sign (dahl_shape with a unit speed while moving)."""
    return dahl_shape(np.sign(velocity), sample_rate_hz, time_s)


class PreslidingProfile(NamedTuple):
    """The profile of a series: its gain over sign(v) (nats, summed over tests) at each travel
    of PRESLIDING_GRID_M and each time of TURNOVER_GRID_S, and the travel taken (0: none)."""

    travel_gain: tuple[float, ...]
    time_gain: tuple[float, ...]
    presliding_m: float

    def leans_to_turn(self, up_to_m: float) -> bool:
        """Whether Dahl's column gains at least LEANING_GAIN_NATS over sign(v) at some travel
        of the grid no longer than up_to_m."""
        gains = [g for x, g in zip(PRESLIDING_GRID_M, self.travel_gain) if x <= up_to_m * (1 + 1e-9)]
        return bool(gains) and max(gains) >= LEANING_GAIN_NATS

    def peaks_within(self, up_to_m: float) -> bool:
        """Whether the best gain at travels up to PRESLIDING_MAX_M lies beyond the grid's first
        travel and no further than up_to_m: a turn that short. Not a profile still rising past
        up_to_m (a lag over a time, a derived acceleration's smoothing), which a floor of
        up_to_m would not cover; nor one at its best on the first travel, which reads no length
        (presliding_profile takes no turn there either) and is what any misfit near the
        reversals looks like: the fifth simulator's 8.08 Hz specimen (seed 214) peaks there."""
        travels = [(x, g) for x, g in zip(PRESLIDING_GRID_M, self.travel_gain) if x <= PRESLIDING_MAX_M * (1 + 1e-9)]
        if not travels:
            return False
        best_travel = max(travels, key=lambda item: item[1])[0]
        return PRESLIDING_GRID_M[0] < best_travel <= up_to_m * (1 + 1e-9)


def _test_log_likelihoods(test, shapes: Sequence) -> np.ndarray:
    """Per shape of friction (functions of the velocity record), the test's Gaussian log
    likelihood at its least-squares fit, n/2*log(RSS/n) with the sign flipped: the force
    F - m_payload*a on a, u, two damping columns (|v|^0.5, |v| times sign v, which span the
    power laws the fit's alpha ranges over well enough for a friction shape) and the shape."""
    keep = test.keep
    y = (test.F - test.payload_kg * test.a)[keep]
    damping = test.regressor(lambda v: np.stack([np.sqrt(np.abs(v)) * np.sign(v), v]))[:, keep]
    base = np.column_stack([test.a[keep], test.u[keep], damping.T])
    out = np.empty(len(shapes))
    n = int(keep.sum())
    for i, shape in enumerate(shapes):
        X = np.column_stack([base, test.friction_load * test.regressor(shape)[keep]])
        coef, *_ = np.linalg.lstsq(X, y, rcond=None)
        rss = float(np.sum((y - X @ coef) ** 2))
        out[i] = -0.5 * n * np.log(max(rss, 1e-300) / n)
    return out


def presliding_profile(tests: Sequence) -> PreslidingProfile:
    """Read the pre-sliding travel of a series of prepared tests (module docstring)."""
    total = None
    for test in tests:
        fs = test.sample_rate_hz
        shapes = ([np.sign] + [lambda v, d=d: dahl_shape(v, fs, d) for d in PRESLIDING_GRID_M]
                  + [lambda v, tau=tau: turnover_shape(v, fs, tau) for tau in TURNOVER_GRID_S])
        values = _test_log_likelihoods(test, shapes)
        total = values if total is None else total + values
    gains = total[1:] - total[0]
    travel = gains[: len(PRESLIDING_GRID_M)]
    time = gains[len(PRESLIDING_GRID_M):]
    best = int(np.argmax(travel))
    taken = (0 < best and PRESLIDING_GRID_M[best] <= PRESLIDING_MAX_M and travel[best] >= PRESLIDING_GAIN_NATS
             and travel[best] >= np.max(time) + PRESLIDING_RIVAL_NATS)
    return PreslidingProfile(tuple(float(g) for g in travel), tuple(float(g) for g in time),
                             float(PRESLIDING_GRID_M[best]) if taken else 0.0)


def _runs(velocity: np.ndarray):
    """(held, new_run, run): the direction of each sample, a sample at exactly zero velocity
    (which moves nothing) joining the run before it; where a run of one direction begins; the
    run of each sample."""
    held = np.sign(velocity)
    # each zero takes the direction of the last moving sample before it (0 before the first)
    last_moving = np.maximum.accumulate(np.where(held != 0.0, np.arange(held.size), 0))
    held = np.where(held != 0.0, held, held[last_moving])
    new_run = np.r_[True, held[1:] != held[:-1]]
    return held, new_run, np.cumsum(new_run) - 1


def travel_since_reversal(velocity: np.ndarray, sample_rate_hz: float) -> np.ndarray:
    """x(t): the travel (m) since the velocity last changed sign, sum of |v|/fs over the run of
    one sign (see _runs)."""
    velocity = np.asarray(velocity, dtype=float)
    if velocity.size == 0:
        return np.zeros(0)
    return _run_travel(velocity, sample_rate_hz)[3]


def _run_travel(velocity: np.ndarray, sample_rate_hz: float):
    """(held, starts, run, since_start, run_travel): _runs' directions and run of each sample,
    the index where each run begins, the travel (m) from its run's start to the start of each
    sample, and each run's whole travel."""
    held, new_run, run = _runs(velocity)
    starts = np.flatnonzero(new_run)
    travel = np.cumsum(np.abs(velocity) / sample_rate_hz)
    before = np.r_[0.0, travel[:-1]]  # travel at the start of each sample
    return held, starts, run, before - before[starts][run], np.diff(np.r_[before[starts], travel[-1]])


def presliding_weight(travel: np.ndarray, presliding_m: float, amplitude_m: float) -> tuple[np.ndarray, float]:
    """(w, x0): a weight 0 until the travel since the reversal (travel_since_reversal) reaches
    x0 = PRESLIDING_TRAVELS*delta (at most the amplitude, so that every stroke keeps its second
    half), rising as a raised cosine to 1 at 1.5*x0; and x0."""
    x0 = min(PRESLIDING_TRAVELS * presliding_m, amplitude_m)
    return raised_cosine_step((travel - x0) / (0.5 * x0)), x0
