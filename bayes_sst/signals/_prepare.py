"""From a recorded test to the filtered, trimmed, decimated signals the likelihood sees.

Treatment, for each periodic test of fundamental f sampled at fs:

1. Band. A zero-phase Butterworth low-pass at fc = cutoff_multiple*f (the study uses 4f)
   cleans the displacement; velocity is its time derivative, acceleration the filtered
   measured `a` when recorded (else the time derivative of the lightly smoothed velocity
   of point 3, before the reversal weight and the low-pass, like a measured a). A recorded a
   that disagrees with the displacement's second derivative (signals._checks: dead, reversed
   or mis-scaled) is set aside with a note in PreparedTest.notes, as if it were not recorded.
2. Consistent filtering. The force is filtered with the same fc, and so is every regressor
   of the model: filter(a) and filter(u) are the filtered signals themselves (a filter
   commutes with differentiation), and the velocity regressors |v|^alpha*sign(v) and sign(v)
   are built at the recorded rate and then filtered. Because the force model is linear in
   Me, Ke, Ce, Fmu, filter(F) = Me*filter(a) + Ke*filter(u) + ... holds exactly, so the
   friction step, which a low-pass smears over about 1/fc, is predicted in its smeared form
   instead of being fought as a residual.
3. Velocity reversals. The velocity regressors use a velocity smoothed by a short Gaussian
   kernel (2.5 ms by default), which keeps the corner where the table rests at a reversal
   (a band-limited velocity rings there and biases alpha and Fmu); its zero crossings are
   those of the motion up to noise chatter inside the excluded band. Samples whose speed is below
   reversal_band times the cycle's peak speed are left out of the likelihood: there the
   table may stick, static friction exceeds kinetic friction, and the Coulomb step is not the
   physics. Leaving them out is not enough on its own, because the low-pass would spread their
   misfit over about 1/fc into the kept samples; so force and regressors are first multiplied
   by a weight that is 0 inside the band and rises to 1 over the next reversal_taper of the
   peak speed (reversal_weight), which keeps filter(w*F) = Me*filter(w*a) + ... exact.
   Measured on the virtual table (50 randomised series): alpha's mean z went from -0.44 to
   -0.01, Fmu's from -0.31 to +0.04, and a noise-free twin's per-test misfit at the true
   parameters from up to 384 N to at most 44 N. The band is 10 % of the peak speed (20 % until
   2026-11-25): the slow samples it keeps are where |v|^alpha is small, and they are what tells
   Fmu from Ce*|v|^alpha. On the independent generator's 24 series Fmu's posterior sd went from
   2.8 % to 2.2 % (within 3 % of the truth in 79 % of series instead of 54 %) and Ce's coverage
   from 83 % to 92 %; on 50 twin series Fmu within 3 % from 80 % to 84 %, every coverage
   within 86-96 %. 5 % narrowed Fmu further (1.9 %) but moved the twin's Me by +0.36 posterior
   sd on average, since its table rests for 5-30 ms at a reversal. A test without a recorded
   acceleration keeps 20 % (SignalOptions.band_for). The band reaches at least
   reversal_speed (10 mm/s; at most half the peak speed): friction exceeds the kinetic level
   below a few Stribeck velocities (mm/s on lubricated bearings) whatever the test's peak
   speed, and on a slow sine those samples are a large share of the cycle. Their excess
   friction enters the harmonics that alone tell a sine's Me from its Ke; on 30 clean series of
   the LuGre generator (Stribeck velocity 2-5 mm/s, peak ratio up to 1.05) the slow sines' Me
   came out 30-90 % low, and Me and Ke were covered in 83 % of series; with the 10 mm/s floor
   in 90 % and 93 % (Ce 93 -> 90 %, alpha 83 % either way). On the first independent
   generator (Coulomb friction) coverage stayed within one series of what it was.
   Without an accelerometer a is derived through a smoothing S (acceleration_kernel: the
   velocity's Gaussian kernel and the [1, 2, 1]/4 that two central differences add), so it is
   S(a), each reversal's pulse widened by a few milliseconds (by more at low sampling rates:
   at 200 Hz the [1, 2, 1]/4 alone has a 3.5 ms sd), and the weight then cuts S(a) where the
   force's own, narrower pulse has another share (a triangle's acceleration is nearly all
   pulse). The force, u and the velocity regressors therefore pass through S as well before
   the weight (kernel_on_force), so that filter(w*S(F)) = Me*filter(w*S(a)) + ... holds; S
   moves no zero crossing, and S(sign(v)) differs from sign(S(v)) only within a few kernel
   widths of a reversal, inside the band and its ramp. Measured on 2026-12-01: rounded
   triangles and sines (tests/test_signals.py) pooled Me -0.02 % at 1 kHz and +0.19 % at 200 Hz
   with S on the force, -1.27 % and -3.33 % without, -0.10 % and -2.05 % with the Gaussian
   alone; on 24 series of the sixth and seventh simulators fitted with their a and v columns
   removed (with the pre-sliding floor of prepare_series, adopted the same day), the mean
   absolute error over 23 of them went from Me 2.21 to 0.88 %, Ke 4.85 to 0.69 %, Ce 3.07 to
   1.01 %, alpha 0.017 to 0.010, Fmu 4.66 to 2.61 %, coverage Me 20 -> 20, Ke 23 -> 20, Ce 22
   -> 23, alpha 22 -> 22, Fmu 20 -> 21, converged 19 -> 23; the 24th (the sixth's seed 7
   without a) slides along the Me-Ke ridge to Me -30 %, flagged as not converged, where it had
   read -1.9 %, also not converged (docs/measurements.md).
4. Steady state. Only the longest run of whole cycles whose amplitude sits on the plateau
   enters; ramp-in and ramp-out cycles are trimmed. The means of F, u, a (and a measured v)
   over those cycles are subtracted first (without_steady_offsets): sensor zero offsets. What
   is left of a constant force (the dissipative force need not average to zero) is each test's
   free constant, projected out of the force and every regressor last (project_out).
5. Accelerometer noise. Within the steady window the measured acceleration is replaced by its
   cycle-synchronous average (signals.periodic_component): the motion repeats from cycle to
   cycle, the accelerometer's noise does not. Noise in a regressor biases its coefficient
   toward zero (errors in variables), and for a sine test Me is told apart from Ke only by the
   small harmonics of a, where the noise weighs most: single-test least squares on a
   randomised twin series put Me 20-100 % low. Skipped when u's fundamental slips by more
   than a quarter sample over the window (the motion's period is not the test frequency's).
   The average only reaches cycles a whole number of samples apart, so at most test
   frequencies it leaves much or all of the noise; the noise's level is therefore also read
   off the record (white_noise_sd, from fourth differences, of a less its low-pass,
   mid-stroke), together with any in-band drift beyond that white level
   (coloured_noise_excess: a drifting accelerometer's noise sits at a slow test's own
   frequencies), and the inference subtracts what that noise adds to its moments
   (inference.lagged_moments, errors in variables). See README, known limitations.
6. Decimation. Inside the steady window every D-th sample is kept, D chosen so the kept
   rate is about 2*fc: the filtered residual is then close to white over the kept band and
   an AR(1) term can model what colour remains, instead of facing the steep roll-off of a
   heavily oversampled filtered signal.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Callable

import numpy as np

from bayes_sst.io import Series, SeriesFormatError, TestRecord, table_number
from bayes_sst.io._series import sample_rate_of
from bayes_sst.physics import friction_load_ratio, hold_down_force
from bayes_sst.signals._checks import accelerometer_disagreement
from bayes_sst.signals._cycles import CycleWindow, fundamental_phase, periodic_component, steady_cycles
from bayes_sst.signals._filters import (lowpass_power_gain, raised_cosine_step, second_derivative, time_derivative,
                                       velocity_with_acceleration_above, zero_phase_lowpass)
from bayes_sst.signals._noise import NoiseSpectrum, coloured_noise_excess, mid_stroke_noise_sd
from bayes_sst.signals._presliding import (PRESLIDING_TRAVELS, presliding_profile, presliding_weight,
                                           travel_since_reversal)

MIN_STEADY_CYCLES = 3
# a test with fewer likelihood samples than this is named in the notes: its four coefficients
# then rest on the between-test prior (tests of 1 mm at 0.5-1 Hz kept 5-12, a series of them
# put Ke 30 % low, outside its 90 % interval); the tests of the twin's and three other
# generators' series keep 25-60
FEW_LIKELIHOOD_SAMPLES = 12


@dataclass(frozen=True)
class SignalOptions:
    """Settings of the signal treatment (see the module docstring).

    cutoff_multiple : low-pass cut-off as a multiple of the test frequency.
    reversal_band : samples with |v| below this share of the peak speed are left out.
    reversal_band_without_accelerometer : the band of a test whose acceleration is derived
        from u (no `a` column, or one set aside by check_accelerometer); None uses
        reversal_band. Wider, because the derived acceleration carries the rest's corner at a
        reversal (see band_for).
    steady_tolerance : relative amplitude band that defines a steady cycle.
    skip_cycles : steady cycles dropped at the start of the run (settling).
    samples_per_cutoff : kept samples per 1/fc; 2 puts the kept Nyquist frequency at fc.
    velocity_cutoff_ratio : Butterworth cut-off of the velocity, relative to fc, used only
        when velocity_smoothing_s is 0.
    velocity_smoothing_s : standard deviation (s) of the Gaussian kernel that smooths u (or a
        measured v) before the velocity regressors are built; 0 uses the Butterworth route.
    velocity_with_accelerometer : where a recorded acceleration is accepted, the velocity
        regressors take the velocity's part above the kernel's band from the integrated
        acceleration (complementary_velocity), so that a wide kernel keeps the corner of a
        breakaway; the reversal band and weight are still set from the kernel's velocity.
    reversal_window : multiply force and regressors by the reversal weight (reversal_weight)
        before filtering, so that the reversal misfit is not spread into the kept samples.
    reversal_taper : width of the weight's ramp, as a share of the peak speed.
    reversal_speed : the band reaches at least this speed (m/s), up to half the peak speed.
    periodic_acceleration : replace a measured acceleration inside the steady window by its
        cycle-synchronous average over whole-sample cycle shifts (periodic_component).
    remove_offsets : subtract from F, u, a (and a measured v) their means over the steady
        window's whole cycles (sensor zero offsets; see without_steady_offsets).
    free_constant : give each test's force a free constant: the shape a constant takes after
        the reversal weight and the low-pass, filter(w), is projected out of the force and of
        every regressor over the kept samples (PreparedTest.without_constant), so what is left
        of the steady window's means after remove_offsets cannot bias the coefficients.
    payload_friction : scale each test's Coulomb regressor by its bearing-load ratio
        (friction_load), so that every test's Fmu is the empty table's.
    check_accelerometer : set aside a recorded acceleration that disagrees with the
        displacement's second derivative (signals._checks), with a note.
    accelerometer_noise : estimate the white noise of a measured acceleration
        (acceleration_noise_sd), so that the likelihood's moments can be rid of what that
        noise adds to them (inference.lagged_moments, errors in variables).
    coloured_accelerometer_noise : estimate, as well, the measured acceleration's in-band
        noise beyond its white level (a drifting accelerometer; signals.coloured_noise_excess).
    drift_displacement_covariate : the displacement's second derivative is one of that
        estimate's covariates (_drift_of_accelerometer).
    noise_difference_order : the differences (2 or 4) from which the accelerometer's white
        noise is read (signals._noise.white_noise_sd says why 4).
    stagger_phases : let the decimation grid slip by one step over the steady window, so that
        the cycles of a test whose period is a whole number of steps are sampled at new phases
        (kept_indices; off by default, it says why).
    presliding : the friction's pre-sliding distance delta (m): samples within
        PRESLIDING_TRAVELS*delta of travel after a reversal are left out like the reversal band's
        (signals._presliding); None reads delta from the series (prepare_series), 0 leaves
        nothing out for it.
    presliding_floor : with presliding None, the travel left out where the series reads a
        shorter turn, or none but leans to one (its profile gains at least 2 nats at a travel
        up to the floor): the profile cannot read a turn of a few tens of um, at low sampling
        rates least (docs/measurements.md, 2026-12-01).
    presliding_floor_needs_peak : take the floor on a lean only where the profile's best gain up
        to PRESLIDING_MAX_M lies within the floor (PreslidingProfile.peaks_within); the
        diagnosis's default view does (diagnosis._data says why), the fit does not.
    kernel_on_force : where the acceleration is derived (no accelerometer), pass the force, the
        displacement and the velocity regressors through the smoothing the derived acceleration
        went through (acceleration_kernel), before the reversal weight (module docstring, point 3).
    """

    cutoff_multiple: float = 4.0
    reversal_band: float = 0.1
    reversal_band_without_accelerometer: float | None = 0.2
    steady_tolerance: float = 0.025
    skip_cycles: int = 0
    samples_per_cutoff: float = 2.0
    velocity_cutoff_ratio: float = 1.0
    velocity_smoothing_s: float = 0.0025
    velocity_with_accelerometer: bool = False
    reversal_window: bool = True
    reversal_taper: float = 0.1
    reversal_speed: float = 0.01
    periodic_acceleration: bool = True
    remove_offsets: bool = True
    free_constant: bool = True
    payload_friction: bool = True
    accelerometer_noise: bool = True
    coloured_accelerometer_noise: bool = True
    drift_displacement_covariate: bool = True
    check_accelerometer: bool = True
    stagger_phases: bool = False
    noise_difference_order: int = 4
    presliding: float | None = None
    presliding_floor: float = 40e-6
    presliding_floor_needs_peak: bool = False
    kernel_on_force: bool = True

    def band_for(self, measured_acceleration: bool) -> "SignalOptions":
        """These options with the reversal band that applies to a test with or without a
        measured acceleration.

        Why two bands: without an accelerometer, a is the second derivative of the smoothed
        displacement, which turns the corner of the rest at a reversal into a spike that the
        kernel spreads over a few milliseconds. On the twin series of
        tests/test_fit.py with `a` removed, Fmu came out -2.8 % with the band at 20 % and
        -6.1 % at 10 %, while with `a` recorded 10 % is the better band (module docstring).
        """
        if measured_acceleration or self.reversal_band_without_accelerometer is None:
            return self
        return replace(self, reversal_band=self.reversal_band_without_accelerometer)


@dataclass(frozen=True)
class PreparedTest:
    """A periodic test ready for the likelihood.

    Arrays named like the model (t, F, u, v, a) hold the kept, filtered samples, F, u and a
    less their projection on constant_shape (each test's free constant; v is not a column);
    `keep` marks those that enter the likelihood (outside the reversal band). `velocity_full`
    is the filtered velocity at the recorded rate, from which velocity regressors are rebuilt
    and filtered exactly like the force (see `regressor`).
    """

    id: str
    file: str
    kind: str
    frequency_hz: float
    amplitude_m: float
    payload_kg: float
    order: int | None
    sample_rate_hz: float
    cutoff_hz: float
    decimation: int
    window: CycleWindow
    index: np.ndarray
    t: np.ndarray
    F: np.ndarray
    u: np.ndarray
    v: np.ndarray
    a: np.ndarray
    keep: np.ndarray
    velocity_full: np.ndarray
    weight_full: np.ndarray | None = None
    friction_load: float = 1.0  # N_test/N_empty, see friction_load
    acceleration_noise_sd: float = 0.0  # white noise of the recorded a (m/s^2); 0: none known
    acceleration_noise_excess: NoiseSpectrum | None = None  # its in-band noise beyond the white level
    acceleration_averaged: bool = False  # a replaced by its cycle-synchronous average
    acceleration_measured: bool = False  # a is the recorded one (not derived from u)
    notes: tuple[str, ...] = ()  # what the treatment changed about the record, for the user
    # filter(w)[index]: the shape of a constant force after the weight and the low-pass, which
    # every column loses its projection on (without_constant); None: no free constant
    constant_shape: np.ndarray | None = None
    # sd (s) of the Gaussian in the acceleration_kernel that force and every regressor went
    # through before the weight (SignalOptions.kernel_on_force); 0: none
    kernel_s: float = 0.0

    @property
    def n_kept(self) -> int:
        return int(self.keep.sum())

    @property
    def filter_span(self) -> tuple[int, int]:
        """[lo, hi): the steady window plus a margin of four cut-off periods each side, the
        stretch a regressor is filtered over (the filter has settled well within the margin)."""
        margin = int(np.ceil(4.0 * self.sample_rate_hz / self.cutoff_hz))
        return max(0, self.window.start - margin), min(len(self.velocity_full), self.window.stop + margin)

    def regressor(self, of_velocity: Callable[[np.ndarray], np.ndarray]) -> np.ndarray:
        """filter(w*S(g(v)))[index]: a velocity regressor treated exactly as the force was (S
        the acceleration_kernel of kernel_s where there is one; less its projection on
        constant_shape).

        `of_velocity` maps an array of velocities to regressor values (extra leading axes
        are allowed in its output, the last axis being time). Only the steady window plus a
        margin of four cut-off periods is filtered; the filter has settled well within it.
        """
        lo, hi = self.filter_span
        values = of_velocity(self.velocity_full[lo:hi])
        if self.kernel_s > 0.0:
            values = acceleration_kernel(values, self.kernel_s * self.sample_rate_hz)
        if self.weight_full is not None:
            values = values * self.weight_full[lo:hi]
        filtered = zero_phase_lowpass(values, self.cutoff_hz, self.sample_rate_hz, axis=-1)
        return self.without_constant(filtered[..., self.index - lo])

    def without_constant(self, values: np.ndarray) -> np.ndarray:
        """values less their least-squares projection on constant_shape over the kept samples
        (last axis: the samples at `index`); unchanged without a free constant."""
        return project_out(values, self.constant_shape, self.keep)

    @property
    def acceleration_noise_known(self) -> bool:
        return self.acceleration_noise_sd > 0.0 or self.acceleration_noise_excess is not None

    def raw_acceleration_noise(self, n_draws: int, length: int, rng) -> np.ndarray:
        """(n_draws, length) draws of the recorded accelerometer's noise at the recorded rate:
        white of sd acceleration_noise_sd plus, where one was read, the in-band excess
        (signals.coloured_noise_excess)."""
        noise = rng.normal(0.0, self.acceleration_noise_sd, (n_draws, length))
        if self.acceleration_noise_excess is not None:
            noise += self.acceleration_noise_excess.draws(n_draws, length, self.sample_rate_hz, rng)
        return noise

    def averaged_acceleration_noise(self, n_draws: int, rng) -> np.ndarray:
        """(n_draws, filter span) draws of raw_acceleration_noise, replaced by their
        cycle-synchronous average inside the steady window where the recorded acceleration was."""
        lo, hi = self.filter_span
        noise = self.raw_acceleration_noise(n_draws, hi - lo, rng)
        if self.acceleration_averaged:
            local = self.window._replace(start=self.window.start - lo, stop=self.window.stop - lo)
            noise[:, local.start : local.stop] = periodic_component(noise, local)
        return noise

    def acceleration_noise(self, n_draws: int, seed: int = 0) -> np.ndarray:
        """(n_draws, len(index)) draws of the accelerometer's noise (raw_acceleration_noise)
        treated exactly as the recorded acceleration was: cycle-synchronous average (when it was
        applied), reversal weight, low-pass, decimation, the free constant's projection. What the
        accelerometer's noise adds to `a`, for the errors-in-variables correction of the moments;
        zeros when none is known.
        """
        if not self.acceleration_noise_known:
            return np.zeros((n_draws, len(self.index)))
        lo, hi = self.filter_span
        noise = self.averaged_acceleration_noise(n_draws, np.random.default_rng(seed))
        if self.weight_full is not None:
            noise = noise * self.weight_full[lo:hi]
        filtered = zero_phase_lowpass(noise, self.cutoff_hz, self.sample_rate_hz, axis=-1)
        return self.without_constant(filtered[:, self.index - lo])

    @property
    def friction_sign(self) -> np.ndarray:
        """friction_load*filter(sign(v)) at the kept samples: the Coulomb regressor, whose
        coefficient is then the friction of the empty table (see friction_load)."""
        return self.friction_load * self.regressor(np.sign)


def friction_load(table, payload_kg: float) -> float:
    """N_test/N_empty = (F_hd + (m_deck + m_payload)*g)/(F_hd + m_deck*g) from the series' table
    description (strut.p0_pa, strut.area_m2 give F_hd = 4*p0*A; deck_mass_kg); with the deck's
    mass but not the struts', the weights' ratio (m_deck + m_payload)/m_deck; 1.0 without a
    payload or without the deck's mass.

    Why: Fmu = mu_e*N and the payload's weight loads the bearings as the deck's does, so a test
    with a specimen has more Coulomb friction than the empty table (SST: +5 % for 5 t). Scaling
    the test's sign(v) regressor by this ratio makes every test's friction coefficient the
    empty table's, which the between-test model then treats as one population value; left
    unscaled, the payload tests' extra friction went into the population Fmu (+2 % on a
    campaign with 0, 5 and 10 t payloads, measured on the virtual table). The fit does not take
    the ratio as exact: it learns the share kappa of the increase L - 1 that the data show
    (inference._collapsed.friction_factors), so the ratio sets the scale of the payload's
    effect, and where the struts are not described the weights alone set it.
    """
    if not payload_kg:
        return 1.0
    deck = table_number(table, "deck_mass_kg")
    if deck is None:
        return 1.0
    p0, area = table_number(table, "strut", "p0_pa"), table_number(table, "strut", "area_m2")
    if p0 is None or area is None:
        return float((deck + float(payload_kg)) / deck)
    return float(friction_load_ratio(hold_down_force(p0, area), deck, float(payload_kg)))


def reversal_band_share(peak_speed: float, options: "SignalOptions") -> float:
    """The band's edge as a share of the peak speed: b = max(reversal_band, reversal_speed/peak),
    at most max(reversal_band, 0.5) so that a slow test keeps the faster half of its cycle."""
    if peak_speed <= 0.0:
        return options.reversal_band
    return min(max(options.reversal_band, options.reversal_speed / peak_speed), max(options.reversal_band, 0.5))


def kept_indices(start: int, stop: int, step: int, stagger: bool = False) -> np.ndarray:
    """The record indices of the kept samples in [start, stop): every step-th sample, or, with
    stagger, j*step + floor(j*step/N) for j = 0, 1, ... (N = the unstaggered count), a grid
    that slips by one step over the window.

    Why stagger: at a lab's round test frequencies and sampling rates the period is a whole
    number of steps, so every cycle is sampled at the same phases, and the steady cycles of a
    test add no phase, hence no new speed, to the few that tell the power law from the
    Coulomb step. Slipping the grid by step/n per cycle spreads n cycles' samples over n times
    as many phases, as a test frequency that is not a round number does by itself. The grid
    stays uniform up to a sample (spacing step*(1 + 1/N), rounded down), so the AR(1)
    residual still sees evenly spaced pairs, and it keeps N or N - 1 samples.

    Off by default (SignalOptions.stagger_phases): measured on 2026-11-30 (docs/measurements.md)
    it narrowed alpha's and Fmu's intervals by about a third and put Fmu within 3 % on 31 of 40
    clean series of the sixth simulator instead of 24, but the bias it uncovered grew as fast:
    Me's and Ke's coverage there fell from 90 and 88 % to 78 and 80 %, the fifth simulator's
    alpha and Fmu z sd rose from 1.2 to 1.5, and the virtual table's Ce coverage from 90 to 84 %."""
    n = len(range(start, stop, step))
    j = np.arange(n)
    index = start + j * step
    if stagger and n > 1 and step > 1:
        index = index + (j * step) // n
    return index[index < stop]


def reversal_weight(velocity: np.ndarray, peak_speed: float, options: "SignalOptions") -> np.ndarray:
    """w(t) in [0, 1]: 0 where |v| < b*peak_speed, 1 above (b + reversal_taper)*peak_speed, a
    raised-cosine ramp between (all ones when the window is off); b = reversal_band_share.

    Why: at a reversal the table rests and breaks away, and there the force is not
    Me*a + Ke*u + (Ce*|v|^alpha + Fmu)*sign(v) (the holding force ramps between -Fs and +Fs
    while sign(v) steps). Leaving those samples out of the likelihood is not enough: the
    low-pass spreads their misfit over about 1/fc, a quarter cycle at 4f, into the kept
    samples. Multiplying the force and every regressor by w BEFORE filtering keeps the linear
    relation exact, filter(w*F) = Me*filter(w*a) + Ke*filter(w*u) + ..., because w*(F - model)
    is zero wherever the model is wrong, so the reversal misfit never reaches the likelihood.
    """
    if not options.reversal_window or options.reversal_band <= 0.0 or peak_speed <= 0.0:
        return np.ones_like(velocity, dtype=float)
    share_above_band = np.abs(velocity) / peak_speed - reversal_band_share(peak_speed, options)
    return raised_cosine_step(share_above_band / max(options.reversal_taper, 1e-9))


# the synchronous average needs the motion's period to match the test frequency: over the
# window the fundamental of u may slip by at most this many samples
MAX_PHASE_SLIP_SAMPLES = 0.25


def _holds_its_period(u_filtered, t, frequency_hz: float, window: CycleWindow) -> bool:
    """True when u's fundamental in the window's last cycle has the phase of its first cycle
    (within MAX_PHASE_SLIP_SAMPLES): a test frequency that differs from the motion's by a
    relative 1/(n*T) would otherwise average cycles at drifting phases."""
    period = window.period_samples
    phases = []
    for m in (0, window.n_cycles - 1):
        lo = window.start + int(round(m * period))
        cycle = slice(lo, lo + int(round(period)))
        phases.append(fundamental_phase(u_filtered[cycle], t[cycle], frequency_hz)[1])
    slip = np.angle(np.exp(1j * (phases[1] - phases[0])))
    return abs(slip) / (2.0 * np.pi) * period <= MAX_PHASE_SLIP_SAMPLES


def complementary_velocity(smoothed_v: np.ndarray, a: np.ndarray, sample_rate_hz: float,
                           smoothing_s: float) -> np.ndarray:
    """v = G*v_s + (I - G)*integral(a): the smoothed velocity below the Gaussian kernel G's band,
    the recorded acceleration's running (trapezoidal) integral above it, where smoothed_v is
    already G applied to the velocity (G*v_s, smoothing_s its sd).

    Why: G preserves a straight line, so a ramp of v is kept, but it rounds a corner: where a
    table that rested breaks away (v = 0, then a*(t - t0)), G*v reads about 0.4*a*smoothing_s
    too fast at the corner, 12 mm/s for 3 m/s^2 under a 10 ms kernel, which hides a Stribeck
    peak of a few mm/s. The integrated acceleration has the corner; its drift and offset are
    slow (a constant offset integrates to a line, which I - G removes exactly). Measured on
    the virtual table (stiction at a 5 mm/s Stribeck velocity, seeds 21 and 31-33): static
    ratios 1.3 and 1.5 read within -13..+13 % with it, -6..+96 % without.
    """
    from scipy.ndimage import gaussian_filter1d

    return velocity_with_acceleration_above(smoothed_v, a, sample_rate_hz,
                                            lambda x: gaussian_filter1d(x, smoothing_s * sample_rate_hz))


def _derivative_noise(x: np.ndarray, fs: float, cutoff: float, to_velocity) -> float:
    """sd of the white noise on x after to_velocity, a time derivative and the analysis
    low-pass: x's white-noise sd (read off its part above the cut-off,
    signals._noise.white_noise_sd) times the norm of that chain's impulse response."""
    from bayes_sst.signals._noise import white_noise_sd

    sigma = white_noise_sd(x - zero_phase_lowpass(x, cutoff, fs))
    n = 2 * (int(8.0 * fs / cutoff) + 64) + 1
    impulse = np.zeros(n)
    impulse[n // 2] = 1.0
    response = zero_phase_lowpass(time_derivative(to_velocity(impulse), fs), cutoff, fs)
    return sigma * float(np.linalg.norm(response))


def _derived_acceleration(record: TestRecord, v_f: np.ndarray, cutoff: float, options: SignalOptions) -> np.ndarray:
    """The acceleration of a test without an accelerometer: the time derivative of the velocity
    _velocity gives, or, where that velocity is a recorded v noisier in the analysis band than
    the one from u, the derivative of the velocity from u. Why: a velocity transducer's white
    noise is flat in frequency, the derivative of u's noise rises with it, so in the band of a
    slow test u gives the quieter acceleration; a recorded v with 2 mm/s of noise (u with
    20 um) at 200 Hz gave an acceleration that put Me's between-test sd at 905 %."""
    fs = record.sample_rate_hz
    if record.get("v") is None or recorded_velocity_is_quieter(record, cutoff, options):
        return time_derivative(v_f, fs)
    return time_derivative(_velocity_map(fs, cutoff, options, of_displacement=True)(record.u), fs)


def recorded_velocity_is_quieter(record: TestRecord, cutoff: float, options: SignalOptions) -> bool:
    """Whether the test's recorded v, smoothed and differentiated, carries less white noise in
    the analysis band (below `cutoff`) than u smoothed and differentiated twice (False without v)."""
    measured_v = record.get("v")
    if measured_v is None:
        return False
    fs = record.sample_rate_hz
    from_v = _velocity_map(fs, cutoff, options, of_displacement=False)
    from_u = _velocity_map(fs, cutoff, options, of_displacement=True)
    return bool(_derivative_noise(np.asarray(measured_v, dtype=float), fs, cutoff, from_v)
                <= _derivative_noise(np.asarray(record.u, dtype=float), fs, cutoff, from_u))


def _velocity(record: TestRecord, cutoff: float, options: SignalOptions) -> np.ndarray:
    """Velocity for the sign and power-law regressors, at the recorded rate.

    A table rests for a few milliseconds at each reversal. A band-limited (Butterworth) velocity
    cannot follow that corner: it rings around it, and because |v|^alpha is steep near zero the
    regressors are distorted well beyond the excluded band, which biased alpha by about -0.01
    and Fmu by about -2.5 % on the virtual table. A short Gaussian kernel (no overshoot, zero
    phase) keeps the corner. Its width trades noise for shape: the kernel scales a sine of
    frequency f by exp(-(2 pi f s)^2/2) and rounds the corners, and on a nearly noise-free
    virtual table (sst-paper, no spread) s = 20, 10, 5, 2.5, 1 ms gave Fmu errors of -2.7,
    -2.2, -0.6, -0.1, -0.0 % and Ce errors of +2.0, +1.0, +0.2, +0.0, -0.0 %. With the twin's
    sensor noise (20 um on u at 200 Hz) 2.5 ms leaves a velocity noise of a few mm/s, which
    the force-rate low-pass of the regressors averages away; hence the default of 2.5 ms.
    """
    fs = record.sample_rate_hz
    measured_v = record.get("v")
    if measured_v is not None:
        return _velocity_map(fs, cutoff, options, of_displacement=False)(measured_v)
    return _velocity_map(fs, cutoff, options, of_displacement=True)(record.u)


def _velocity_map(fs: float, cutoff: float, options: SignalOptions, *, of_displacement: bool):
    """The linear map _velocity applies to a recorded v (the smoothing), or to u (the smoothing,
    then the time derivative): a 2.5 ms Gaussian kernel by default, the Butterworth low-pass at
    velocity_cutoff_ratio*cutoff where velocity_smoothing_s is 0."""
    if options.velocity_smoothing_s > 0:
        from scipy.ndimage import gaussian_filter1d

        width = options.velocity_smoothing_s * fs

        def smooth(x):
            return gaussian_filter1d(np.asarray(x, dtype=float), width)
    else:
        v_cutoff = min(options.velocity_cutoff_ratio * cutoff, 0.8 * 0.5 * fs)

        def smooth(x):
            return zero_phase_lowpass(np.asarray(x, dtype=float), v_cutoff, fs)
    if of_displacement:
        return lambda x: time_derivative(smooth(x), fs)
    return smooth


def acceleration_kernel(values, width_samples: float):
    """S(x) = B(K(x)) along the last axis: K the Gaussian of sd width_samples samples that
    _velocity_map smooths with, B = [1, 2, 1]/4. S is what a derived acceleration has been
    through: two central differences are the second difference of B(x),
    (x[n+2] - 2x[n] + x[n-2])/(4h^2) = delta^2(B(x))[n], so the derivative of K(u)'s central
    difference is delta^2(S(u)), about S(a); a recorded v's one central difference is, to the
    trapezoid rule's accuracy, B of its derivative. At 200 Hz B's sd, h/sqrt(2) = 3.5 ms, is
    more than K's 2.5 ms."""
    from scipy.ndimage import convolve1d, gaussian_filter1d

    smoothed = gaussian_filter1d(np.asarray(values, dtype=float), width_samples, axis=-1)
    return convolve1d(smoothed, np.array([0.25, 0.5, 0.25]), axis=-1, mode="nearest")


def project_out(values: np.ndarray, shape: np.ndarray | None, keep: np.ndarray) -> np.ndarray:
    """values - c*shape, c = sum_keep(values*shape)/sum_keep(shape^2), along the last axis
    (values unchanged where shape is None: no free constant).

    The free constant of each test (SignalOptions.free_constant). A constant force c, weighted
    and low-passed like everything else, reaches the kept samples as c*filter(w); projecting
    filter(w) out of the force and every regressor removes any such c exactly (ordinary least
    squares over the kept samples; the likelihood then whitens what is left, so the constant is
    not re-estimated in its AR(1) metric, and each test's noise has one degree of freedom fewer
    than it counts, 2-4 % of its variance at 25-60 kept samples).

    Why: without_steady_offsets removes the steady window's means of F, u and a, which is exact
    only if mean(F) = Ke*mean(u), that is if the dissipative force averages to zero over the
    window, and neither the model's regressors nor the table's real force need to: a
    controller, a valve or a stick that holds one direction a few samples longer leaves sign(v)
    a mean of 0.1-0.3 %, and the table's force at rest in the reversal band is not the model's
    at all. On the fifth independent simulator with all noise removed (seed 6) the force kept a
    constant misfit of 10-60 N at the true parameters, which the slowest sines, whose inertia
    force is a few hundred newtons, read as Me 4-12 % high (least squares per test, true alpha).
    Fitted over the kept samples, where the model holds, the constant takes up neither.
    """
    values = np.asarray(values, dtype=float)
    if shape is None:
        return values
    kept_shape = shape[keep]
    norm = float(kept_shape @ kept_shape)
    if norm <= 0.0:
        return values
    coefficient = values[..., keep] @ kept_shape / norm
    return values - coefficient[..., None] * shape


def without_steady_offsets(record: TestRecord, window: CycleWindow) -> TestRecord:
    """The record with the means of F, u, a and v over the steady window's whole cycles removed.

    Over whole cycles of a periodic motion the means of a and v are zero, and where the
    dissipative force averages to zero too (odd in v, exactly symmetric cycles) mean(F) =
    Ke*mean(u): removing the means of F and u together then keeps F = Me*a + Ke*u + D(v) exact
    whether the table oscillates about the strut's neutral or not, and removes constant sensor
    offsets of every channel. Where it does not, what is left is a constant force, which each
    test's free constant takes (project_out).
    Why: the model has no constant term, and measured on randomised virtual series an offset of
    3 kN on F, 3 mm on u and 0.05 m/s^2 on a moved Me by -2.4 % and Ke by -3.2 % (seed 2) with
    intervals narrower than without it.
    """
    span = slice(window.start, window.stop)
    columns = dict(record.columns)
    for name in ("F", "u", "a", "v"):
        if name in columns:
            values = np.asarray(columns[name], dtype=float)
            columns[name] = values - float(np.mean(values[span]))
    return TestRecord(record.spec, columns)


# the record's dominant frequency must lie within this share of frequency_hz; its steady
# amplitude within AMPLITUDE_RATIO_LIMITS of amplitude_m (a units slip: u in mm is 1000x), with
# a note outside AMPLITUDE_RATIO_NOTE. The twin's and three other generators' 136 tests lie
# within 3 % of their frequency and at 0.89-1.05 of their amplitude
FREQUENCY_RTOL = 0.1
AMPLITUDE_RATIO_LIMITS = (0.2, 5.0)
AMPLITUDE_RATIO_NOTE = (0.67, 1.5)


def dominant_frequency(u, t, above_hz: float = 0.0) -> float:
    """The frequency (Hz) of the largest peak of u's spectrum above above_hz (linear trend
    removed, Hann window, zero-padded four times), the DC bin excluded."""
    u = np.asarray(u, dtype=float)
    t = np.asarray(t, dtype=float)
    x = u - np.polyval(np.polyfit(t - t[0], u, 1), t - t[0])
    n = len(x)
    spectrum = np.abs(np.fft.rfft(x * np.hanning(n), 4 * n))
    frequencies = np.fft.rfftfreq(4 * n, 1.0 / sample_rate_of(t))
    searched = np.flatnonzero(frequencies > above_hz)[1 if above_hz <= 0 else 0:]
    return float(frequencies[searched[int(np.argmax(spectrum[searched]))]])


# a record whose u spans no more than this (m) does not move at all: a nanometre, far below
# any displacement transducer's resolution
STILL_SPAN_M = 1e-9


def _check_frequency(record: TestRecord, where: str) -> None:
    """Raise where the record's motion is at another frequency than the manifest's. Why: a
    file listed under a test of twice its frequency was cut into 12 'cycles' and fitted without
    a word."""
    spec = record.spec
    f = float(spec.frequency_hz)
    span = float(np.ptp(record.u))
    if not span > STILL_SPAN_M:
        raise SeriesFormatError(where, f"test '{spec.id}'",
                                f"u does not move (peak to peak {span:.3g} m): is this the test's file?")
    # above a quarter of f: a slow drift of u, beyond the linear trend, is no test's motion
    found = dominant_frequency(record.u, record.t, above_hz=0.25 * f)
    if abs(found / f - 1.0) > FREQUENCY_RTOL:
        raise SeriesFormatError(
            where, f"test '{spec.id}'",
            f"u's strongest motion above {0.25 * f:.3g} Hz is at {found:.3g} Hz, but frequency_hz is {f:g} Hz "
            "(slower motion is not searched): is this the test's file?")


def _check_amplitude(record: TestRecord, window: CycleWindow, where: str) -> tuple[str, ...]:
    """Raise where the steady amplitude is AMPLITUDE_RATIO_LIMITS away from amplitude_m
    (another test's file, u not in metres); a note where it is merely far off. Why: u in mm
    gave Me = -0.5 kg, with the accelerometer blamed for it."""
    spec = record.spec
    if not spec.amplitude_m:
        return ()
    ratio = window.amplitude / float(spec.amplitude_m)
    if not AMPLITUDE_RATIO_LIMITS[0] <= ratio <= AMPLITUDE_RATIO_LIMITS[1]:
        raise SeriesFormatError(
            where, f"test '{spec.id}'",
            f"the steady amplitude of u is {window.amplitude:.4g} m but amplitude_m is {spec.amplitude_m:g} m "
            f"({ratio:.3g} times): is u in metres?")
    if not AMPLITUDE_RATIO_NOTE[0] <= ratio <= AMPLITUDE_RATIO_NOTE[1]:
        return (f"{where}: test '{spec.id}': the steady amplitude of u is {ratio:.2f} times amplitude_m "
                f"({window.amplitude:.4g} m against {spec.amplitude_m:g} m); check the record and the manifest",)
    return ()


# a channel that holds its largest or smallest value in at least this share of the samples (and
# CLIPPED_MIN_SAMPLES of them) reads as clipped. Noisy records hold each extreme once or twice
# (F and a of the twin's and three other generators' 136 tests: at most 2); a force clipped at
# 80 % of its peak, in 8-10 % of them
CLIPPED_SHARE = 0.01
CLIPPED_MIN_SAMPLES = 10


def _clipping_notes(record: TestRecord, where: str) -> tuple[str, ...]:
    """A note for each of F and a that sits at its extreme value in many samples (saturated)."""
    notes = []
    for name in ("F", "a"):
        x = record.get(name)
        if x is None:
            continue
        x = np.asarray(x, dtype=float)
        for side, level in (("largest", x.max()), ("smallest", x.min())):
            count = int(np.sum(x == level))
            if count >= max(CLIPPED_MIN_SAMPLES, CLIPPED_SHARE * len(x)):
                notes.append(f"{where}: test '{record.spec.id}': column '{name}' holds its {side} value, {level:.6g}, "
                             f"in {count} of {len(x)} samples: a clipped (saturated) channel reads so, and the fit "
                             "takes those samples at face value; if it is clipped, leave the test out")
    return tuple(notes)


def _steady_motion(record: TestRecord, options: SignalOptions):
    """(cutoff, u low-passed at it, the steady-cycle window or None) of a periodic test: the
    cut-off is cutoff_multiple*f, held below 0.8 of Nyquist."""
    f = float(record.spec.frequency_hz)
    fs = record.sample_rate_hz
    cutoff = min(options.cutoff_multiple * f, 0.8 * 0.5 * fs)
    u_f = zero_phase_lowpass(record.u, cutoff, fs)
    window = steady_cycles(u_f, record.t, f, tolerance=options.steady_tolerance, skip_cycles=options.skip_cycles,
                           keep_at_least=MIN_STEADY_CYCLES)
    return cutoff, u_f, window


def check_record(record: TestRecord, options: SignalOptions = SignalOptions(), *, source: str = "") -> tuple[str, ...]:
    """prepare_test's checks of a record against its manifest entry, for a method that reads the
    record without prepare_test (the classical loop method): raise where the record cannot be
    the declared test (u still, at another frequency, or far from amplitude_m, as u in
    millimetres is); return the notes where it is merely odd (amplitude somewhat off, a clipped
    channel). Too few steady cycles are left to the caller's own message."""
    where = source or record.spec.file
    _check_frequency(record, where)
    _, _, window = _steady_motion(record, options)
    if window is None or window.n_cycles < MIN_STEADY_CYCLES:
        return ()
    return _check_amplitude(record, window, where) + _clipping_notes(record, where)


def prepare_test(record: TestRecord, options: SignalOptions = SignalOptions(), *, source="") -> PreparedTest:
    """Filter, differentiate, trim and decimate one periodic test (see the module docstring)."""
    spec = record.spec
    where = source or spec.file
    fs = record.sample_rate_hz
    f = float(spec.frequency_hz)
    _check_frequency(record, where)
    cutoff, u_f, window = _steady_motion(record, options)
    n_cycles = 0 if window is None else window.n_cycles
    if n_cycles < MIN_STEADY_CYCLES:
        raise SeriesFormatError(
            where,
            f"test '{spec.id}'",
            f"only {n_cycles} steady cycle(s) of {f:g} Hz found after trimming the ramps; "
            f"at least {MIN_STEADY_CYCLES} are needed (to analyse the other tests, leave this one out: "
            f"--exclude-test {spec.id} on the command line, load_series(..., exclude=[{spec.id!r}]) in Python)",
        )
    manifest_notes = _check_amplitude(record, window, where) + _clipping_notes(record, where)
    if options.remove_offsets:
        centred = without_steady_offsets(record, window)
        # the low-pass passes a constant unchanged: shift u_f rather than filter u again
        u_f = u_f - (record.u[0] - centred.u[0])
        record = centred
    measured_a = record.get("a")
    # the recorded a in the analysis band, for the check and the noise estimate below
    a_low = (zero_phase_lowpass(measured_a, cutoff, fs)
             if measured_a is not None and (options.check_accelerometer or options.accelerometer_noise) else None)
    notes: tuple[str, ...] = manifest_notes
    if measured_a is not None and options.check_accelerometer:
        problem = accelerometer_disagreement(measured_a, u_f, cutoff, fs, window, a_low=a_low)
        if problem:
            notes = (f"{where}: test '{spec.id}': {problem}; it is ignored and a is derived from u",)
            measured_a = None
    options = options.band_for(measured_a is not None)
    v_f = _velocity(record, cutoff, options)
    # the reversal band and weight are set from the kernel's velocity (v_f) in either case
    v_model = v_f
    if measured_a is not None and options.velocity_with_accelerometer and options.velocity_smoothing_s > 0:
        v_model = complementary_velocity(v_f, measured_a, fs, options.velocity_smoothing_s)
    # Without an accelerometer, the time derivative of the lightly smoothed velocity of the
    # velocity regressors, at the recorded rate, so that it is weighted and filtered exactly as
    # a measured a would be. The second derivative of the low-passed u (used before) is the
    # acceleration already smeared over 1/fc: the reversal weight then could not keep the rest
    # and breakaway out of it, and randomised virtual series (seeds 5-8, a removed) came out
    # with Ce +8..+12 % and Fmu -5..-10 %; with this one Ce +1.8..+2.4 % and Fmu -2.0..-4.4 %,
    # 0.9-2.0 % (Ce) and 1.7-5.7 % (Fmu) from the same series fitted with their accelerometer.
    # The second difference of the raw u was noisier (its near-Nyquist noise, multiplied by the
    # weight, folds into the band: Fmu -10.5 % on seed 2, against -5.2 % with a).
    a_raw = measured_a if measured_a is not None else _derived_acceleration(record, v_f, cutoff, options)

    averaged = False
    if measured_a is not None and options.periodic_acceleration and _holds_its_period(u_f, record.t, f, window):
        a_raw = np.array(measured_a, dtype=float)
        a_raw[window.start : window.stop] = periodic_component(a_raw, window)
        averaged = True
    # the tolerance: a whole ratio must not truncate to one less from rounding in the last digit
    decimation = max(1, int(fs / (options.samples_per_cutoff * cutoff) + 1e-9))
    index = kept_indices(window.start, window.stop, decimation, options.stagger_phases)
    speed = np.abs(v_f[window.start : window.stop])
    peak_speed = float(np.percentile(speed, 99.5))
    band_edge = reversal_band_share(peak_speed, options) * peak_speed
    keep = np.abs(v_f[index]) >= band_edge
    if keep.sum() < FEW_LIKELIHOOD_SAMPLES:
        notes = notes + (f"{where}: test '{spec.id}': only {int(keep.sum())} samples enter the likelihood (peak "
                         f"speed {1e3 * peak_speed:.3g} mm/s; the reversal band leaves out those under "
                         f"{1e3 * band_edge:.3g} mm/s): its own coefficients rest mostly on the other tests",)
    weight = reversal_weight(v_f, peak_speed, options)
    if options.presliding:
        amplitude = 0.5 * float(np.ptp(u_f[window.start : window.stop]))
        travel = travel_since_reversal(v_f, fs)
        turning, turn_travel = presliding_weight(travel, options.presliding, amplitude)
        weight = weight * turning
        keep = keep & (travel[index] >= turn_travel)
    weighted = not np.all(weight == 1.0)
    noise_sd = 0.0
    noise_excess = None
    if measured_a is not None and options.accelerometer_noise:
        # less the motion's band, whose curvature shows in second differences at high f/fs
        above_band = (np.asarray(measured_a, dtype=float) - a_low)[window.start : window.stop]
        noise_sd = mid_stroke_noise_sd(above_band, speed, options.noise_difference_order)
        if options.coloured_accelerometer_noise:
            noise_excess = _drift_of_accelerometer(record, a_low, u_f, v_f, window, cutoff, noise_sd,
                                                   options.drift_displacement_covariate)

    # a derived a is S(a): the kernel and the central differences spread each reversal's
    # acceleration pulse over a few milliseconds, and the weight then cut S(a) where the force's
    # own pulse is narrower, so filter(w*F) = Me*filter(w*S(a)) + ... no longer held (module
    # docstring, point 3)
    kernel_s = (options.velocity_smoothing_s
                if measured_a is None and options.kernel_on_force and options.velocity_smoothing_s > 0 else 0.0)
    force, displacement = record.F, record.u
    if kernel_s:
        force = acceleration_kernel(force, kernel_s * fs)
        displacement = acceleration_kernel(displacement, kernel_s * fs)
    F_f = zero_phase_lowpass(force * weight, cutoff, fs)
    u_model = zero_phase_lowpass(displacement * weight, cutoff, fs) if weighted or kernel_s else u_f
    a_f = zero_phase_lowpass(np.asarray(a_raw, dtype=float) * weight, cutoff, fs)
    constant_shape = None
    if options.free_constant and keep.any():
        constant_shape = zero_phase_lowpass(weight, cutoff, fs)[index] if weighted else np.ones(len(index))

    return PreparedTest(
        id=spec.id,
        file=spec.file,
        kind=spec.kind,
        frequency_hz=f,
        amplitude_m=float(spec.amplitude_m) if spec.amplitude_m is not None else float("nan"),
        payload_kg=float(spec.payload_kg or 0.0),
        order=spec.order,
        sample_rate_hz=fs,
        cutoff_hz=cutoff,
        decimation=decimation,
        window=window,
        index=index,
        t=record.t[index],
        F=project_out(F_f[index], constant_shape, keep),
        u=project_out(u_model[index], constant_shape, keep),
        v=v_model[index],
        a=project_out(a_f[index], constant_shape, keep),
        keep=keep,
        velocity_full=v_model,
        weight_full=weight if weighted else None,
        acceleration_noise_sd=noise_sd,
        acceleration_noise_excess=noise_excess,
        acceleration_averaged=averaged,
        acceleration_measured=measured_a is not None,
        notes=notes,
        constant_shape=constant_shape,
        kernel_s=kernel_s,
    )


def _drift_of_accelerometer(record, a_low, u_f, v_f, window, cutoff, white_sd, displacement_covariate=True):
    """The recorded acceleration's in-band noise beyond its white level
    (signals.coloured_noise_excess), with the low-passed force, displacement, its second time
    derivative and sign(v) as covariates: what the motion does beyond its harmonics shows in
    them as well, and the sampled sign(v) folds into the band as the accelerometer's friction
    step does.

    Why u'': the deck's own motion beyond the harmonics (the jolt of a breakaway, an oil column
    ringing after it) is acceleration the displacement transducer records too, while the
    accelerometer's drift is not. Without it, the white accelerometer of the fifth independent
    simulator (benchmarks/fifth_generator.py, seed 6) read an in-band excess on 5 of 17 tests,
    now on 2, and the errors-in-variables correction took that motion out of a's moments as if
    it were noise."""
    fs = record.sample_rate_hz
    span = slice(window.start, window.stop)
    return coloured_noise_excess(
        a_low[span], window.period_samples, cutoff, fs, white_sd,
        band_gain=lambda frequency: lowpass_power_gain(frequency, cutoff, fs),
        # their low-passes are most of the cost, skipped where nothing can be read (6 cycles or fewer)
        covariates=lambda: [zero_phase_lowpass(record.F, cutoff, fs)[span], u_f[span],
                            zero_phase_lowpass(np.sign(v_f), cutoff, fs)[span]]
        + ([second_derivative(u_f, fs)[span]] if displacement_covariate else []),
    )


# the tests the pre-sliding profile reads at most (prepare_series)
PROFILE_TESTS = 40


def prepare_series(series: Series, options: SignalOptions = SignalOptions()) -> list[PreparedTest]:
    """Prepare every periodic test of a series; broadband tests are not for the force fit.

    With options.presliding None the friction's pre-sliding distance is read from at most
    PROFILE_TESTS of the tests, prepared without it (signals._presliding.presliding_profile),
    and every test is prepared leaving out its turn; a note says so. Where the profile reads
    no turn but leans to one at travels up to options.presliding_floor
    (PreslidingProfile.leans_to_turn), or reads a shorter one, the floor's travel is left out."""
    records = series.periodic_tests
    if not records:
        raise SeriesFormatError(
            series.path or series.name, "tests", "no sine or triangle test to identify the force model from"
        )
    if options.presliding is not None:
        return [_prepared(series, record, options) for record in records]
    without_turn = replace(options, presliding=0.0)
    stride = max(1, int(np.ceil(len(records) / PROFILE_TESTS)))
    chosen = {k: _prepared(series, records[k], without_turn) for k in range(0, len(records), stride)}
    profile = presliding_profile(list(chosen.values()))
    travel = profile.presliding_m
    leans = profile.leans_to_turn(options.presliding_floor) and (
        not options.presliding_floor_needs_peak or profile.peaks_within(options.presliding_floor))
    if options.presliding_floor > travel and (travel > 0.0 or leans):
        travel = options.presliding_floor
    if travel <= 0.0:
        return [chosen[k] if k in chosen else _prepared(series, record, without_turn) for k, record in enumerate(records)]
    prepared = [_prepared(series, record, replace(options, presliding=travel)) for record in records]
    if profile.presliding_m <= 0.0:
        return prepared
    note = (f"pre-sliding friction: the friction turns over about {profile.presliding_m * 1e6:.0f} um of travel "
            f"after each reversal (Dahl's law fits {max(profile.travel_gain):.0f} nats better than sign(v) over "
            f"{len(chosen)} tests), so the samples within {PRESLIDING_TRAVELS * travel * 1e6:.0f} um "
            "after a reversal are left out as well; with sign(v) there Fmu and Me read low")
    return [replace(test, notes=test.notes + ((note,) if k == 0 else ())) for k, test in enumerate(prepared)]


def _prepared(series: Series, record: TestRecord, options: SignalOptions) -> PreparedTest:
    """prepare_test with the record's path for messages and, where asked, its payload's friction load."""
    source = str(series.path / record.spec.file) if series.path else record.spec.file
    test = prepare_test(record, options, source=source)
    if options.payload_friction:
        test = replace(test, friction_load=friction_load(series.table, test.payload_kg))
    return test
