"""Accelerometer noise: its level read off the record, its path through the signal treatment,
and the errors-in-variables correction of the likelihood's moments."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from bayes_sst.io import TestRecord, TestSpec
from bayes_sst.signals import SignalOptions, prepare_test, zero_phase_lowpass
from bayes_sst.signals._noise import white_noise_sd

FS = 200.0


def _sine_with_friction_steps(f, n_cycles, fs=FS, jump=1.9):
    """A deck acceleration: -omega^2 A sin(omega t) plus a friction step of `jump` m/s^2 at
    every reversal (the sign of the velocity flips), sampled at fs with a sub-sample offset."""
    t = (np.arange(int(n_cycles * fs / f)) + 0.37) / fs
    omega = 2 * np.pi * f
    amplitude = 0.3 / omega
    v = amplitude * omega * np.cos(omega * t)
    return t, -(omega**2) * amplitude * np.sin(omega * t) - 0.5 * jump * np.sign(v), v


@pytest.mark.parametrize("f", [0.3, 1.1, 2.9])
def test_white_noise_sd_reads_the_noise_and_not_the_motion(f):
    """As prepare_test uses it: on the record minus its low-pass at 4f, mid-stroke."""
    t, a, v = _sine_with_friction_steps(f, 8)
    sigma = 0.05
    mid_stroke = np.abs(v) >= 0.6 * np.abs(v).max()

    def estimate(x):
        return white_noise_sd(x - zero_phase_lowpass(x, 4 * f, FS), where=mid_stroke)

    readings = [estimate(a + sigma * np.random.default_rng(seed).standard_normal(len(a))) for seed in range(8)]
    # the median of about 300-3000 differences: a few % each, and no bias beyond 3 %
    assert np.mean(readings) == pytest.approx(sigma, rel=0.03)
    assert np.max(np.abs(np.asarray(readings) / sigma - 1)) < 0.15
    # the motion alone, friction steps included, reads as (nearly) no noise
    assert estimate(a) < 0.15 * sigma
    # without the low-pass the motion's own curvature shows at 2.9 Hz (69 samples a cycle):
    # up to (omega/fs)^2 of the peak acceleration, 0.017 m/s^2, in the differences
    if f > 2:
        assert white_noise_sd(a, where=mid_stroke) > 0.2 * sigma


@pytest.mark.parametrize("order", [2, 4])
def test_white_noise_sd_reads_white_noise_at_either_order(order):
    noise = 0.04 * np.random.default_rng(3).standard_normal(20000)
    assert white_noise_sd(noise, order=order) == pytest.approx(0.04, rel=0.03)
    every_third = np.arange(noise.size) % 3 == 0
    assert white_noise_sd(noise, where=every_third, order=order) == pytest.approx(0.04, rel=0.05)


def test_fourth_differences_leave_out_the_real_motion_above_the_band():
    """A 3 Hz test at 200 Hz whose deck also moves at 30 Hz (a servo loop's or an oil column's
    response, 0.06 m/s^2 peak: real motion, which the force carries as well) beside 0.03 m/s^2
    of white sensor noise. Above the 12 Hz band the second differences count the 30 Hz motion
    as noise (gain (2 sin(w/2))^2/sqrt(6) = 0.335 against the noise's 1: 0.03 reads about
    0.033), the fourth differences hardly (0.080: about 0.0302)."""
    f, sigma = 3.0, 0.03
    t, a, v = _sine_with_friction_steps(f, 12)
    motion = a + 0.06 * np.sin(2 * np.pi * 30.0 * t + 0.4)
    mid_stroke = np.abs(v) >= 0.6 * np.abs(v).max()
    readings = {2: [], 4: []}
    for seed in range(6):
        x = motion + sigma * np.random.default_rng(seed).standard_normal(len(t))
        for order in readings:
            readings[order].append(white_noise_sd(x - zero_phase_lowpass(x, 4 * f, FS), where=mid_stroke, order=order))
    second, fourth = np.mean(readings[2]), np.mean(readings[4])
    assert second > 1.06 * sigma
    assert fourth == pytest.approx(sigma, rel=0.03)
    assert abs(fourth - sigma) < 0.5 * abs(second - sigma)


def test_white_noise_sd_of_a_too_short_record_is_zero():
    assert white_noise_sd(np.ones(4)) == 0.0
    assert white_noise_sd(np.ones(4), order=4) == 0.0
    with pytest.raises(ValueError, match="order must be one of"):
        white_noise_sd(np.ones(40), order=3)


def _record(a, u, F, t, f, test_id="S01"):
    spec = TestSpec(id=test_id, file=f"{test_id}.csv", kind="sine", frequency_hz=f, amplitude_m=float(np.ptp(u) / 2))
    return TestRecord(spec, {"t": t, "u": u, "F": F, "a": a})


@pytest.mark.parametrize("f", [0.5, 1.37])  # a whole-sample period (cycle average applies) and not
def test_acceleration_noise_draws_carry_the_energy_the_noise_leaves_in_a(f):
    """PreparedTest.acceleration_noise against the noise itself: the same record prepared with
    and without white accelerometer noise differs in `a` by exactly that noise after the
    treatment (average, weight, low-pass, decimation), whose energy the draws must match."""
    n_cycles = 10
    t = np.arange(int((n_cycles + 2) / f * FS)) / FS
    envelope = np.clip(t * f, 0, 1) * np.clip((t[-1] - t) * f, 0, 1)
    omega = 2 * np.pi * f
    u = 0.02 * envelope * np.sin(omega * t)
    v = np.gradient(u, 1 / FS)
    a = np.gradient(v, 1 / FS)
    F = 13200 * a + 7.2e5 * u + 12500 * np.tanh(v / 1e-3)
    sigma = 0.08
    clean = prepare_test(_record(a, u, F, t, f), SignalOptions())
    energies = []
    for seed in range(12):
        noisy_a = a + sigma * np.random.default_rng(seed).standard_normal(len(a))
        noisy = prepare_test(_record(noisy_a, u, F, t, f), SignalOptions())
        energies.append(np.sum(((noisy.a - clean.a)[noisy.keep]) ** 2))
        assert noisy.acceleration_noise_sd == pytest.approx(sigma, rel=0.15)
    assert clean.acceleration_averaged == noisy.acceleration_averaged
    draws = replace(noisy, acceleration_noise_sd=sigma).acceleration_noise(48, seed=1)
    predicted = np.mean(np.sum(draws[:, noisy.keep] ** 2, axis=1))
    # 12 realisations of a sum over ~100-300 correlated samples: within 15 %
    assert np.mean(energies) == pytest.approx(predicted, rel=0.15)
    # and the cycle average, when it applies, does remove most of the noise
    if noisy.acceleration_averaged and abs(FS / f - round(FS / f)) < 1e-9:
        unaveraged = replace(noisy, acceleration_noise_sd=sigma, acceleration_averaged=False)
        assert predicted < 0.3 * np.mean(np.sum(unaveraged.acceleration_noise(48, seed=1)[:, noisy.keep] ** 2, axis=1))


def test_prepare_test_reads_the_accelerometer_noise_past_the_motion_above_the_band():
    """The fit's default reads the noise from fourth differences: a 3 Hz test at 200 Hz whose
    deck also moves at 30 Hz (0.06 m/s^2, in u, a and F alike) reads its 0.03 m/s^2 of white
    accelerometer noise within 4 %; second differences read it more than 6 % high."""
    f, sigma = 3.0, 0.03
    t = np.arange(int(16 / f * FS)) / FS
    envelope = np.clip(t * f, 0, 1) * np.clip((t[-1] - t) * f, 0, 1)
    omega, jitter = 2 * np.pi * f, 2 * np.pi * 30.0
    u = 0.02 * envelope * np.sin(omega * t) - 0.06 / jitter**2 * np.sin(jitter * t + 0.4)
    v = np.gradient(u, 1 / FS)
    a = -(omega**2) * 0.02 * envelope * np.sin(omega * t) + 0.06 * np.sin(jitter * t + 0.4)
    F = 13200 * a + 7.2e5 * u + 12500 * np.tanh(v / 1e-3)
    readings = {2: [], 4: []}
    for seed in range(6):
        record = _record(a + sigma * np.random.default_rng(seed).standard_normal(len(t)), u, F, t, f)
        for order in readings:
            readings[order].append(prepare_test(record, SignalOptions(noise_difference_order=order)).acceleration_noise_sd)
        assert prepare_test(record).acceleration_noise_sd == readings[4][-1]
    assert np.mean(readings[4]) == pytest.approx(sigma, rel=0.04)
    assert np.mean(readings[2]) > 1.06 * sigma


def test_no_measured_acceleration_means_no_noise_estimate():
    f = 1.0
    t = np.arange(int(10 / f * FS)) / FS
    u = 0.02 * np.clip(t * f, 0, 1) * np.clip((t[-1] - t) * f, 0, 1) * np.sin(2 * np.pi * f * t)
    spec = TestSpec(id="S01", file="S01.csv", kind="sine", frequency_hz=f, amplitude_m=0.02)
    prepared = prepare_test(TestRecord(spec, {"t": t, "u": u, "F": 7.2e5 * u}))
    assert prepared.acceleration_noise_sd == 0.0
    assert not np.any(prepared.acceleration_noise(4))


def test_fit_corrected_for_accelerometer_noise_recovers_mass_and_stiffness():
    """Ten sine tests at frequencies whose period is no whole number of 200 Hz samples (so the
    cycle average cannot help), 2 % test-to-test spread and a noisy accelerometer (0.1 m/s^2
    white). Within one sine test Me is told from Ke only by the small harmonics of a, which the
    noise swamps; measured with this series: without the correction Me -58 % and Ke -103 %
    (the mass refit included), with it Me +0.2 % and Ke +0.0 %, each within its interval."""
    from bayes_sst.inference import fit
    from bayes_sst.inference._summary import summarize
    from bayes_sst.twin import simulate

    plan = [dict(kind="sine", frequency_hz=f, amplitude_m=round(min(0.25 / (2 * np.pi * f), 0.08), 4))
            for f in (0.37, 0.53, 0.71, 0.93, 1.17, 1.41, 1.73, 2.07, 2.39, 2.83)]
    series = simulate("sst-paper", seed=5, plan=plan, noise=dict(a_white=0.1), spread=0.02)
    truth = series.extra["truth"]
    corrected = summarize(fit(series, seed=1).tree)["parameters"]
    for name in ("Me", "Ke"):
        assert corrected[name]["mean"] == pytest.approx(truth[name], rel=0.03), name
        assert corrected[name]["q05"] <= truth[name] <= corrected[name]["q95"], name
    raw = summarize(fit(series, seed=1, signals=SignalOptions(accelerometer_noise=False)).tree)["parameters"]
    assert raw["Me"]["mean"] < 0.8 * truth["Me"]


def _periodic_acceleration(f, n_cycles, fs):
    """A band-limited periodic deck acceleration (fundamental and two harmonics) over whole
    cycles, with its displacement."""
    t = np.arange(int(round(n_cycles * fs / f))) / fs
    omega = 2 * np.pi * f
    u = 0.02 * np.sin(omega * t) + 0.0004 * np.sin(3 * omega * t + 0.3) + 0.0001 * np.sin(5 * omega * t)
    a = -(omega**2) * (0.02 * np.sin(omega * t) + 9 * 0.0004 * np.sin(3 * omega * t + 0.3)
                       + 25 * 0.0001 * np.sin(5 * omega * t))
    return t, u, a


def _excess(a, u, f, fs, white_sd):
    from bayes_sst.signals._filters import lowpass_power_gain
    from bayes_sst.signals._noise import coloured_noise_excess

    cutoff = 6 * f
    return coloured_noise_excess(
        zero_phase_lowpass(a, cutoff, fs), fs / f, cutoff, fs, white_sd,
        band_gain=lambda frequency: lowpass_power_gain(frequency, cutoff, fs),
        covariates=[zero_phase_lowpass(u, cutoff, fs)],
    )


@pytest.mark.parametrize("f, correlation_s", [(0.31, 1.0), (1.37, 0.2)])
def test_coloured_noise_excess_is_none_for_white_noise_and_reads_a_drift(f, correlation_s):
    """White accelerometer noise keeps the white treatment (no excess in any of 8 records);
    an AR(1) drift of known spectrum, added on top, is read: the estimate's in-band power
    matches the drift's own (the AR(1) spectrum summed over the band) within 40 %."""
    from bayes_sst.twin._noise import ar1

    fs, sigma, drift = 200.0, 0.03, 0.04
    t, u, a = _periodic_acceleration(f, 12, fs)
    cutoff = 6 * f
    for seed in range(8):
        noise = sigma * np.random.default_rng(seed).standard_normal(t.size)
        assert _excess(a + noise, u, f, fs, sigma) is None, seed
    estimates = []
    phi = np.exp(-1 / (fs * correlation_s))
    for seed in range(6):
        rng = np.random.default_rng(100 + seed)
        noisy = a + sigma * rng.standard_normal(t.size) + ar1(rng, t.size, drift, correlation_s, fs)
        found = _excess(noisy, u, f, fs, sigma)
        assert found is not None, seed
        frequency = np.arange(found.excess.size) * found.step_hz
        band = (frequency > 0) & (frequency <= cutoff)
        # the AR(1)'s expected periodogram, drift^2 (1 - phi^2)/|1 - phi e^{-iw}|^2, per bin
        expected = drift**2 * (1 - phi**2) / np.abs(1 - phi * np.exp(-2j * np.pi * frequency / fs)) ** 2
        estimates.append(found.excess[band].sum() / expected[band].sum())
    assert np.mean(estimates) == pytest.approx(1.0, rel=0.4)


def test_noise_spectrum_draws_have_the_spectrum_they_are_given():
    """NoiseSpectrum.draws: the mean periodogram of many draws is the excess, interpolated to
    the draws' own frequency grid (here a different length than the one it was read on)."""
    from bayes_sst.signals._noise import NoiseSpectrum

    fs = 100.0
    step = fs / 1000
    frequency = np.arange(501) * step
    excess = np.where(frequency <= 5.0, 1e-3 / (1 + (frequency / 0.5) ** 2), 0.0)
    draws = NoiseSpectrum(step, excess).draws(400, 1600, fs, np.random.default_rng(3))
    periodogram = np.mean(np.abs(np.fft.rfft(draws, axis=-1)) ** 2, axis=0) / 1600
    grid = np.fft.rfftfreq(1600, 1 / fs)
    target = np.interp(grid, frequency, excess)
    inside = (grid > 0.2) & (grid < 4.5)
    assert np.allclose(periodogram[inside], target[inside], rtol=0.25)
    assert periodogram[grid > 6.0].max() < 1e-12


def test_the_twin_accelerometer_drift_is_read_on_its_slow_tests_and_nothing_else_changes():
    """The virtual table's a_drift (AR(1), 1 s): the same series without it has identical u
    and F and no excess; with it, the slow tests' prepared acceleration carries an excess
    (12 steady cycles: with the twin's default 6, every bin between two harmonics is next to a
    harmonic or a half-harmonic and nothing can be read)."""
    from bayes_sst.signals import prepare_series
    from bayes_sst.twin import simulate

    plan = [dict(kind="sine", frequency_hz=f, amplitude_m=0.08) for f in (0.25, 0.4)]
    plain = simulate("sst-paper", seed=3, plan=plan, n_cycles=12)
    drifting = simulate("sst-paper", seed=3, plan=plan, n_cycles=12,
                        noise=dict(a_drift=0.02, a_drift_correlation_s=1.0))
    for one, other in zip(plain.tests, drifting.tests):
        assert np.array_equal(one.columns["u"], other.columns["u"])
        assert np.array_equal(one.columns["F"], other.columns["F"])
        assert 0.01 < np.std(other.columns["a"] - one.columns["a"]) < 0.06
    assert all(p.acceleration_noise_excess is None for p in prepare_series(plain))
    assert all(p.acceleration_noise_excess is not None for p in prepare_series(drifting))


def test_motion_beyond_the_harmonics_is_not_read_as_accelerometer_drift():
    """A deck whose motion wanders from cycle to cycle (a broadband in-band part beside the
    sine, as a servo loop's own response and sticking give) has that part in the displacement
    as well as in a: its acceleration, recorded with white noise only, must keep the white
    treatment. The displacement's second derivative is a covariate of the excess fit for that
    reason; with the force, the displacement and sign(v) alone the wander read as a drift."""
    fs, f, n_cycles, sigma = 500.0, 0.4, 12, 0.02
    rng = np.random.default_rng(5)
    t = (np.arange(int(n_cycles * fs / f)) + 0.3) / fs
    omega = 2 * np.pi * f
    amplitude = 0.05
    u = amplitude * np.sin(omega * t)
    v = amplitude * omega * np.cos(omega * t)
    a = -(omega**2) * u
    # 400 components at random frequencies up to 1.6 Hz, 0.4 mm of displacement in all
    frequency = rng.uniform(0.05, 1.6, 400)
    phase = rng.uniform(0, 2 * np.pi, 400)
    size = 4e-4 / np.sqrt(200) * np.ones(400)
    for fk, pk, ak in zip(frequency, phase, size):
        wk = 2 * np.pi * fk
        u = u + ak * np.sin(wk * t + pk)
        v = v + ak * wk * np.cos(wk * t + pk)
        a = a - ak * wk**2 * np.sin(wk * t + pk)
    force = 13200.0 * a + 720e3 * u + (29.6e3 * np.abs(v) ** 0.5 + 12.5e3) * np.sign(v)
    spec = TestSpec(id="W01", file="W01.csv", kind="sine", frequency_hz=f, amplitude_m=amplitude, order=1)
    columns = {"t": t, "u": u + 1e-5 * rng.standard_normal(t.size),
               "F": force + 50.0 * rng.standard_normal(t.size),
               "a": a + sigma * rng.standard_normal(t.size)}
    prepared = prepare_test(TestRecord(spec, columns), SignalOptions(steady_tolerance=0.05))
    assert prepared.acceleration_noise_sd == pytest.approx(sigma, rel=0.1)
    assert prepared.acceleration_noise_excess is None
