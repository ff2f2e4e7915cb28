"""Filtering, differentiation, steady cycles and prepare_test against known truth.

Reference values: the Butterworth magnitude |H(f)|^2 = 1/(1 + (f/fc)^(2N)) (N = 4, squared
again by the forward-backward pass), the analytic derivative of a sine (and the exact
response of a central difference to it), and synthetic tests built here from a raised-cosine
ramped sine and the force model F = Me*a + Ke*u + (Ce*|v|^alpha + Fmu)*sign(v) written out in
numpy with known parameters.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from scipy import signal as sp_signal

from bayes_sst.io import Series, SeriesFormatError, TestRecord, TestSpec
from bayes_sst.signals import (
    CycleWindow,
    MIN_STEADY_CYCLES,
    SignalOptions,
    acceleration_from_velocity,
    friction_load,
    fundamental_phase,
    kept_indices,
    lowpass_sos,
    periodic_component,
    prepare_series,
    prepare_test,
    project_out,
    steady_cycles,
    reversal_weight,
    second_derivative,
    time_derivative,
    zero_phase_lowpass,
)

# --------------------------------------------------------------------------- filters


def _middle(x, share=0.5):
    n = len(x)
    k = int(n * (1 - share) / 2)
    return slice(k, n - k)


def test_zero_phase_lowpass_keeps_phase_and_amplitude_below_cutoff():
    fs, fc, f = 2000.0, 10.0, 1.0
    t = np.arange(int(20 * fs)) / fs
    x = 0.7 * np.sin(2 * np.pi * f * t + 0.3)
    y = zero_phase_lowpass(x, fc, fs)
    mid = _middle(x)
    xm, ym = x[mid], y[mid]

    # cross-correlation over lags within half a period: the peak must sit at lag 0
    half = int(fs / f / 2) - 1

    def peak_lag(y_mid):
        corr = sp_signal.correlate(y_mid, xm, mode="full", method="fft")
        lags = sp_signal.correlation_lags(len(y_mid), len(xm), mode="full")
        near = np.abs(lags) <= half
        return int(lags[near][np.argmax(corr[near])])

    assert peak_lag(ym) == 0
    # the same estimator does see the lag of a causal Butterworth-4 (group delay ~ 50 ms)
    causal = sp_signal.sosfilt(lowpass_sos(fc, fs), x)[mid]
    assert peak_lag(causal) > 0.02 * fs

    # amplitude: |H|^2 at f/fc = 0.1 is 1/(1 + 0.1^8), i.e. 1 to 1e-8
    amp_in, ph_in = fundamental_phase(xm, t[mid], f)
    amp_out, ph_out = fundamental_phase(ym, t[mid], f)
    assert amp_out == pytest.approx(amp_in, rel=1e-3)
    assert amp_out == pytest.approx(0.7, rel=1e-3)
    assert ph_out == pytest.approx(ph_in, abs=1e-4)


def test_zero_phase_lowpass_attenuation_at_three_times_cutoff():
    # fs >> fc so the bilinear transform's frequency warping (tan(pi f/fs) against pi f/fs)
    # changes (f/fc)^8 by only ~0.5 %: the analog forward-backward factor applies.
    fs, fc = 2000.0, 10.0
    f = 3.0 * fc
    t = np.arange(int(10 * fs)) / fs
    x = np.sin(2 * np.pi * f * t)
    y = zero_phase_lowpass(x, fc, fs)
    mid = _middle(x)
    amp, _ = fundamental_phase(y[mid], t[mid], f)
    expected = 1.0 / (1.0 + 3.0**8)  # |H|^2 of a 4th-order Butterworth at 3 fc = 1/6562
    assert amp == pytest.approx(expected, rel=0.05)


def test_zero_phase_lowpass_filters_along_axis():
    fs, fc = 500.0, 5.0
    t = np.arange(2000) / fs
    rows = np.stack([np.sin(2 * np.pi * 1.0 * t), np.sin(2 * np.pi * 40.0 * t)])
    along_last = zero_phase_lowpass(rows, fc, fs)
    along_first = zero_phase_lowpass(rows.T, fc, fs, axis=0)
    np.testing.assert_allclose(along_first.T, along_last, atol=1e-12)
    np.testing.assert_allclose(along_last[0], zero_phase_lowpass(rows[0], fc, fs), atol=1e-12)
    # 40 Hz at fc = 5 Hz: 1/(1 + 8^8) ~ 6e-8 of the input in the middle
    assert np.max(np.abs(along_last[1][500:1500])) < 1e-6


def test_zero_phase_lowpass_is_scipys_forward_backward_filter():
    # the steady-state start is cached per design; the result must be scipy's sosfiltfilt
    # (odd extension, default pad) to rounding, along any axis
    from scipy import signal as sp_signal

    from bayes_sst.signals._filters import lowpass_sos

    rng = np.random.default_rng(3)
    for shape, axis in (((700,), -1), ((3, 400), -1), ((400, 3), 0), ((2, 300, 4), 1)):
        x = rng.normal(size=shape).cumsum(axis=axis) + 5.0
        expected = sp_signal.sosfiltfilt(lowpass_sos(7.0, 200.0), x, axis=axis)
        np.testing.assert_allclose(zero_phase_lowpass(x, 7.0, 200.0, axis=axis), expected, rtol=0, atol=1e-12 * np.abs(expected).max())


@pytest.mark.parametrize("cutoff", [500.0, 600.0])
def test_lowpass_sos_rejects_cutoff_at_or_above_nyquist(cutoff):
    with pytest.raises(ValueError, match=rf"{cutoff:g} Hz.*Nyquist frequency 500 Hz"):
        lowpass_sos(cutoff, 1000.0)


@pytest.mark.parametrize("cutoff", [0.0, -3.0])
def test_lowpass_sos_rejects_non_positive_cutoff(cutoff):
    with pytest.raises(ValueError, match="Nyquist"):
        lowpass_sos(cutoff, 1000.0)


def test_lowpass_sos_just_below_nyquist_is_accepted():
    sos = lowpass_sos(499.0, 1000.0)
    assert sos.shape == (2, 6)  # order 4 = two second-order sections


# --------------------------------------------------------------------------- derivative


def test_time_derivative_of_sine():
    fs, f = 250.0, 2.3
    omega = 2 * np.pi * f
    h = 1.0 / fs
    t = 0.123 + np.arange(1000) * h
    x = np.sin(omega * t)
    d = time_derivative(x, fs)
    exact = omega * np.cos(omega * t)
    # Interior: a central difference of sin gives cos(w t)*sin(w h)/h exactly.
    np.testing.assert_allclose(d[1:-1], (np.cos(omega * t) * np.sin(omega * h) / h)[1:-1], atol=1e-9)
    # ... which is the analytic derivative to (w h)^2/6 = 5.5e-4 relative
    bound = (omega * h) ** 2 / 6 * omega
    assert np.max(np.abs(d[1:-1] - exact[1:-1])) <= 1.01 * bound
    assert np.max(np.abs(d[1:-1] - exact[1:-1])) > 0.5 * bound  # not a trivially exact result
    # Ends: one-sided first-order differences, error up to w^2 h/2
    assert np.all(np.abs(d[[0, -1]] - exact[[0, -1]]) <= omega**2 * h / 2 * 1.01)
    # along an axis of a 2-D array
    d2 = time_derivative(np.stack([x, 2 * x], axis=1), fs, axis=0)
    np.testing.assert_allclose(d2[:, 1], 2 * d, atol=1e-12)


def test_second_derivative_of_sine_is_fourth_order_accurate():
    fs, f = 200.0, 6.0
    omega, h = 2 * np.pi * f, 1.0 / fs
    t = 0.0371 + np.arange(400) * h
    x = np.sin(omega * t)
    d2 = second_derivative(x, fs)
    exact = -(omega**2) * x
    # the five-point stencil scales a sine by (32 cos wh - 2 cos 2wh - 30)/(-12 (wh)^2) exactly
    w = omega * h
    gain = (32 * np.cos(w) - 2 * np.cos(2 * w) - 30) / (-12 * w**2)
    np.testing.assert_allclose(d2[2:-2], gain * exact[2:-2], atol=1e-9 * omega**2)
    assert abs(gain - 1) < 1e-4  # against 1.2 % for two second-order first derivatives
    np.testing.assert_allclose(d2[2:-2], exact[2:-2], atol=1e-4 * omega**2)
    two_gradients = np.gradient(np.gradient(x, h), h)
    assert np.max(np.abs(two_gradients[2:-2] - exact[2:-2])) > 0.01 * omega**2


@pytest.mark.parametrize("f, corrected_tolerance", [(3.0, 2e-4), (9.0, 3e-3), (12.0, 6e-3)])
def test_acceleration_from_velocity_removes_the_second_order_loss(f, corrected_tolerance):
    """u smoothed by a 2.5 ms Gaussian and differentiated twice by central differences scales a
    sine by the kernel's gain times (sin(w h)/(w h))^2: 3.4 % low at 9 Hz sampled at 200 Hz.
    The corrected estimate is within corrected_tolerance of -w^2*u."""
    from scipy.ndimage import gaussian_filter1d

    fs, s = 200.0, 0.0025
    omega, h = 2 * np.pi * f, 1.0 / fs
    t = np.arange(2000) * h
    u = 0.01 * np.sin(omega * t + 0.3)
    v = time_derivative(gaussian_filter1d(u, s * fs), fs)
    exact = -(omega**2) * u
    inner = _middle(u)
    peak = omega**2 * 0.01
    plain = np.max(np.abs(time_derivative(v, fs)[inner] - exact[inner])) / peak
    corrected = np.max(np.abs(acceleration_from_velocity(v, fs, s)[inner] - exact[inner])) / peak
    # the sampled kernel's gain at f, and the second difference over 2h
    impulse = np.zeros(41)
    impulse[20] = 1.0
    weights = gaussian_filter1d(impulse, s * fs)
    kernel_gain = np.sum(weights * np.cos(omega * h * (np.arange(41) - 20)))
    expected_loss = 1 - kernel_gain * (np.sin(omega * h) / (omega * h)) ** 2
    assert plain == pytest.approx(expected_loss, rel=0.02)
    assert corrected < corrected_tolerance < plain / 5


def test_reversal_weight_is_zero_in_the_band_and_one_beyond_the_taper():
    speed = np.linspace(-1.0, 1.0, 2001)
    options = SignalOptions(reversal_band=0.2, reversal_taper=0.1)
    w = reversal_weight(speed, 1.0, options)
    assert np.all(w[np.abs(speed) <= 0.2 - 1e-9] == 0.0)
    assert np.all(w[np.abs(speed) >= 0.3 + 1e-9] == 1.0)
    ramp = (np.abs(speed) > 0.2 + 1e-6) & (np.abs(speed) < 0.3 - 1e-6)
    assert np.all((w[ramp] > 0.0) & (w[ramp] < 1.0))
    # raised cosine: one half at the middle of the ramp, monotonic in |v|
    assert reversal_weight(np.array([0.25]), 1.0, options)[0] == pytest.approx(0.5)
    order = np.argsort(np.abs(speed))
    assert np.all(np.diff(w[order]) >= 0.0)
    # switched off, or no band: all ones
    assert np.all(reversal_weight(speed, 1.0, SignalOptions(reversal_window=False)) == 1.0)
    assert np.all(reversal_weight(speed, 1.0, SignalOptions(reversal_band=0.0)) == 1.0)


@pytest.mark.parametrize("peak, edge", [(1.0, 0.1), (0.05, 0.2), (0.015, 0.5), (0.004, 0.5)])
def test_the_reversal_band_reaches_the_speed_floor_up_to_half_the_peak(peak, edge):
    """10 % of the peak speed, but at least 10 mm/s, and never more than half the peak: a
    1 m/s test keeps its 10 %, a 50 mm/s test loses up to 10 mm/s (20 %), a 15 or 4 mm/s one
    its slower half."""
    from bayes_sst.signals._prepare import reversal_band_share

    options = SignalOptions(reversal_band=0.1, reversal_speed=0.01, reversal_taper=0.1)
    assert reversal_band_share(peak, options) == pytest.approx(edge)
    speed = np.linspace(-peak, peak, 4001)
    w = reversal_weight(speed, peak, options)
    assert np.all(w[np.abs(speed) <= (edge - 1e-6) * peak] == 0.0)
    assert np.all(w[np.abs(speed) >= (edge + 0.1 + 1e-6) * peak] == 1.0)
    assert reversal_weight(np.array([(edge + 0.05) * peak]), peak, options)[0] == pytest.approx(0.5)
    assert reversal_band_share(peak, replace(options, reversal_speed=0.0)) == pytest.approx(0.1)


# --------------------------------------------------------------------------- cycles


@pytest.mark.parametrize(
    "amplitude, f, phi, offset",
    [(0.3, 1.7, 0.9, 0.05), (2.0e-3, 0.45, -2.5, -1.0e-3), (5.0, 3.0, 3.1, 0.0)],
)
def test_fundamental_phase_recovers_amplitude_and_phase(amplitude, f, phi, offset):
    rng = np.random.default_rng(1)
    fs = 200.0
    # a non-integer number of cycles, starting at an arbitrary time
    t = rng.uniform(0, 3) + np.arange(int(4.37 * fs / f)) / fs
    x = amplitude * np.sin(2 * np.pi * f * t + phi) + offset
    a, p = fundamental_phase(x, t, f)
    assert a == pytest.approx(amplitude, rel=1e-9)
    # phase compared on the circle
    assert np.angle(np.exp(1j * (p - phi))) == pytest.approx(0.0, abs=1e-9)


def _envelope(t, f, n_in, n_steady, n_out):
    """Raised-cosine ramp-in over n_in cycles, n_steady cycles at 1, ramp-out over n_out cycles.
    Also returns w' and w''."""
    period = 1.0 / f
    t_in, t_out = n_in * period, (n_in + n_steady) * period
    t_end = t_out + n_out * period
    w, dw, ddw = np.ones_like(t), np.zeros_like(t), np.zeros_like(t)
    if n_in:
        m = t < t_in
        k = np.pi / t_in
        w[m] = 0.5 * (1 - np.cos(k * t[m]))
        dw[m] = 0.5 * k * np.sin(k * t[m])
        ddw[m] = 0.5 * k**2 * np.cos(k * t[m])
    if n_out:
        m = t > t_out
        k = np.pi / (n_out * period)
        w[m] = 0.5 * (1 + np.cos(k * (t[m] - t_out)))
        dw[m] = -0.5 * k * np.sin(k * (t[m] - t_out))
        ddw[m] = -0.5 * k**2 * np.cos(k * (t[m] - t_out))
    outside = (t < 0) | (t > t_end)
    w[outside] = dw[outside] = ddw[outside] = 0.0
    return w, dw, ddw


def _ramped_sine(f, amplitude, fs, n_in, n_steady, n_out, offset):
    """u = A*w(t)*sin(2 pi f t) with its exact velocity and acceleration; t = (k + offset)/fs."""
    n = int(np.floor((n_in + n_steady + n_out) / f * fs))
    t = (np.arange(n) + offset) / fs
    w, dw, ddw = _envelope(t, f, n_in, n_steady, n_out)
    om = 2 * np.pi * f
    s, c = np.sin(om * t), np.cos(om * t)
    u = amplitude * w * s
    v = amplitude * (dw * s + om * w * c)
    a = amplitude * (ddw * s + 2 * om * dw * c - om**2 * w * s)
    return t, u, v, a


def test_steady_cycles_on_ramped_sine():
    fs, f, amp = 1000.0, 1.3, 0.03
    tol = 0.025
    t, u, _, _ = _ramped_sine(f, amp, fs, 2, 7, 2, offset=0.37)
    window = steady_cycles(u, t, f, tolerance=tol)
    period = fs / f
    # Why exactly 7: the cycles run from up-crossing to up-crossing at t = k/f, so the 7
    # steady cycles are whole and have amplitude A (to 1 - cos(pi/769) ~ 1e-5). Their
    # neighbours are ramp cycles: the one before the plateau has its positive lobe in the
    # half-cycle where w <= w(1.5/f) = 0.5*(1 - cos(0.75 pi)) = 0.854, so its half
    # peak-to-peak is at most (0.854 + 1)/2 = 0.927 A, outside 2.5 % (same for the ramp-out
    # by symmetry). No steady cycle touches the record's ends, so none is partial.
    assert window is not None
    assert window.n_cycles == 7
    assert window.period_samples == pytest.approx(period, rel=1e-9)
    assert window.amplitude == pytest.approx(amp, rel=1e-4)
    # the plateau starts at t = 2/f, i.e. sample 2*fs/f - offset
    assert abs(window.start - (2 * period - 0.37)) <= 1.0
    assert abs(window.stop - (9 * period - 0.37)) <= 1.0
    for m in range(window.n_cycles):
        b = window.start + m * period
        first, half, last = int(np.ceil(b)), int(np.floor(b + period / 2)), int(np.floor(b + period))
        # u crosses zero going up at the start: positive over the first half, negative over
        # the second (one sample of slack at each end for the rounding of b)
        assert np.all(u[first + 1 : half - 1] > 0)
        assert np.all(u[half + 2 : last - 1] < 0)
        assert abs(u[int(round(b))]) <= amp * 2 * np.pi / period  # within a sample of 0
        cyc_amp = 0.5 * np.ptp(u[int(round(b)) : int(round(b + period))])
        assert abs(cyc_amp - window.amplitude) <= tol * window.amplitude
    # skip_cycles drops settling cycles from the start of the run
    skipped = steady_cycles(u, t, f, tolerance=tol, skip_cycles=2)
    assert skipped.n_cycles == 5
    assert skipped.start == pytest.approx(window.start + 2 * period, abs=1.0)
    assert skipped.stop == window.stop


def test_steady_cycles_leave_out_the_records_edge_cycles_of_a_test_without_ramps():
    fs, f, amp = 500.0, 1.3, 0.03
    period = fs / f
    t, u, _, _ = _ramped_sine(f, amp, fs, 0, 6, 0, offset=0.37)
    kept_all = steady_cycles(u, t, f)
    assert kept_all.n_cycles in (5, 6)  # the last cycle may lack its final sample
    first_edge = kept_all.start < period
    window = steady_cycles(u, t, f, keep_at_least=3)
    assert first_edge and window.start == pytest.approx(kept_all.start + period, abs=1.0)
    assert window.n_cycles == kept_all.n_cycles - 2
    assert window.stop == pytest.approx(kept_all.stop - period, abs=1.0)
    # never below keep_at_least: four cycles lose only the first
    t, u, _, _ = _ramped_sine(f, amp, fs, 0, 5, 0, offset=0.37)
    four = steady_cycles(u, t, f)
    assert steady_cycles(u, t, f, keep_at_least=four.n_cycles - 1).n_cycles == four.n_cycles - 1
    assert steady_cycles(u, t, f, keep_at_least=four.n_cycles).n_cycles == four.n_cycles
    # a run inside ramps keeps every cycle
    t, u, _, _ = _ramped_sine(f, amp, fs, 2, 7, 2, offset=0.37)
    assert steady_cycles(u, t, f, keep_at_least=3) == steady_cycles(u, t, f)


def _square_wave_window(period, n_cycles, start=37):
    t = np.arange(start + int(np.ceil((n_cycles + 1) * period)))
    clean = np.sign(np.sin(2 * np.pi * (t + 0.3) / period)) + 0.3 * np.sin(6 * np.pi * t / period)
    window = CycleWindow(start=start, stop=start + int(round(n_cycles * period)), n_cycles=n_cycles,
                         period_samples=period, amplitude=1.0)
    return clean, window


@pytest.mark.parametrize(
    "period, n_cycles, kept_share",
    [
        (100.0, 8, 1 / 8),  # whole period: every cycle averaged
        (800 / 3, 6, 1 / 2),  # 0.75 Hz at 200 Hz: cycles three apart, pairs of 6
        (200 / 1.3, 8, 1.0),  # no whole multiple in 8 cycles: nothing to average
    ],
)
def test_periodic_component_averages_the_cycles_a_whole_number_of_samples_apart(period, n_cycles, kept_share):
    clean, window = _square_wave_window(period, n_cycles)
    inside = slice(window.start, window.stop)
    # a square wave (a step between samples, like a friction jump) repeats exactly: unchanged
    assert np.max(np.abs(periodic_component(clean, window) - clean[inside])) < 1e-12
    noise = np.random.default_rng(4).standard_normal((200, len(clean)))
    averaged = np.array([periodic_component(row, window) for row in noise])
    # the noise keeps the share of its variance 1/(number of cycles averaged)
    assert np.var(averaged) == pytest.approx(kept_share, rel=0.03)


def test_prepare_test_averages_the_measured_acceleration_over_the_steady_cycles():
    # 1.25 Hz at 1000 Hz: 800 samples per cycle. The accelerometer's white noise does not repeat
    # from cycle to cycle: the averaged, filtered regressor is closer to the filtered true a
    record, truth = _synthetic_test(0, 1.25, 0.03, seed=5)
    rng = np.random.default_rng(6)
    columns = dict(record.columns, a=truth["a"] + 0.03 * rng.standard_normal(len(truth["a"])))
    measured = TestRecord(record.spec, columns)
    options = SignalOptions(reversal_window=False)
    averaged = prepare_test(measured, options)
    raw = prepare_test(measured, replace(options, periodic_acceleration=False))
    exact = prepare_test(record, replace(options, periodic_acceleration=False))
    # noise-free: unchanged up to the steady window's last trace of the ramp (measured 1.5e-6)
    assert np.max(np.abs(prepare_test(record, options).a - exact.a)) < 1e-5 * np.max(np.abs(exact.a))
    # away from the window's ends, where the low-pass mixes in the raw a outside the window
    middle = _middle(exact.a)
    err_averaged = np.sqrt(np.mean((averaged.a - exact.a)[middle] ** 2))
    err_raw = np.sqrt(np.mean((raw.a - exact.a)[middle] ** 2))
    # 7 cycles averaged: the noise sd falls by sqrt(7), a ratio of 0.38 (measured 0.41)
    assert err_averaged < 0.5 * err_raw, (err_averaged, err_raw)


def test_prepare_test_leaves_a_unaveraged_when_the_motion_slips_against_the_test_frequency():
    # the manifest says 1.25 Hz, the table moved at 1.2505 Hz: over 7 cycles the fundamental
    # slips by 2.8 samples, and averaging would blur the motion
    record, truth = _synthetic_test(0, 1.2505, 0.03, seed=5)
    spec = replace(record.spec, frequency_hz=1.25)
    rng = np.random.default_rng(6)
    noisy = TestRecord(spec, dict(record.columns, a=truth["a"] + 0.03 * rng.standard_normal(len(truth["a"]))))
    options = SignalOptions(reversal_window=False)
    assert np.array_equal(prepare_test(noisy, options).a,
                          prepare_test(noisy, replace(options, periodic_acceleration=False)).a)


def test_steady_cycles_tolerance_decides_membership():
    # A looser tolerance (0.2) admits the two 0.83 A cycles next to the plateau (computed
    # half peak-to-peak of the 2nd ramp cycle: 0.832 A), but not the 0.19 A outer ones.
    fs, f, amp = 1000.0, 1.3, 0.03
    t, u, _, _ = _ramped_sine(f, amp, fs, 2, 7, 2, offset=0.37)
    assert steady_cycles(u, t, f, tolerance=0.2).n_cycles == 9


# --------------------------------------------------------------------------- prepare_test

TRUE = {"Me": 13200.0, "Ke": 7.2e5, "Ce": 2.0e4, "alpha": 0.5, "Fmu": 1.25e4}
FS = 1000.0
# (frequency, amplitude): three frequencies so that inertia and stiffness separate
# (at one frequency a steady sine has a = -w^2 u and Me, Ke are collinear).
PLAN = [(0.7, 0.05), (1.3, 0.03), (2.1, 0.015)]
N_IN, N_STEADY, N_OUT = 2, 7, 2


def _force_truth(u, v, a, p=TRUE):
    """The base force model, written out independently of bayes_sst.physics."""
    return p["Me"] * a + p["Ke"] * u + (p["Ce"] * np.abs(v) ** p["alpha"] + p["Fmu"]) * np.sign(v)


def _synthetic_test(index, f, amp, *, noise_u=0.0, noise_F=0.0, seed=0, n_steady=N_STEADY):
    rng = np.random.default_rng(seed)
    offset = rng.uniform(0.05, 0.95)  # sub-sample: no velocity zero falls on a sample
    t, u, v, a = _ramped_sine(f, amp, FS, N_IN, n_steady, N_OUT, offset)
    F = _force_truth(u, v, a)
    u_meas = u + noise_u * rng.standard_normal(u.shape)
    F_meas = F + noise_F * rng.standard_normal(F.shape)
    spec = TestSpec(id=f"S{index:02d}", file=f"S{index:02d}.csv", kind="sine", frequency_hz=f,
                    amplitude_m=amp, order=index)
    record = TestRecord(spec, {"t": t, "u": u_meas, "F": F_meas, "a": a})
    return record, {"t": t, "u": u, "v": v, "a": a, "offset": offset}


@pytest.fixture(scope="module")
def clean():
    return [_synthetic_test(i, f, amp, seed=10 + i) for i, (f, amp) in enumerate(PLAN)]


@pytest.fixture(scope="module")
def noisy():
    # 50 um on u (0.1-0.3 % of the amplitude), 100 N on F (~0.3 % of its amplitude)
    return [_synthetic_test(i, f, amp, noise_u=5e-5, noise_F=100.0, seed=20 + i)
            for i, (f, amp) in enumerate(PLAN)]


def test_prepare_test_trims_to_the_steady_window(clean):
    for record, truth in clean:
        f = record.spec.frequency_hz
        # the plain low-pass (the reversal weight and the free constant, which takes the kept
        # samples' mean out of u, are tested on their own below)
        prep = prepare_test(record, SignalOptions(reversal_window=False, free_constant=False))
        assert prep.window.n_cycles == N_STEADY
        assert prep.id == record.spec.id and prep.file == record.spec.file
        assert prep.cutoff_hz == pytest.approx(4.0 * f)
        # the plateau lies in [N_IN/f, (N_IN + N_STEADY)/f); allow a sample of rounding
        t_lo, t_hi = N_IN / f - 1.0 / FS, (N_IN + N_STEADY) / f
        assert prep.t[0] >= t_lo and prep.t[-1] < t_hi
        assert np.all((prep.index >= prep.window.start) & (prep.index < prep.window.stop))
        np.testing.assert_array_equal(prep.t, record.t[prep.index])
        # The kept signals are the truth, filtered: the 4 f cut-off passes the fundamental
        # (1 - 1.5e-5), but the kink where the ramp meets the plateau (a' jumps by A w^3/32,
        # the raised cosine's w'' = -0.5 (w/4)^2 A times u' = A w) is smoothed over ~1/(2 pi fc),
        # an error of about A w^3/32 / (4 w) = A w^2/128 ~ 0.8 % in a near the window's start.
        om, amp = 2 * np.pi * f, record.spec.amplitude_m
        np.testing.assert_allclose(prep.u, truth["u"][prep.index], rtol=0, atol=5e-4 * amp)
        # v comes from a 2.5 ms Gaussian kernel, which scales a sine by exp(-(w s)^2/2)
        gain = np.exp(-0.5 * (om * 0.0025) ** 2)
        np.testing.assert_allclose(prep.v, gain * truth["v"][prep.index], rtol=0, atol=1.5e-3 * om * amp)
        np.testing.assert_allclose(prep.a, truth["a"][prep.index], rtol=0, atol=1.2e-2 * om**2 * amp)


def test_prepare_test_decimates_to_two_samples_per_cutoff_period(clean):
    for record, _ in clean:
        f = record.spec.frequency_hz
        prep = prepare_test(record)
        staggered = prepare_test(record, SignalOptions(stagger_phases=True))
        # D = floor(fs / (2 * 4 f)), so samples per cycle fs/(f D) lie in [8, 8*(D+1)/D)
        per_cycle = FS / (f * prep.decimation)
        assert prep.decimation == int(FS / (2 * 4.0 * f))
        assert 8.0 <= per_cycle < 8.0 * (prep.decimation + 1) / prep.decimation
        assert per_cycle == pytest.approx(8.0, rel=0.02)
        assert np.all(np.diff(prep.index) == prep.decimation)
        assert len(prep.index) == pytest.approx(N_STEADY * per_cycle, abs=1.0)
        # the staggered grid (kept_indices) steps by D(1 + 1/N), rounded down to whole samples
        slipped = prep.decimation * (1 + 1 / len(prep.index))
        assert set(np.diff(staggered.index)) <= {int(slipped), int(slipped) + 1}
        assert len(staggered.index) in (len(prep.index), len(prep.index) - 1)
        # a different multiple changes it accordingly
        prep6 = prepare_test(record, SignalOptions(cutoff_multiple=6.0))
        assert FS / (f * prep6.decimation) == pytest.approx(12.0, rel=0.02)


def test_kept_samples_of_a_phase_locked_test_spread_over_new_phases_every_cycle():
    """fs = 1000 Hz, f = 1 Hz, fc = 4 Hz: D = 125 and the period is exactly 8 steps, so every
    cycle of the plain grid falls on the same 8 phases; the staggered grid slips by D/n per
    cycle, and its n = 5 cycles fill 40 distinct phases with no gap wider than 28 samples
    (the slip is spread over the steps, 3.125 samples each, so the gaps are 25 and, once a
    cycle, 28; the plain grid's are 125)."""
    period, step, n_cycles = 1000, 125, 5
    plain = kept_indices(300, 300 + n_cycles * period, step, stagger=False)
    staggered = kept_indices(300, 300 + n_cycles * period, step, stagger=True)
    assert len(plain) == 40 and len(np.unique((plain - 300) % period)) == 8
    assert len(staggered) == 40 and staggered[-1] < 300 + n_cycles * period
    phases = np.sort((staggered - 300) % period)
    gaps = np.diff(np.append(phases, phases[0] + period))
    assert len(np.unique(phases)) == 40 and gaps.max() == 28
    assert set(np.diff(staggered)) == {128, 129}
    # nothing to stagger with one sample or a step of one sample
    np.testing.assert_array_equal(kept_indices(7, 8, 125, stagger=True), [7])
    np.testing.assert_array_equal(kept_indices(0, 10, 1, stagger=True), np.arange(10))


@pytest.mark.parametrize("band", [0.2, 0.5])
def test_keep_excludes_exactly_the_reversal_band(clean, band):
    n_out, n_in, n_near = 0, 0, 0
    for record, truth in clean:
        f, amp = record.spec.frequency_hz, record.spec.amplitude_m
        prep = prepare_test(record, SignalOptions(reversal_band=band, samples_per_cutoff=4.0))
        # steady-state peak speed is A*w; the truth velocity at the kept samples
        threshold = band * amp * 2 * np.pi * f
        speed = np.abs(truth["v"][prep.index])
        # The package's peak speed (99.5th percentile of the filtered |v|) is A*w to ~1e-4 and
        # its filtered v is the truth to ~1e-3 A w, so only samples within 0.3 % of the
        # threshold can go either way.
        clear = np.abs(speed - threshold) > 0.003 * threshold
        n_near += int(np.sum(~clear))
        np.testing.assert_array_equal(prep.keep[clear], speed[clear] >= threshold)
        n_out += int(np.sum(~prep.keep))
        n_in += int(np.sum(prep.keep))
        assert prep.n_kept == int(prep.keep.sum())
    assert n_near <= 0.01 * (n_out + n_in)
    # share of a sine's phase with |cos| < band is (2/pi)*arcsin(band): 12.8 % and 33.3 %
    share = n_out / (n_out + n_in)
    assert share == pytest.approx(2 / np.pi * np.arcsin(band), abs=0.05)


def test_a_test_without_an_accelerometer_gets_the_wider_band(clean):
    """Defaults: 10 % of the peak speed with a measured a, 20 % without one (the derived a
    carries the rest's corner); None applies reversal_band to both."""
    record, _ = clean[0]
    without_a = TestRecord(record.spec, {k: v for k, v in record.columns.items() if k not in ("a", "v")})

    def left_out(rec, options=SignalOptions()):
        # many kept samples per cycle, so that the left-out share is not quantised
        prep = prepare_test(rec, replace(options, samples_per_cutoff=20.0))
        return 1.0 - prep.n_kept / len(prep.index)

    assert "a" in record.columns
    assert left_out(record) == pytest.approx(2 / np.pi * np.arcsin(0.1), abs=0.02)
    assert left_out(without_a) == pytest.approx(2 / np.pi * np.arcsin(0.2), abs=0.02)
    same = SignalOptions(reversal_band=0.1, reversal_band_without_accelerometer=None)
    assert left_out(without_a, same) == pytest.approx(2 / np.pi * np.arcsin(0.1), abs=0.02)
    assert SignalOptions().band_for(True).reversal_band == 0.1
    assert SignalOptions().band_for(False).reversal_band == 0.2


def test_filtered_velocity_has_two_reversals_per_cycle(noisy):
    for record, _ in noisy:
        prep = prepare_test(record)
        w = prep.window
        moving_up = prep.velocity_full[w.start : w.stop] > 0
        # a 2.5 ms kernel leaves sensor noise that may flip the sign a few times right at a
        # reversal; grouped within 5 % of a period, the flips are two reversals per cycle
        flips = np.flatnonzero(np.diff(moving_up))
        groups = 1 + np.count_nonzero(np.diff(flips) > 0.05 * FS / record.spec.frequency_hz)
        assert groups == 2 * w.n_cycles
        raw = np.gradient(record.u, 1.0 / FS)[w.start : w.stop] > 0
        assert np.count_nonzero(np.diff(raw)) > 10 * 2 * w.n_cycles
        # the friction regressor's sign follows those two reversals too
        assert np.count_nonzero(np.diff(prep.v > 0)) <= 2 * w.n_cycles


def _pooled_least_squares(prepared):
    rows, rhs = [], []
    for prep in prepared:
        damping = prep.regressor(lambda v: np.abs(v) ** TRUE["alpha"] * np.sign(v))
        design = np.column_stack([prep.a, prep.u, damping, prep.friction_sign])
        rows.append(design[prep.keep])
        rhs.append(prep.F[prep.keep])
    coef, *_ = np.linalg.lstsq(np.vstack(rows), np.concatenate(rhs), rcond=None)
    return dict(zip(("Me", "Ke", "Ce", "Fmu"), coef))


def test_pooled_least_squares_recovers_parameters_without_noise(clean):
    estimate = _pooled_least_squares([prepare_test(record) for record, _ in clean])
    for name, value in estimate.items():
        assert value == pytest.approx(TRUE[name], rel=0.01), name


def test_pooled_least_squares_with_noise_stays_close(noisy):
    # Not the acceptance criterion (that is the noise-free fit), only a guard that the
    # treatment does not bias a noisy fit grossly.
    estimate = _pooled_least_squares([prepare_test(record) for record, _ in noisy])
    for name, value in estimate.items():
        assert value == pytest.approx(TRUE[name], rel=0.02), name


def test_unfiltered_friction_regressor_would_bias_the_fit(clean):
    # The point of filtering the regressors like the force: using the raw sign(v) at the kept
    # samples instead of filter(sign(v)) misfits the smeared friction step. Guard that the
    # test above is sensitive to it.
    rows, rhs = [], []
    for record, _ in clean:
        prep = prepare_test(record)
        damping = prep.regressor(lambda v: np.abs(v) ** TRUE["alpha"] * np.sign(v))
        design = np.column_stack([prep.a, prep.u, damping, prep.without_constant(np.sign(prep.v))])
        rows.append(design[prep.keep])
        rhs.append(prep.F[prep.keep])
    coef, *_ = np.linalg.lstsq(np.vstack(rows), np.concatenate(rhs), rcond=None)
    errors = np.abs(coef / np.array([TRUE[k] for k in ("Me", "Ke", "Ce", "Fmu")]) - 1)
    assert errors.max() > 0.01


def _with_reversal_misfit(record, truth, band=0.15):
    """The record with friction the model does not have, only where |v| < band*peak: a
    holding force that ramps linearly across each reversal instead of the Coulomb step."""
    v = truth["v"]
    ramp = np.clip(v / (band * np.max(np.abs(v))), -1.0, 1.0)
    columns = dict(record.columns)
    columns["F"] = record.F + TRUE["Fmu"] * (ramp - np.sign(v))
    return TestRecord(record.spec, columns)


def test_reversal_weight_keeps_a_misfit_inside_the_band_out_of_the_fit(clean):
    # A force the base model lacks, confined to the reversals: weighted out before the
    # low-pass it leaves the fit exact; filtered plainly it leaks into the kept samples.
    corrupted = [_with_reversal_misfit(record, truth) for record, truth in clean]
    weighted = _pooled_least_squares([prepare_test(r) for r in corrupted])
    # measured: Ce +0.20 %, Fmu -0.13 %, Me and Ke exact (the misfit reaches 15 % of the peak
    # speed, half way up the weight's ramp)
    for name, value in weighted.items():
        assert value == pytest.approx(TRUE[name], rel=0.0025), name
    plain = _pooled_least_squares([prepare_test(r, SignalOptions(reversal_window=False)) for r in corrupted])
    # measured: Ce +6.7 %, Fmu -4.8 %
    assert plain["Ce"] / TRUE["Ce"] - 1 > 0.03 and plain["Fmu"] / TRUE["Fmu"] - 1 < -0.03


# --------------------------------------------------------------------------- errors


def _abrupt_sine(n_cycles, f=1.3, amp=0.03, file="short.csv"):
    """One period of rest, n_cycles of a sine switched on and off at up-crossings, one of rest.
    The rest cycles have amplitude 0 and no ramp cycle competes with the plateau, so the
    steady run is exactly the n_cycles of sine."""
    period = 1.0 / f
    n = int(np.floor((n_cycles + 2) * period * FS))
    t = (np.arange(n) + 0.37) / FS
    on = (t >= period) & (t < (n_cycles + 1) * period)
    u = np.where(on, amp * np.sin(2 * np.pi * f * (t - period)), 0.0)
    spec = TestSpec(id="short", file=file, kind="sine", frequency_hz=f, amplitude_m=amp)
    return TestRecord(spec, {"t": t, "u": u, "F": 7.2e5 * u})


def test_prepare_test_with_two_steady_cycles_raises():
    assert MIN_STEADY_CYCLES == 3
    with pytest.raises(SeriesFormatError) as info:
        prepare_test(_abrupt_sine(2))
    message = str(info.value)
    assert "short.csv" in message
    assert "only 2 steady cycle(s)" in message
    assert info.value.path == "short.csv"
    # the same construction with 3 cycles is accepted, with exactly 3
    assert prepare_test(_abrupt_sine(3)).window.n_cycles == 3


def test_prepare_series_names_the_file_and_rejects_broadband_only(tmp_path):
    record = _abrupt_sine(2, file="S07.csv")
    series = Series(name="lab", tests=(record,), path=Path(tmp_path))
    with pytest.raises(SeriesFormatError, match="only 2 steady cycle"):
        prepare_series(series)
    try:
        prepare_series(series)
    except SeriesFormatError as err:
        assert err.path == str(Path(tmp_path) / "S07.csv")
        assert str(Path(tmp_path) / "S07.csv") in str(err)

    t = np.arange(2000) / FS
    rng = np.random.default_rng(3)
    u = 1e-3 * rng.standard_normal(t.shape)
    broadband = TestRecord(TestSpec(id="bb", file="bb.csv", kind="broadband"), {"t": t, "u": u, "F": 1e5 * u})
    with pytest.raises(SeriesFormatError, match="no sine or triangle test"):
        prepare_series(Series(name="lab", tests=(broadband,)))
    with pytest.raises(SeriesFormatError, match="no sine or triangle test") as info:
        prepare_series(Series(name="lab", tests=(broadband, broadband), path=Path(tmp_path)))
    assert info.value.path == str(Path(tmp_path))


def test_prepare_series_prepares_only_periodic_tests(clean):
    t = np.arange(2000) / FS
    u = 1e-3 * np.sin(2 * np.pi * 3.0 * t)
    broadband = TestRecord(TestSpec(id="bb", file="bb.csv", kind="broadband"), {"t": t, "u": u, "F": 1e5 * u})
    records = tuple(r for r, _ in clean)
    prepared = prepare_series(Series(name="lab", tests=(records[0], broadband, records[1])))
    assert [p.id for p in prepared] == [records[0].spec.id, records[1].spec.id]


def test_without_an_accelerometer_the_weighted_acceleration_matches_the_measured_one():
    """Virtual-table tests without sensor noise (the deck rests at each reversal), prepared with
    and without their `a` column. The acceleration regressor is weighted at the recorded rate
    and then low-passed; built from the velocity it matches the accelerometer's (measured:
    0.74 % RMS of the kept samples for a 2 Hz, 10 mm sine, 3.9 % for a 1 Hz triangle, whose
    acceleration is nearly all reversal). The second derivative of the low-passed u, used
    before, differed by 2.7 % and 168 %: the reversal, smeared over 1/fc, leaked into the kept
    samples (on randomised series: Ce 8-12 % high, Fmu 5-10 % low)."""
    from bayes_sst.twin import default_plan, simulate

    plan = [item for item in default_plan("sst-paper")
            if (item.kind, item.frequency_hz, item.amplitude_m) in (("sine", 2.0, 0.01), ("triangle", 1.0, 0.04))]
    series = simulate("sst-paper", seed=3, plan=plan, noise="quiet")
    limits = {"sine": 0.015, "triangle": 0.08}
    assert sorted(r.spec.kind for r in series.periodic_tests) == ["sine", "triangle"]
    for record in series.periodic_tests:
        without = TestRecord(record.spec, {k: v for k, v in record.columns.items() if k not in ("a", "v")})
        # one band for both (the defaults give a test without `a` a wider one)
        same = SignalOptions(reversal_band=0.2, reversal_band_without_accelerometer=None)
        with_a, without_a = prepare_test(record, same), prepare_test(without, same)
        keep = with_a.keep
        relative = np.sqrt(np.mean((without_a.a - with_a.a)[keep] ** 2) / np.mean(with_a.a[keep] ** 2))
        assert relative < limits[record.spec.kind], (record.spec.kind, relative)


def _rounded_triangle_series(seed=0, fs=1000.0):
    """Three triangles (reversals turned over about 8 ms) and three sines, no `a` column: u with
    2 um and F with 30 N of white noise, base law with Coulomb friction; the motion is computed
    at 20 kHz and sampled at fs."""
    rng = np.random.default_rng(seed)
    truth = dict(Me=12000.0, Ke=7e5, Ce=3e4, alpha=0.6, Fmu=8000.0)
    fine_rate = 20000.0
    step = int(round(fine_rate / fs))
    records = []
    for k, (kind, f, amplitude) in enumerate([("triangle", 2.0, 0.004), ("triangle", 4.0, 0.0015), ("sine", 0.5, 0.02),
                                              ("sine", 2.0, 0.005), ("triangle", 1.0, 0.01), ("sine", 4.0, 0.002)]):
        period, om = 1.0 / f, 2 * np.pi * f
        t = np.arange(0.0, 10 * period, 1.0 / fine_rate)
        ramp = np.clip(t / (2 * period), 0.0, 1.0) * np.clip((10 * period - t) / (2 * period), 0.0, 1.0)
        shape = np.sin(om * t)
        if kind == "triangle":
            shape = np.cumsum(np.tanh(np.cos(om * t) / (0.008 * om)))
            shape = shape - 0.5 * (shape.max() + shape.min())
            shape = shape / np.abs(shape).max()
        u = amplitude * (0.5 - 0.5 * np.cos(np.pi * ramp)) * shape
        v = np.gradient(u, 1.0 / fine_rate)
        a = np.gradient(v, 1.0 / fine_rate)
        F = truth["Me"] * a + truth["Ke"] * u + (truth["Ce"] * np.abs(v) ** truth["alpha"] + truth["Fmu"]) * np.sign(v)
        t, u, F = t[::step], u[::step], F[::step]
        spec = TestSpec(id=f"R{k}", file=f"R{k}.csv", kind=kind, frequency_hz=f, amplitude_m=amplitude)
        records.append(TestRecord(spec, {"t": t, "u": u + rng.normal(0.0, 2e-6, t.size),
                                         "F": F + rng.normal(0.0, 30.0, t.size)}))
    return Series(name="rounded-triangles", tests=tuple(records)), truth


def _pooled_mass_and_stiffness(prepared, alpha):
    """Least squares over the kept samples of every test: Me and Ke shared, Ce and Fmu per test."""
    blocks, force = [], []
    for j, test in enumerate(prepared):
        keep = test.keep
        columns = np.zeros((int(keep.sum()), 2 + 2 * len(prepared)))
        columns[:, 0], columns[:, 1] = test.a[keep], test.u[keep]
        columns[:, 2 + 2 * j] = test.regressor(lambda v: np.abs(v) ** alpha * np.sign(v))[keep]
        columns[:, 3 + 2 * j] = test.regressor(np.sign)[keep]
        blocks.append(columns)
        force.append(test.F[keep])
    coefficients, *_ = np.linalg.lstsq(np.vstack(blocks), np.concatenate(force), rcond=None)
    return coefficients[0], coefficients[1]


@pytest.mark.parametrize("rate", [1000.0, 200.0])
def test_without_an_accelerometer_force_and_regressors_pass_the_acceleration_kernel(rate):
    """A derived acceleration is the true one smoothed by S, the 2.5 ms Gaussian kernel and the
    [1, 2, 1]/4 that two central differences add (signals._prepare.acceleration_kernel). At a
    triangle's reversal the acceleration is one short pulse, which S widens, and the reversal
    weight then cuts S(a) where the force's own pulse is narrower. Passing the force, u and the
    velocity regressors through S as well keeps filter(w*S(F)) = Me*filter(w*S(a)) + ... exact.
    Measured on this series, pooled Me at 1 kHz and 200 Hz: -0.02 % and +0.19 % with S on the
    force, -1.27 % and -3.33 % without; with the Gaussian alone (no [1, 2, 1]/4) -0.10 % and
    -2.05 %."""
    series, truth = _rounded_triangle_series(fs=rate)
    errors = {}
    for on in (True, False):
        prepared = prepare_series(series, SignalOptions(presliding=0.0, kernel_on_force=on))
        assert all(test.kernel_s == (0.0025 if on else 0.0) for test in prepared)
        mass, stiffness = _pooled_mass_and_stiffness(prepared, truth["alpha"])
        errors[on] = (mass / truth["Me"] - 1.0, stiffness / truth["Ke"] - 1.0)
    assert abs(errors[True][0]) < 0.004 and abs(errors[True][1]) < 0.002, errors
    assert errors[False][0] < -0.01, errors
    # a test with its accelerometer is prepared as before: no kernel
    record = series.tests[0]
    dt = 1.0 / rate
    with_a = TestRecord(record.spec, dict(record.columns, a=np.gradient(np.gradient(record.columns["u"], dt), dt)))
    assert prepare_test(with_a, SignalOptions(presliding=0.0, check_accelerometer=False)).kernel_s == 0.0


def test_without_an_accelerometer_a_noisy_recorded_velocity_leaves_the_acceleration_to_u():
    """A recorded v is differentiated for the acceleration only where its noise in the analysis
    band is below that of u's derivative: a transducer with 2 mm/s of white noise (u with 50 um)
    is passed over, a noise-free one is used; and the prepared acceleration from the noisy one
    is as close to the truth as without any v."""
    from bayes_sst.signals._filters import time_derivative
    from bayes_sst.signals._prepare import _derived_acceleration, _velocity

    record, truth = _synthetic_test(1, 1.3, 0.03, noise_u=5e-5, noise_F=100.0, seed=8)
    rng = np.random.default_rng(5)
    without_a = {k: v for k, v in record.columns.items() if k != "a"}
    options, cutoff, fs = SignalOptions(), 4 * 1.3, record.sample_rate_hz
    u_only = TestRecord(record.spec, without_a)
    a_from_u = time_derivative(_velocity(u_only, cutoff, options), fs)
    for v, uses_v in ((truth["v"] + 2e-3 * rng.standard_normal(len(truth["v"])), False), (truth["v"], True)):
        with_v = TestRecord(record.spec, dict(without_a, v=v))
        v_f = _velocity(with_v, cutoff, options)
        a = _derived_acceleration(with_v, v_f, cutoff, options)
        assert np.array_equal(a, time_derivative(v_f, fs) if uses_v else a_from_u)
    true_a = prepare_test(record).a
    keep = prepare_test(u_only).keep
    errors = [np.sqrt(np.mean((prepare_test(r).a - true_a)[keep] ** 2)) for r in (
        u_only, TestRecord(record.spec, dict(without_a, v=truth["v"] + 2e-3 * rng.standard_normal(len(truth["v"])))))]
    assert errors[1] < 1.5 * errors[0], errors


def test_a_record_that_cannot_be_the_declared_test_is_refused():
    record, _ = _synthetic_test(1, 1.3, 0.03, noise_u=5e-5, noise_F=100.0, seed=8)
    assert prepare_test(record).notes == ()
    # another test's file: the motion is at 1.3 Hz, the manifest says 2.6
    wrong = TestRecord(replace(record.spec, frequency_hz=2.6), record.columns)
    with pytest.raises(SeriesFormatError, match=r"S01.csv: test 'S01': u's strongest motion above 0.65 Hz is at "
                                                r"1.3 Hz, but frequency_hz is 2.6 Hz"):
        prepare_test(wrong)
    # a displacement channel that does not move is said to, not given a frequency
    still = TestRecord(record.spec, dict(record.columns, u=np.full(len(record.u), 0.001)))
    with pytest.raises(SeriesFormatError, match=r"test 'S01': u does not move \(peak to peak 0 m\)"):
        prepare_test(still)
    # u in millimetres
    in_mm = TestRecord(record.spec, dict(record.columns, u=1000.0 * record.u))
    with pytest.raises(SeriesFormatError, match=r"steady amplitude of u is 30 m but amplitude_m is 0.03 m.*metres"):
        prepare_test(in_mm)
    # merely far off: a note
    far = TestRecord(replace(record.spec, amplitude_m=0.018), record.columns)
    assert any("1.67 times amplitude_m" in note for note in prepare_test(far).notes)


def test_a_clipped_force_channel_is_named():
    record, _ = _synthetic_test(1, 1.3, 0.03, noise_u=5e-5, noise_F=100.0, seed=8)
    level = 0.8 * record.F.max()
    clipped = TestRecord(record.spec, dict(record.columns, F=np.minimum(record.F, level)))
    notes = prepare_test(clipped).notes
    assert len(notes) == 1 and "column 'F' holds its largest value" in notes[0] and "clipped" in notes[0]


def test_prepare_test_removes_constant_sensor_offsets():
    """Offsets on F, u, a and v change nothing the likelihood sees (up to the means' own
    partial-sample error), and with remove_offsets=False they do."""
    record, truth = _synthetic_test(1, 1.3, 0.03, noise_u=5e-5, noise_F=100.0, seed=8)
    record = TestRecord(record.spec, dict(record.columns, v=truth["v"]))
    shifted = TestRecord(record.spec, {k: v + {"F": 3000.0, "u": 0.003, "a": 0.05, "v": 0.002}.get(k, 0.0)
                                       for k, v in record.columns.items()})
    # the offsets' removal alone, then with each test's free constant, which takes up what is
    # left of a constant in F, u and a (not of one in v, which is not a column)
    alone = SignalOptions(free_constant=False)
    for options in (alone, SignalOptions()):
        base, moved = prepare_test(record, options), prepare_test(shifted, options)
        for name, scale in (("F", 3000.0), ("u", 0.003), ("a", 0.05), ("v", 0.002)):
            assert np.max(np.abs(getattr(moved, name) - getattr(base, name))) < 1e-3 * scale, name
        assert np.array_equal(moved.keep, base.keep)
    base = prepare_test(record, alone)
    kept = prepare_test(shifted, SignalOptions(remove_offsets=False, free_constant=False))
    assert np.max(np.abs(kept.F - base.F)) > 0.5 * 3000.0
    # (v's offset would move the reversal band and weight, which v sets)
    shifted_Fua = TestRecord(record.spec, {k: v + {"F": 3000.0, "u": 0.003, "a": 0.05}.get(k, 0.0)
                                           for k, v in record.columns.items()})
    projected = prepare_test(shifted_Fua, SignalOptions(remove_offsets=False))
    reference = prepare_test(record, SignalOptions(remove_offsets=False))
    for name, scale in (("F", 3000.0), ("u", 0.003), ("a", 0.05)):
        assert np.max(np.abs(getattr(projected, name) - getattr(reference, name))) < 1e-3 * scale, name


def _lopsided_test(f, amp, second, seed):
    """u = A*w(t)*(sin(2 pi f t) + c*sin(4 pi f t)): its velocity is positive for less than half
    of each cycle (0.416 of it for c = 0.15), so mean(sign v) over whole cycles is -0.17, not 0."""
    rng = np.random.default_rng(seed)
    offset = rng.uniform(0.05, 0.95)
    t, u1, v1, a1 = _ramped_sine(f, amp, FS, N_IN, N_STEADY, N_OUT, offset)
    _, u2, v2, a2 = _ramped_sine(2 * f, second * amp, FS, 2 * N_IN, 2 * N_STEADY, 2 * N_OUT, offset)
    u, v, a = u1 + u2, v1 + v2, a1 + a2
    spec = TestSpec(id="L01", file="L01.csv", kind="sine", frequency_hz=f, amplitude_m=amp, order=1)
    return TestRecord(spec, {"t": t, "u": u, "F": _force_truth(u, v, a), "a": a, "v": v})


def test_project_out_removes_a_multiple_of_the_shape_fitted_on_the_kept_samples():
    rng = np.random.default_rng(2)
    shape = 1.0 + 0.3 * np.sin(np.linspace(0, 9, 200))
    keep = rng.uniform(size=200) > 0.3
    columns = rng.normal(size=(3, 200))
    moved = columns + np.array([[2.0], [-5.0], [0.0]]) * shape
    left = project_out(moved, shape, keep)
    # the same result whatever multiple of the shape was added, orthogonal to it where kept
    np.testing.assert_allclose(left, project_out(columns, shape, keep), atol=1e-12)
    np.testing.assert_allclose(left[:, keep] @ shape[keep], 0.0, atol=1e-10)
    # outside the kept samples the same multiple is removed
    coefficient = columns[0, keep] @ shape[keep] / (shape[keep] @ shape[keep])
    np.testing.assert_allclose(left[0], columns[0] - coefficient * shape, atol=1e-12)


def test_each_test_has_a_free_constant():
    """Removing the steady window's means from F, u and a is exact only when the dissipative
    force averages to zero there (mean(F) carries Fmu*mean(sign v)). With each test's constant
    projected out of the force and of every regressor (free_constant), least squares at the
    true alpha on a noise-free test whose cycle is not odd in v returns every coefficient;
    without it the force keeps a constant misfit of Fmu*0.17 (2 kN) and the coefficients move."""
    record = _lopsided_test(0.5, 0.04, 0.15, seed=3)
    window = prepare_test(record).window
    mean_sign = np.mean(np.sign(record.columns["v"][window.start:window.stop]))
    assert mean_sign == pytest.approx(-0.168, abs=0.01)
    truth = np.array([TRUE["Me"], TRUE["Ke"], TRUE["Ce"], TRUE["Fmu"]])

    def least_squares(options):
        prep = prepare_test(record, options)
        X = np.column_stack([prep.a, prep.u, prep.regressor(lambda v: np.abs(v) ** TRUE["alpha"] * np.sign(v)),
                             prep.friction_sign])[prep.keep]
        y = prep.F[prep.keep]
        return np.linalg.lstsq(X, y, rcond=None)[0], np.sqrt(np.mean((y - X @ truth) ** 2))

    # exact signals (the recorded v feeds the regressors): 0.13 N of misfit is left
    with_constant, misfit = least_squares(SignalOptions())
    np.testing.assert_allclose(with_constant / truth, 1.0, atol=1e-3)
    assert misfit < 5.0
    without, old_misfit = least_squares(SignalOptions(free_constant=False))
    assert old_misfit > 1000.0
    assert np.max(np.abs(without / truth - 1.0)) > 0.05
    # the accelerometer-noise draws are treated as a is: no part along the constant's shape
    prep = replace(prepare_test(record), acceleration_noise_sd=0.05)
    draws = prep.acceleration_noise(3)
    assert np.abs(draws[:, prep.keep] @ prep.constant_shape[prep.keep]).max() < 1e-9 * np.abs(draws).sum()


SST_TABLE = {"deck_mass_kg": 12000.0, "strut": {"p0_pa": 6.9e6, "area_m2": 0.0314, "h_m": 1.2}}


def test_friction_load_is_the_ratio_of_bearing_loads():
    # SST: F_hd = 4*6.9e6*0.0314 = 866,640 N, N_empty = F_hd + 12,000*9.80665 = 984,320 N;
    # 5 t more weighs 49,033 N: ratio 1.049814
    assert friction_load(SST_TABLE, 5000.0) == pytest.approx(1.0 + 5000.0 * 9.80665 / 984319.8, rel=1e-9)
    assert friction_load(SST_TABLE, 5000.0) == pytest.approx(1.049814, abs=1e-6)
    assert friction_load(SST_TABLE, 0.0) == 1.0
    # without F_hd the weights alone (the fit learns how much of the increase is real);
    # without the deck mass the ratio is unknown and left at 1
    assert friction_load({"deck_mass_kg": 12000.0}, 5000.0) == pytest.approx(17.0 / 12.0, rel=1e-12)
    assert friction_load({"strut": SST_TABLE["strut"]}, 5000.0) == 1.0
    assert friction_load({}, 5000.0) == 1.0


def test_payload_friction_is_scaled_to_the_empty_tables_coefficient():
    """Fmu = mu_e*(F_hd + (m_deck + payload)*g): tests with payloads 0, 4 and 8 t have 0, 4 and
    8 % more friction. prepare_series scales each test's Coulomb regressor by its load ratio,
    so pooled least squares on F - payload*a returns the empty table's Fmu."""
    payloads = (0.0, 4000.0, 8000.0)
    records = []
    for i, ((f, amp), payload) in enumerate(zip(PLAN, payloads)):
        rng = np.random.default_rng(40 + i)
        t, u, v, a = _ramped_sine(f, amp, FS, N_IN, N_STEADY, N_OUT, rng.uniform(0.05, 0.95))
        load = 1.0 + payload * 9.80665 / (4 * 6.9e6 * 0.0314 + 12000.0 * 9.80665)
        truth = dict(TRUE, Me=TRUE["Me"] + payload, Fmu=TRUE["Fmu"] * load)
        spec = TestSpec(id=f"P{i}", file=f"P{i}.csv", kind="sine", frequency_hz=f, amplitude_m=amp,
                        payload_kg=payload, order=i)
        records.append(TestRecord(spec, {"t": t, "u": u, "F": _force_truth(u, v, a, truth), "a": a}))
    series = Series(name="payloads", tests=tuple(records), table=SST_TABLE)
    prepared = prepare_series(series)
    assert [p.friction_load for p in prepared] == pytest.approx([1.0, 1.0398514, 1.0797028], abs=1e-6)

    def pooled(tests):
        shifted = [replace(p, F=p.F - p.payload_kg * p.a) for p in tests]
        return _pooled_least_squares(shifted)

    estimate = pooled(prepared)
    for name, value in estimate.items():
        assert value == pytest.approx(TRUE[name], rel=0.01), name
    # the same tests without the table's bearing loads: the extra friction lands in Fmu
    unscaled = pooled([replace(p, friction_load=1.0) for p in prepared])
    assert unscaled["Fmu"] / TRUE["Fmu"] - 1 > 0.02


def test_a_dead_or_reversed_accelerometer_is_ignored_with_a_note(clean):
    """A recorded a that disagrees with the displacement's second derivative (all zeros, the
    wrong sign, ten times too large) is replaced by the derived acceleration and the reason is
    kept in PreparedTest.notes; a working one (the synthetic truth) passes untouched."""
    from bayes_sst.signals._checks import accelerometer_disagreement

    record, truth = clean[1]
    good = prepare_test(record)
    assert good.acceleration_measured and good.notes == ()
    derived = prepare_test(TestRecord(record.spec, {k: v for k, v in record.columns.items() if k != "a"}))
    for bad_a in (np.zeros_like(truth["a"]), -truth["a"], 10.0 * truth["a"]):
        prep = prepare_test(TestRecord(record.spec, dict(record.columns, a=bad_a)), source="S01.csv")
        assert not prep.acceleration_measured
        assert len(prep.notes) == 1 and "S01.csv" in prep.notes[0] and "column 'a'" in prep.notes[0]
        np.testing.assert_allclose(prep.a, derived.a)
    fs = 1.0 / (record.t[1] - record.t[0])
    u_f = zero_phase_lowpass(record.u, good.cutoff_hz, fs)
    assert accelerometer_disagreement(truth["a"], u_f, good.cutoff_hz, fs, good.window) is None
    assert "RMS ratio 0 " in accelerometer_disagreement(np.zeros_like(truth["a"]), u_f, good.cutoff_hz, fs, good.window)


def test_a_working_but_noisy_accelerometer_on_a_slow_small_test_is_kept():
    """0.25 Hz, 2 mm: the acceleration's amplitude is 5 mm/s^2, under the accelerometer's
    in-band noise (0.2 m/s^2 white at the recorded rate); the check allows for that noise and
    keeps the channel, while the same channel reversed is still refused."""
    record, truth = _synthetic_test(0, 0.25, 0.002, seed=4)
    rng = np.random.default_rng(4)
    noisy_a = truth["a"] + 0.2 * rng.standard_normal(truth["a"].shape)
    kept = prepare_test(TestRecord(record.spec, dict(record.columns, a=noisy_a)))
    assert kept.acceleration_measured and kept.notes == ()
    refused = prepare_test(TestRecord(record.spec, dict(record.columns, a=-noisy_a)))
    assert not refused.acceleration_measured and len(refused.notes) == 1


def test_an_accelerometer_that_also_records_ringing_above_the_band_is_kept():
    """A deck ringing at 53 Hz (+-30 m/s^2, a servo loop limit-cycling) shows in the recorded a
    above the analysis band, where the check reads the accelerometer's noise: on a slow, small
    sine (0.3 Hz, 10 mm: 0.036 m/s^2 of acceleration) that reading alone puts the expected
    ratio near 2, yet the in-band RMS ratio is 1 and the correlation 0.999, so the channel is
    kept (a lower bound of e/1.5 refused it); the same channel at half its scale is still
    refused (ratio 0.5, under 1/ACCELERATION_RMS_FACTOR whatever the noise reading)."""
    from bayes_sst.signals._checks import accelerometer_disagreement

    record, truth = _synthetic_test(0, 0.3, 0.01, seed=7)
    rng = np.random.default_rng(7)
    ringing = 30.0 * np.sin(2 * np.pi * 53.0 * truth["t"] + 0.3)
    a = truth["a"] + ringing + 0.02 * rng.standard_normal(truth["t"].shape)
    prep = prepare_test(TestRecord(record.spec, dict(record.columns, a=a)))
    assert prep.acceleration_measured and prep.notes == ()
    fs = 1.0 / (record.t[1] - record.t[0])
    u_f = zero_phase_lowpass(record.u, prep.cutoff_hz, fs)
    assert accelerometer_disagreement(a, u_f, prep.cutoff_hz, fs, prep.window) is None
    problem = accelerometer_disagreement(0.5 * a, u_f, prep.cutoff_hz, fs, prep.window)
    assert problem is not None and "RMS ratio 0.5" in problem
    assert float(problem.split("allows ")[1].split(",")[0]) > 1.5  # the noise reading's expected ratio


def test_complementary_velocity_keeps_the_corner_of_a_breakaway():
    """A table at rest that breaks away at 3 m/s^2: a 10 ms Gaussian kernel reads the corner
    0.4*a*s = 12 mm/s too fast (G preserves lines, not corners); with the kernel's band
    replaced above by the integrated acceleration, the corner is back to within the
    trapezoid's half-sample step (a*dt/2 = 1.5 mm/s at 1 kHz), and an accelerometer offset
    (0.05 m/s^2, a line once integrated) changes nothing in the interior."""
    from scipy.ndimage import gaussian_filter1d

    from bayes_sst.signals import complementary_velocity

    fs, s, a0, t0 = 1000.0, 0.01, 3.0, 1.0
    t = np.arange(0, 2.0, 1 / fs)
    v_true = a0 * np.clip(t - t0, 0.0, None)
    v_kernel = gaussian_filter1d(v_true, s * fs)
    a = a0 * (t >= t0)
    corner = np.abs(t - t0) <= 0.03
    assert np.max(np.abs(v_kernel - v_true)[corner]) == pytest.approx(0.4 * a0 * s, rel=0.05)
    v = complementary_velocity(v_kernel, a, fs, s)
    assert np.max(np.abs(v - v_true)[corner]) < 0.75 * a0 / fs
    inner = (t > 0.2) & (t < 1.8)
    with_offset = complementary_velocity(v_kernel, a + 0.05, fs, s)
    np.testing.assert_allclose(with_offset[inner], v[inner], atol=1e-9)
