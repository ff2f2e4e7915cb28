"""Symmetric instants: splitting one steady hysteresis loop into its dissipative and its
inertial-plus-elastic parts, the hand method of the reference study.

The split
---------
Take one steady cycle [0, T) of a periodic test whose origin t = 0 is where the
fundamental of the displacement crosses zero going up, and for t1 in (0, T/4) the four
instants

    t2 = T/2 - t1,   t3 = T/2 + t1,   t4 = T - t1.

Assumptions:

(A1) Steady periodic motion: every signal repeats with period T, so t4 = T - t1 is the
     same as -t1.
(A2) Half-wave symmetry of the displacement about the cycle origin,

         u(-t) = -u(t)         (odd about 0, hence about T/2 too),
         u(T/2 - t) = u(t)     (even about T/4, hence about 3T/4 too).

     Both hold for any waveform made of odd sine harmonics in phase with the fundamental,
     u = sum_{k odd} b_k sin(k*w*t): sin(k*(pi - w*t)) = sin(k*w*t) for odd k. The sine
     and the (rounded) triangle commands are of this kind.
(A3) The force splits as F_A = G(u, a) + F_D(v), where the non-dissipative part is odd,
     G(-u, -a) = -G(u, a) (Me*a + Ke*u is, and so is a cubic strut term), and the
     dissipative part depends on the present velocity only and is odd,
     F_D(-v) = -F_D(v) ((Ce*|v|^alpha + Fmu)*sign(v) is).

Differentiating (A2): acceleration has the symmetries of u, velocity the opposite ones,

    v(-t) = v(t),   v(T/2 - t) = -v(t),   a(-t) = -a(t),   a(T/2 - t) = a(t).

So, writing u1 = u(t1), v1 = v(t1), a1 = a(t1):

    instant   u     v     a
    t1        u1    v1    a1
    t2        u1   -v1    a1
    t3       -u1   -v1   -a1
    t4       -u1    v1   -a1

and with (A3)

    [F_A(t1) + F_A(t4)]/2 = [G(u1, a1) + G(-u1, -a1)]/2 + F_D(v1)      = F_D(v(t1))
    [F_A(t2) + F_A(t3)]/2 = [G(u1, a1) + G(-u1, -a1)]/2 + F_D(-v1)     = F_D(v(t2))
    [F_A(t1) + F_A(t2)]/2 = G(u1, a1) + [F_D(v1) + F_D(-v1)]/2         = G(u(t1), a(t1))
    [F_A(t3) + F_A(t4)]/2 = G(-u1, -a1) + [F_D(-v1) + F_D(v1)]/2       = G(u(t3), a(t3))

The dissipative force is thus read off against velocity, and the inertial-plus-elastic
force against displacement and acceleration, without knowing any parameter. Pairing
instants of equal velocity (t1, t4) cancels everything even in (u, a); pairing instants of
equal (u, a) (t1, t2) cancels everything odd in v.

Filtering. A zero-phase (forward-backward) filter has an even impulse response, so it
commutes with time reversal about any instant and preserves (A2) and the parity of
F_D(v(t)) in time. The filtered force is Me*a_f + Ke*u_f + filter(F_D(v)) exactly (the
filter is linear), so the inertial-plus-elastic pair stays exact after filtering. What
the filter does change is the dissipative part: filter(F_D(v)) is not F_D(v_f) where F_D
moves fast, i.e. around velocity reversals, where the Coulomb step is smeared over about
1/f_c (at f_c = 4f, a quarter cycle). Loop.dissipative_regressor therefore lets a force
model be filtered and split exactly like the measured force before it is compared with F_D.
Instants slower than `reversal_band` times the cycle's peak speed are marked and left out
of the fits: static friction and sticking live there, and after a stick the motion is not
the mirror image of the motion before it, which (A2) needs.

What breaks the split: even harmonics or cosine (out-of-phase) harmonics in u, e.g. a
distorted servo response; a misplaced cycle origin (an error d mixes the parts at first
order in 2*pi*f*d, which is why the origin is fitted to sub-sample accuracy, from the
fundamental of u over the two periods around the cycle, harmonics fitted alongside);
forces with memory (stick-slip, hysteretic bearings); drift between cycles. Sampling
itself: a friction step is only placed to within the sample it falls in, so a sampled
Coulomb force is exactly symmetric only when the samples are (a leak of order
Fmu/(f_s*T) per pair otherwise, noise-like over a campaign).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from bayes_sst.io import SeriesFormatError, TestRecord

DEFAULT_POINTS = 64
DEFAULT_REVERSAL_BAND = 0.2
DEFAULT_STEADY_TOLERANCE = 0.025
DEFAULT_VELOCITY_CUTOFF_MULTIPLE = 20.0
# odd and even harmonics fitted together with the fundamental when locating the origin, so
# that a triangle's (or a distorted sine's) harmonics do not leak into its phase
ORIGIN_HARMONICS = 7


def symmetric_instants(period: float, n_points: int = DEFAULT_POINTS) -> np.ndarray:
    """Offsets t1 of a midpoint grid on (0, T/4), shape (n_points,); T/4 itself is excluded."""
    if n_points < 1:
        raise ValueError(f"n_points must be positive, got {n_points!r}")
    return (np.arange(n_points) + 0.5) / n_points * (0.25 * period)


def quadruple_times(t0: float, period: float, t1) -> np.ndarray:
    """Absolute times of t1, t2 = T/2 - t1, t3 = T/2 + t1, t4 = T - t1 after origin t0, shape (n, 4)."""
    t1 = np.asarray(t1, dtype=float)
    half = 0.5 * period
    return t0 + np.stack([t1, half - t1, half + t1, period - t1], axis=-1)


def split_force(F) -> tuple[np.ndarray, np.ndarray]:
    """Dissipative and inertial-plus-elastic forces from F at the four instants, F shape (n, 4).

    Returns (F_D, F_ie), each of shape (2n,): F_D holds F_D(v(t1)) = (F1 + F4)/2 for every t1,
    then F_D(v(t2)) = (F2 + F3)/2; F_ie holds G(u(t1), a(t1)) = (F1 + F2)/2, then
    G(u(t3), a(t3)) = (F3 + F4)/2.
    """
    F = np.asarray(F, dtype=float)
    return _pairs_D(F), _pairs_ie(F)


def _pairs_D(x: np.ndarray) -> np.ndarray:
    """Means over the dissipative pairs (t1, t4) then (t2, t3), from shape (n, 4) to (2n,)."""
    return 0.5 * np.concatenate([x[:, 0] + x[:, 3], x[:, 1] + x[:, 2]])


def _pairs_ie(x: np.ndarray) -> np.ndarray:
    """Means over the inertial-elastic pairs (t1, t2) then (t3, t4), from shape (n, 4) to (2n,)."""
    return 0.5 * np.concatenate([x[:, 0] + x[:, 1], x[:, 2] + x[:, 3]])


@dataclass(frozen=True, eq=False)
class Loop:
    """One steady cycle of a periodic test, split at symmetric instants.

    `times`, `u`, `v`, `a`, `F` hold the (treated) signals at the four instants, shape
    (n_points, 4), columns t1, t2, t3, t4. The split parts are pair means, 2*n_points values
    each: the dissipative part over the pairs (t1, t4) and (t2, t3) (`v_D`, `F_D`, and the
    residual u_D, a_D, which are zero for an ideal loop), the inertial-plus-elastic part over
    the pairs (t1, t2) and (t3, t4) (`u_ie`, `a_ie`, `F_ie`). Means rather than single
    members make the abscissae right for the linear terms when the loop is not quite ideal.

    keep_D and keep_ie mark pairs whose two instants are both outside the reversal band:
    near a reversal the deck may stick, so friction is not a function of velocity there, and
    the motion after a stick is not the mirror image of the motion before it.
    """

    id: str
    kind: str
    frequency_hz: float
    amplitude_m: float
    payload_kg: float
    cutoff_hz: float | None
    sample_rate_hz: float
    period: float
    t0: float
    t1: np.ndarray
    times: np.ndarray
    u: np.ndarray
    v: np.ndarray
    a: np.ndarray
    F: np.ndarray
    peak_speed: float
    reversal_band: float
    # recorded-rate velocity around the cycle (for regressors filtered like the force)
    segment_t: np.ndarray = field(repr=False)
    segment_v: np.ndarray = field(repr=False)

    @property
    def v_D(self) -> np.ndarray:
        return _pairs_D(self.v)

    @property
    def F_D(self) -> np.ndarray:
        return _pairs_D(self.F)

    @property
    def u_D(self) -> np.ndarray:
        return _pairs_D(self.u)

    @property
    def a_D(self) -> np.ndarray:
        return _pairs_D(self.a)

    @property
    def u_ie(self) -> np.ndarray:
        return _pairs_ie(self.u)

    @property
    def a_ie(self) -> np.ndarray:
        return _pairs_ie(self.a)

    @property
    def F_ie(self) -> np.ndarray:
        return _pairs_ie(self.F)

    @property
    def _slow(self) -> np.ndarray:
        return np.abs(self.v) < self.reversal_band * self.peak_speed

    @property
    def keep_D(self) -> np.ndarray:
        slow = self._slow
        return ~np.concatenate([slow[:, 0] | slow[:, 3], slow[:, 1] | slow[:, 2]])

    @property
    def keep_ie(self) -> np.ndarray:
        slow = self._slow
        return ~np.concatenate([slow[:, 0] | slow[:, 1], slow[:, 2] | slow[:, 3]])

    def dissipative_regressor(self, of_velocity: Callable[[np.ndarray], np.ndarray]) -> np.ndarray:
        """The dissipative pair means of filter(g(v)), g = of_velocity, like F_D.

        g is applied to the velocity at the recorded rate around the cycle, the result goes
        through the same zero-phase low-pass as the force (none when the loop is unfiltered)
        and is read at the instants. A force model linear in its coefficients, e.g.
        Fmu*sign(v) + Ce*|v|^alpha*sign(v), then predicts F_D exactly as the force was
        treated, smearing of the friction step by the filter included.
        """
        values = np.asarray(of_velocity(self.segment_v), dtype=float)
        if self.cutoff_hz is not None:
            from bayes_sst.signals import zero_phase_lowpass

            values = zero_phase_lowpass(values, self.cutoff_hz, self.sample_rate_hz)
        from scipy.interpolate import CubicSpline

        return _pairs_D(CubicSpline(self.segment_t, values)(self.times))

    @property
    def speed(self) -> np.ndarray:
        """|v| of the kept dissipative points."""
        return np.abs(self.v_D[self.keep_D])

    @property
    def dissipation(self) -> np.ndarray:
        """|F_D| of the kept dissipative points (the dissipative force acts along v)."""
        return np.abs(self.F_D[self.keep_D])


def _harmonic_origin(u, t, frequency_hz: float, near: float) -> float:
    """The upward zero crossing of u's fundamental nearest to `near`, to sub-sample accuracy.

    The fundamental comes from a least-squares fit of the first ORIGIN_HARMONICS harmonics
    (and an offset) over the samples given; u1 = s*sin(w t) + c*cos(w t) = R*sin(w t + phi)
    crosses zero going up where w t + phi = 2*pi*n.
    """
    from bayes_sst.signals import fourier_columns

    w = 2.0 * np.pi * frequency_hz
    (_, c, s, *_), *_ = np.linalg.lstsq(fourier_columns(w * t, ORIGIN_HARMONICS), u, rcond=None)
    phase = float(np.arctan2(c, s))
    n = np.round((w * near + phase) / (2.0 * np.pi))
    return float((2.0 * np.pi * n - phase) / w)


def decompose_test(
    record: TestRecord,
    *,
    cycle: int = -2,
    cutoff_multiple: float | None = 4.0,
    n_points: int = DEFAULT_POINTS,
    reversal_band: float = DEFAULT_REVERSAL_BAND,
    steady_tolerance: float = DEFAULT_STEADY_TOLERANCE,
    velocity_cutoff_multiple: float | None = DEFAULT_VELOCITY_CUTOFF_MULTIPLE,
    source: str = "",
) -> Loop:
    """Split one steady cycle of a periodic test at symmetric instants (module docstring).

    record : a sine or triangle test with t, u, F and optionally a.
    cycle : which steady cycle, Python-indexed over the run of steady cycles (-2: the
        second-to-last: settled, and clear of the ramp-out).
    cutoff_multiple : zero-phase Butterworth low-pass of u, F and a at this multiple of the
        test frequency (capped at 0.4 times the sampling rate); None skips filtering.
    n_points : number of t1 instants on (0, T/4).
    reversal_band : pairs with an instant slower than this share of the cycle's peak speed
        are marked keep_D = False (dissipative pairs) or keep_ie = False (inertial-elastic).
    velocity_cutoff_multiple : the recorded-rate velocity kept for dissipative regressors
        (Loop.dissipative_regressor) is the derivative of u low-passed at this multiple of
        the test frequency (capped at 0.4 times the sampling rate; None: u unfiltered). It
        is wider than the force's band on purpose: the true velocity, not its low-passed
        form, is what the friction and damping forces follow.

    Velocity at the instants is the time derivative of (the cubic spline through) the
    filtered u; acceleration the filtered measured a when recorded, else the second
    derivative. All signals are read at the instants by cubic-spline interpolation.
    """
    from scipy.interpolate import CubicSpline

    from bayes_sst.signals import accelerometer_disagreement, steady_cycles, zero_phase_lowpass

    spec = record.spec
    where = source or spec.file
    if not spec.is_periodic or not spec.frequency_hz:
        raise SeriesFormatError(where, f"test '{spec.id}'", "the loop method needs a sine or triangle test with a frequency")
    f = float(spec.frequency_hz)
    period = 1.0 / f
    fs = record.sample_rate_hz
    t = record.t
    top = 0.8 * 0.5 * fs
    cutoff = None if cutoff_multiple is None else min(float(cutoff_multiple) * f, top)

    def smooth(x, fc=cutoff):
        x = np.asarray(x, dtype=float)
        return x if fc is None else zero_phase_lowpass(x, fc, fs)

    u_f = smooth(record.u)
    F_f = smooth(record.F)
    measured_a = record.get("a")
    a_f = None if measured_a is None else smooth(measured_a)

    window = steady_cycles(u_f, t, f, tolerance=steady_tolerance)
    n_cycles = 0 if window is None else window.n_cycles
    if a_f is not None and window is not None and accelerometer_disagreement(
            measured_a, u_f, top if cutoff is None else cutoff, fs, window, a_low=None if cutoff is None else a_f):
        # a dead, reversed or mis-scaled accelerometer: u'' instead, as the fit does (its summary
        # names the test)
        a_f = None
    if not -n_cycles <= cycle < n_cycles:
        raise SeriesFormatError(
            where,
            f"test '{spec.id}'",
            f"steady cycle {cycle} asked for, but {n_cycles} steady cycle(s) of {f:g} Hz were found"
            + (f" (to analyse the other tests, leave this one out: --exclude-test {spec.id})" if n_cycles < 3 else ""),
        )
    m = cycle % n_cycles
    near = float(t[window.start]) + m * period
    # the origin from two periods centred on the cycle (inside the steady run): local, so a
    # filter's transient at the ends of a record or a slight frequency error cannot tilt it
    lo = max(window.start, int(np.searchsorted(t, near - 0.5 * period)))
    hi = min(window.stop, int(np.searchsorted(t, near + 1.5 * period)))
    if hi - lo < period * fs:
        lo, hi = window.start, window.stop
    t0 = _harmonic_origin(u_f[lo:hi], t[lo:hi], f, near=near)
    # a margin of samples on either side keeps the spline's end effects away from the cycle
    pad = 8
    i0 = max(0, int(np.floor((t0 - t[0]) * fs)) - pad)
    i1 = min(len(t), int(np.ceil((t0 + period - t[0]) * fs)) + pad + 1)
    if t[i0] > t0 or t[i1 - 1] < t0 + period:
        raise SeriesFormatError(where, f"test '{spec.id}'", f"steady cycle {cycle} runs off the end of the record")
    seg = slice(i0, i1)
    u_spline = CubicSpline(t[seg], u_f[seg])
    F_spline = CubicSpline(t[seg], F_f[seg])
    v_spline = u_spline.derivative(1)
    a_spline = u_spline.derivative(2) if a_f is None else CubicSpline(t[seg], a_f[seg])

    t1 = symmetric_instants(period, n_points)
    times = quadruple_times(t0, period, t1)
    cycle_times = np.linspace(t0, t0 + period, 8 * n_points + 1)
    peak_speed = float(np.max(np.abs(v_spline(cycle_times))))

    # recorded-rate velocity over the cycle and a margin of four force cut-off periods, so
    # that regressors filtered on this stretch alone match the force filtered on the record
    v_cut = None if velocity_cutoff_multiple is None else min(float(velocity_cutoff_multiple) * f, top)
    margin = pad + (0 if cutoff is None else int(np.ceil(4.0 * fs / cutoff)))
    j0 = max(0, i0 + pad - margin)
    j1 = min(len(t), i1 - pad + margin)
    velocity = CubicSpline(t, smooth(record.u, v_cut)).derivative(1)(t[j0:j1])
    return Loop(
        id=spec.id,
        kind=spec.kind,
        frequency_hz=f,
        amplitude_m=float(spec.amplitude_m) if spec.amplitude_m is not None else float("nan"),
        payload_kg=float(spec.payload_kg or 0.0),
        cutoff_hz=cutoff,
        sample_rate_hz=fs,
        period=period,
        t0=t0,
        t1=t1,
        times=times,
        u=u_spline(times),
        v=v_spline(times),
        a=a_spline(times),
        F=F_spline(times),
        peak_speed=peak_speed,
        reversal_band=float(reversal_band),
        segment_t=t[j0:j1].copy(),
        segment_v=velocity,
    )
