"""The candidate effects: what the base force model F = Me*a + Ke*u + (Ce*|v|^alpha + Fmu)*sign(v)
leaves out, each as a small object.

Every force-term effect adds k regressor columns that enter linearly for fixed values of its
nonlinear ("grid") parameters; channel_delay instead re-reads the force channel at a shifted
time. An effect is pure: it turns an EffectData into columns, and fitted coefficients into
physical parameters, and never reads files, plots or samples.

Priors: a linear coefficient c_k ~ N(0, prior_sd_k^2) with prior_sd_k set from the base fit's
scale (stated per effect); a grid parameter is uniform over its grid (log-spaced grids:
log-uniform). The grids bound what can be found (documented in docs/diagnosis.md).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field
from typing import Mapping

import numpy as np
from scipy import signal as _sp_signal

from bayes_sst.effects._data import EffectData


@dataclass(frozen=True)
class Parameter:
    """A reported effect parameter: name, SI unit, and its prior in words."""

    name: str
    unit: str
    prior: str


@dataclass(frozen=True)
class Effect:
    """Base of the effect library (abstract: use the concrete effects below).

    name : the effect's key ('stiction', ...); physics : one line; equation : the added term;
    parameters : the reported parameters with their priors; grid : nonlinear parameters and
    the values profiled over (empty for none); coefficients : names of the linear coefficients.
    """

    name: str = ""
    physics: str = ""
    equation: str = ""
    parameters: tuple[Parameter, ...] = ()
    grid: Mapping[str, tuple[float, ...]] = field(default_factory=dict)
    coefficients: tuple[str, ...] = ()
    positive: tuple[str, ...] = ()
    # base coefficients whose test-to-test variation the effect describes (drift): such an
    # effect changes the per-test coefficients, not the within-test residual
    between_tests: tuple[str, ...] = ()
    # base coefficients whose per-test values take in the part of the effect's force that
    # changes from test to test (the hinge's level grows as A^2 in each test's Fmu and Ce; the
    # Stribeck rise lifts the mean friction of the slower tests more). The effect acts within
    # the tests too, so it is selected as one that does; but what it removes shows mostly as
    # those coefficients' test-to-test scatter, where the diagnosis reads its shrink (as drift's)
    absorbed_by: tuple[str, ...] = ()
    # selectable by its coefficient's z alone (bayes_sst.diagnosis COEFFICIENT_Z): one fixed
    # column, no grid, whose leave-one-test-out score is weak by construction because the base
    # model's per-test coefficients absorb most of it (drift's trend, the cubic's A^2*u part)
    z_selectable: bool = False
    # the z that selection by the coefficient alone asks of this effect; None: the diagnosis's
    # COEFFICIENT_Z
    coefficient_z: float | None = None
    # for an effect without linear coefficients: the grid setting that is the base model itself
    # (a delay of 0); its distance from the read setting, in the setting's sds, is the effect's
    # amplitude z (bayes_sst.diagnosis MIN_AMPLITUDE_Z), as a coefficient's is for the others
    null_setting: Mapping[str, float] = field(default_factory=dict)
    # the power p of the test amplitude A that the effect's force grows with at a fixed
    # within-test shape (the cubic A^3, the hinge A^2); the diagnosis checks that the data follow
    # that law better than the same shape with no amplitude law (AmplitudeFree, below). None: no
    # such law to check
    amplitude_power: float | None = None

    def settings(self) -> list[dict[str, float]]:
        """Every combination of grid values ([{}] when the effect has no grid parameter)."""
        out = [{}]
        for key, values in self.grid.items():
            out = [dict(s, **{key: float(v)}) for s in out for v in values]
        return out

    def refine(self, setting: Mapping[str, float]) -> list[dict[str, float]]:
        """Settings on a finer local grid around `setting` (the best of the coarse grid), tried
        before the effect is scored; empty when the coarse grid is fine enough."""
        return []

    def polish(self, setting: Mapping[str, float]) -> list[dict[str, float]]:
        """Settings on a still finer grid around `setting` (the best after refine), tried again
        around each new best until none beats it; empty when refine is fine enough."""
        return []

    def grid_weight(self, setting: Mapping[str, float]) -> float:
        """Prior weight of a coarse grid setting relative to the others: 1 for a grid whose
        spacing is that of its prior (uniform steps for a uniform prior, log steps for a
        log-uniform one); a grid that coarsens where its prior does not returns the width of
        the setting's cell, so that the grid posterior keeps the stated prior."""
        return 1.0

    def coefficient_signs(self, base: Mapping[str, float]) -> dict[str, float]:
        """The physical sign (+1 or -1) of each linear coefficient that has one: a fit whose
        coefficient has the other sign leaves the effect at its bound (the base model)."""
        return {name: 1.0 for name in self.positive}

    def at_setting_bound(self, setting: Mapping[str, float]) -> bool:
        """Whether the setting is at a bound beyond which the effect stops being itself (a
        resonance damped so heavily that it has no peak): such a fit is the base model, unless
        the fit at past_bound is no better by more than a margin (the optimum is at the bound,
        not beyond it; bayes_sst.diagnosis._screen.PAST_BOUND_NATS)."""
        return False

    def past_bound(self, setting: Mapping[str, float]) -> dict[str, float] | None:
        """A setting beyond the bound that `setting` sits at (at_setting_bound), scored to tell
        a likelihood still rising past the bound from one that peaks there; None: no such test."""
        return None

    def columns(self, test: EffectData, setting: Mapping[str, float], alpha: float,
                base: Mapping[str, float] | None = None) -> np.ndarray:
        """(k, n_kept) regressors added to the base design; (0, n) for a response-only effect.
        base: the base fit's population values (Me, Ke, Ce, Fmu), for effects scaled by them."""
        return np.zeros((0, len(test.index)))

    @property
    def reads_acceleration(self) -> bool:
        """Whether the effect's columns read the acceleration (it gives acceleration_columns)."""
        return type(self).acceleration_columns is not Effect.acceleration_columns

    def acceleration_columns(self, test: EffectData, setting: Mapping[str, float],
                             a: np.ndarray) -> np.ndarray | None:
        """(K, k, n_kept): the effect's columns with the recorded acceleration replaced by the
        K signals `a` (K, len(test.F_full)), for columns linear in it; None when the columns do
        not read the acceleration. The diagnosis passes the accelerometer's noise through
        here for its errors-in-variables correction."""
        return None

    def response(self, test: EffectData, setting: Mapping[str, float]) -> np.ndarray | None:
        """The force to explain instead of the recorded one, or None to keep it."""
        return None

    def prior_sd(self, base: Mapping[str, float]) -> np.ndarray:
        """Prior sd of each linear coefficient, SI, from the base fit's population values."""
        return np.zeros(0)

    def report(self, coef: np.ndarray, coef_sd: np.ndarray, setting: Mapping[str, float],
               base: Mapping[str, float]) -> dict[str, dict[str, float]]:
        """Physical parameters {name: {'mean', 'sd'}} from the fitted coefficients and grid values."""
        return {}

    def immaterial(self, params: Mapping[str, Mapping[str, float]], grid_edge: Mapping[str, str],
                   base: Mapping[str, float] | None = None) -> str | None:
        """Why a reading (params as report gives them; grid_edge: the grid parameters whose best
        value is the grid's 'lower' or 'upper' end; base: the fit's base values) is too small to
        be a finding however well the data resolve it, or None. The diagnosis does not select an
        effect so read."""
        return None


def _value(mean: float, sd: float) -> dict[str, float]:
    return {"mean": float(mean), "sd": float(sd)}


# the least static-over-kinetic excess (Fs/Fk - 1) counted as stiction (Stiction.immaterial)
LEAST_STATIC_EXCESS = 0.05
# ... where the Stribeck velocity is not resolved; the breakaway check's own threshold
# (bayes_sst.diagnosis._breakaway.BREAKAWAY_EXCESS)
UNRESOLVED_STATIC_EXCESS = 0.15
# the least specimen mass counted as a specimen, as a share of the deck's effective mass Me
# (Specimen.immaterial)
LEAST_SPECIMEN_SHARE = 0.01


@dataclass(frozen=True)
class Stiction(Effect):
    """Static friction above kinetic friction at the start of motion (Stribeck curve):

        F_st = (Fs - Fk)*exp(-(|v|/v_s)^2)*sign(v),   static_ratio = Fs/Fk = 1 + (Fs - Fk)/Fmu.

    The regressor filter(exp(-(|v|/v_s)^2) sign v) needs the samples near velocity reversals
    and a band wide enough to keep the peak narrow: the diagnosis scores it on its reversal view
    (12f; weight 0 below 2 % of the peak speed, where v crosses zero, rising to 1 at 7 %, so
    the peak sits mostly under the ramp, weighted like the force; v from the displacement under
    a 10 ms kernel, with its part above the kernel's band from the integrated acceleration
    where one is recorded, which keeps the breakaway's corner). Prior: Fs - Fk ~ N(0, Fmu^2);
    v_s log-uniform on its grid. At 200 Hz a peak narrower than one sample (v_s = 5 mm/s on a
    fast test) is at the edge of what the data show.
    """

    name: str = "stiction"
    physics: str = "static friction above kinetic friction at each start and reversal (Stribeck curve)"
    equation: str = "(Fs - Fk)*exp(-(|v|/v_s)^2)*sign(v)"
    parameters: tuple[Parameter, ...] = (
        Parameter("static_ratio", "-", "1 + N(0, 1)"),
        Parameter("stribeck_velocity", "m/s", "log-uniform 0.5-40 mm/s"),
    )
    grid: Mapping[str, tuple[float, ...]] = field(
        default_factory=lambda: {"stribeck_velocity": tuple(np.geomspace(0.0005, 0.04, 13))})
    coefficients: tuple[str, ...] = ("Fs_minus_Fk",)
    positive: tuple[str, ...] = ("Fs_minus_Fk",)
    # The Stribeck rise lifts each test's mean friction by what its speed profile spends near
    # v = 0, which the base model's per-test Fmu and Ce take in: on the reversal view their
    # spread sat at its grid's top (18 %) on 9 of 11 true stictions (seventh simulator seeds
    # 100, 106, 200-207 bar 203, LuGre strong, sixth seed 406, 2026-12-01), and the residual
    # shrink was under 0.7 on 5 of them (-0.26 to 0.47: with stiction the spread falls and alpha
    # moves, as for the hinge), while the share of the per-test Ce and Fmu scatter explained was
    # 0.97-1.00 on all 11
    absorbed_by: tuple[str, ...] = ("Ce", "Fmu")

    def columns(self, test, setting, alpha, base=None):
        vs = setting["stribeck_velocity"]
        v = test.v_full
        return test.filtered(np.exp(-(v / vs) ** 2) * np.sign(v))[None]

    def prior_sd(self, base):
        return np.array([abs(base["Fmu"])])

    def report(self, coef, coef_sd, setting, base):
        return {"static_ratio": _value(1.0 + coef[0] / base["Fmu"], coef_sd[0] / abs(base["Fmu"])),
                "stribeck_velocity": _value(setting["stribeck_velocity"], 0.0)}

    def immaterial(self, params, grid_edge, base=None):
        """Static friction less than LEAST_STATIC_EXCESS over the kinetic is no finding: every
        lubricated contact has a Stribeck curve of a few percent, and each simulator we checked
        against gives its clean tables one (static ratio 1.00-1.03 or 1.00-1.05), which the
        reversal view reads (seventh simulator: 1.015-1.036 on 11 of 48 clean series, within
        0.5 % of the truth). A Stribeck velocity at the grid's lower end is not resolved: the
        column is then a spike on the reversal samples, which other reversal transients also
        fill (a clean seventh series read 1.067 at 0.5 mm/s, truth 1.008 at 9.4 mm/s), so the
        breakaway check's excess (UNRESOLVED_STATIC_EXCESS) is asked of it."""
        if "static_ratio" not in params:  # nothing read
            return None
        ratio = float(params["static_ratio"]["mean"])
        if not math.isfinite(ratio):  # no reading; the amplitude gate refuses it
            return None
        unresolved = grid_edge.get("stribeck_velocity") == "lower"
        least = UNRESOLVED_STATIC_EXCESS if unresolved else LEAST_STATIC_EXCESS
        if ratio - 1.0 >= least:
            return None
        where = " with the Stribeck velocity at the grid's lower end" if unresolved else ""
        return (f"static friction {100 * (ratio - 1.0):.1f} % over the kinetic{where}, "
                f"under the {100 * least:.0f} % that counts as stiction")


@dataclass(frozen=True)
class NonlinearStiffness(Effect):
    """Cubic strut stiffness of the gas struts (large-stroke term the study drops):

        F_k3 = K'e*(u/h)^2*u,   h the strut height; the gas strut gives K'e = 0.5*(gamma*h/l0 - 1)*Ke.

    Prior: K'e ~ N(0, (3*Ke)^2). The gas law gives K'e/Ke = 0.5*(gamma*h/l0 - 1): 0.55 for the
    SST's struts, up to about 3 for a short gas column (h/l0 = 5, gamma = 1.4); the -1 is the
    struts' inclination, a softening -Ke/2. With sd Ke the prior pulled a cubic of three times
    the SST's gas value 8 % toward zero, and one of 5*Ke (soft struts, an independent generator)
    came out 43 % low (13 % with sd 3*Ke).

    Sign: K'e takes the sign of gamma*h/l0 - 1 that the table description gives (base
    "cubic_sign", set by the diagnosis from the series; hardening when the description lacks
    gamma or l0); a fit of the other sign is at its bound. Why: weak stiction with a LuGre
    friction law (an independently written generator, Fs/Fk = 1.32 at 5 mm/s, 200 Hz) read as
    K'e = -8.6e5 +- 2.0e5 N/m on a table whose struts harden, and was selected in its place.
    """

    name: str = "nonlinear_stiffness"
    physics: str = "cubic strut stiffness at large stroke"
    equation: str = "K'e*(u/h)^2*u"
    parameters: tuple[Parameter, ...] = (Parameter("cubic_stiffness", "N/m", "N(0, (3 Ke)^2)"),)
    coefficients: tuple[str, ...] = ("cubic_stiffness",)
    z_selectable: bool = True
    amplitude_power: float | None = 3.0

    def coefficient_signs(self, base):
        return {"cubic_stiffness": float(base.get("cubic_sign", 1.0))}

    def columns(self, test, setting, alpha, base=None):
        u = test.u_full
        return test.filtered(u**3 / test.strut_h**2)[None]

    def prior_sd(self, base):
        return np.array([3.0 * abs(base["Ke"])])

    def report(self, coef, coef_sd, setting, base):
        return {"cubic_stiffness": _value(coef[0], coef_sd[0])}


@dataclass(frozen=True)
class PositionFriction(Effect):
    """Hinge friction growing with displacement:

        F_p = Fp*(u/h)^2*sign(v).

    Prior: Fp ~ N(0, (Fmu*(h/stroke)^2)^2), i.e. up to about Fmu at full stroke.
    """

    name: str = "position_friction"
    physics: str = "hinge friction growing with the square of the displacement"
    equation: str = "Fp*(u/h)^2*sign(v)"
    parameters: tuple[Parameter, ...] = (Parameter("position_friction", "N", "N(0, (Fmu*(h/u_max)^2)^2)"),)
    coefficients: tuple[str, ...] = ("position_friction",)
    positive: tuple[str, ...] = ("position_friction",)
    # One fixed column like the cubic, and weak in the leave-one-test-out score for the same
    # reason: within a sine test (u/h)^2*sign(v) is mostly each test's own Fmu*sign(v), which
    # the per-test coefficients take. Its z without a hinge is larger than the cubic's, so it
    # asks 8: of the physical sign it reached 5.7 on clean series of four simulators (fifth
    # simulator, seed 56) and 7.6 beside an unmodelled 2 ms delay (first independent generator,
    # seed 4, where the amplitude law vetoes it too); a z of -9.5 (valve generator, seed 103) is
    # at the sign bound and never selected. 12, from 2026-11-30 until the amplitude law, missed
    # the valve generator's strong hinge at 9.7 (docs/diagnosis.md, the coefficient rule).
    # Those z's were read at the profiled alpha; with alpha integrated out (since 2026-11-30
    # late: the hinge trades with the damping exponent, diagnosis._screen.alpha_marginal_coefficients)
    # a hinge beside a delay fell from 10.7 to 7.5 and one beside a drift from 10.4 to 6.6
    # (sixth simulator, seeds 119 and 117), the true ones stayed at 9.6-73 (the valve
    # generator's strong one, the sixth's seeds 104-122)
    z_selectable: bool = True
    coefficient_z: float | None = 8.0
    amplitude_power: float | None = 2.0
    # Its in-sample residual shrink says little: with the hinge in the model the (Ce, Fmu) spread
    # reads lower, the per-test coefficients are pulled together, and the residual RMS can rise
    # (stroke view, 2026-12-01: seventh simulator seed 110 -0.12, sixth simulator's seeds 122,
    # 610, 616 -0.07 to -0.14, LuGre generator's weak hinge 0.00; under 0.7 on 10 of 20 true
    # hinges of five simulators), while the share of the per-test Ce and Fmu scatter it explains
    # was 0.84-1.00 on each of the 20
    absorbed_by: tuple[str, ...] = ("Ce", "Fmu")

    def columns(self, test, setting, alpha, base=None):
        return test.filtered((test.u_full / test.strut_h) ** 2 * np.sign(test.v_full))[None]

    def prior_sd(self, base):
        return np.array([abs(base["Fmu"]) * (base.get("strut_h", 1.0) / base.get("stroke", 0.1)) ** 2])

    def report(self, coef, coef_sd, setting, base):
        return {"position_friction": _value(coef[0], coef_sd[0])}


def sdof_base_shear(a: np.ndarray, frequency_hz: float, damping: float, sample_rate_hz: float) -> np.ndarray:
    """Base shear per unit specimen mass, a + x'', of a specimen x'' + 2*z*w*x' + w^2*x = -a
    (along the last axis of a):

        S(s)/A(s) = (2*z*w*s + w^2)/(s^2 + 2*z*w*s + w^2),

    discretised by the bilinear transform with the natural frequency pre-warped, started at rest.
    """
    # a copy of the cached design: scipy's filter wants a writeable buffer
    return _sp_signal.sosfilt(_sdof_sections(float(frequency_hz), float(damping), float(sample_rate_hz)).copy(), a, axis=-1)


@functools.lru_cache(maxsize=1024)
def _sdof_sections(frequency_hz: float, damping: float, sample_rate_hz: float) -> np.ndarray:
    # pre-warp, so that the discrete filter's natural frequency is exactly f_s
    w = 2.0 * sample_rate_hz * math.tan(math.pi * frequency_hz / sample_rate_hz)
    z, p, k = _sp_signal.bilinear_zpk(*_sp_signal.tf2zpk([2.0 * damping * w, w * w], [1.0, 2.0 * damping * w, w * w]),
                                      fs=sample_rate_hz)
    sections = _sp_signal.zpk2sos(z, p, k)
    sections.flags.writeable = False  # shared by every call with this design
    return sections


# the damping range the polish may reach, a little beyond the refinement's 1-8 %. A fit at its
# top has no resonant peak, a smooth filter of a rather than a specimen, and is the base model
# (Specimen.at_setting_bound): beside a 2.1 ms force delay (valve generator, seed 18) the
# "specimen" that followed the delay went to 19.5 % damping without the bound, and was
# selected as a second effect at 8 % (the refinement's top) before the polish and at 10 % after
POLISHED_DAMPING = (0.008, 0.1)
# ... except where the likelihood does not rise past the top: a fit at 1.5 times the top damping
# is scored, and the bound binds only if that fit is better by more than PAST_BOUND_NATS
# (Specimen.past_bound; bayes_sst.diagnosis._screen)
PAST_BOUND_FACTOR = 1.5


@dataclass(frozen=True)
class Specimen(Effect):
    """A flexible specimen (mass m_s, natural frequency f_s, damping ratio zeta_s) on the deck:

        F_s = m_s*(a + x''),   x'' + 2*zeta_s*w_s*x' + w_s^2*x = -a,   w_s = 2*pi*f_s,

    its base shear. The column is the shear per unit mass driven by the recorded acceleration;
    its rigid part m_s*a moves into the coefficient m_s, so Me drops by m_s when it is added.
    Prior: m_s ~ N(0, Me^2); f_s log-uniform 0.5-25 Hz, zeta_s on {2, 5} % (the best setting is
    then refined, f_s within +-6 % and zeta_s from 1 to 8 %, and polished, f_s in 0.5 % steps and
    zeta_s by factors 0.8-1.25 within 0.8-10 %). The grid reaches down among the test
    frequencies because a tall specimen's first mode (a frame model at 1-2 Hz) lies there: each
    sine test's own Me and damping then absorb the shear at its frequency, and the specimen
    shows in how they change from test to test and in the transients. Until 2026-11-26 the grid
    began at 2 Hz, and a 2 t specimen at 1.5 Hz on the independent generator (RMS 2498 N against
    a 1143 N floor) was not found at all.
    """

    name: str = "specimen"
    physics: str = "a flexible specimen whose base shear loads the deck"
    equation: str = "m_s*(a + x''),  x'' + 2*zeta_s*w_s*x' + w_s^2*x = -a"
    parameters: tuple[Parameter, ...] = (
        Parameter("specimen_mass", "kg", "N(0, Me^2)"),
        Parameter("specimen_frequency", "Hz", "log-uniform 0.5-25 Hz"),
        Parameter("specimen_damping", "-", "uniform on {0.02, 0.05}"),
    )
    grid: Mapping[str, tuple[float, ...]] = field(default_factory=lambda: {
        "specimen_frequency": tuple(np.round(np.geomspace(0.5, 25.0, 35), 3)),
        "specimen_damping": (0.02, 0.05),
    })
    coefficients: tuple[str, ...] = ("specimen_mass",)
    positive: tuple[str, ...] = ("specimen_mass",)

    def immaterial(self, params, grid_edge, base=None):
        """A specimen lighter than LEAST_SPECIMEN_SHARE of the deck's effective mass is no finding:
        the specimens a lab mounts, and those of every simulator we check against (0.7-5 t), are
        tons, while the specimens read where there was none were tens of kilograms (29 kg at
        2.5 Hz beside an unmodelled hinge on the first independent generator; 47 kg at 0.82 Hz on
        a clean series of the seventh simulator, 34.4 +- 21.7 nats, seed 32)."""
        if base is None or "specimen_mass" not in params:
            return None
        mass, deck = float(params["specimen_mass"]["mean"]), abs(float(base["Me"]))
        if not (math.isfinite(mass) and math.isfinite(deck)) or mass >= LEAST_SPECIMEN_SHARE * deck:
            return None
        return (f"a specimen of {mass:.0f} kg, {100 * mass / deck:.1f} % of the deck's effective mass, under the "
                f"{100 * LEAST_SPECIMEN_SHARE:.0f} % that counts as a specimen")

    def refine(self, setting):
        # the coarse frequency grid steps by 12 %, and an imperfect resonance leaves a misfit
        # in the tests that excite it, which a second effect then picks up (a 3 t specimen at
        # 9 Hz with 3 % damping, fitted at 8.9 Hz and 5 %, was followed by a -0.3 ms delay on
        # an independent generator's series)
        f0 = setting["specimen_frequency"]
        return [{"specimen_frequency": float(np.round(f0 * k, 4)), "specimen_damping": z}
                for k in np.geomspace(1 / 1.06, 1.06, 7) for z in (0.01, 0.02, 0.03, 0.05, 0.08)]

    def polish(self, setting):
        # the refined grid's steps (2 % in frequency, damping 0.01-0.08) are still coarse for a
        # lightly damped resonance, whose peak response goes as m_s/zeta_s: on the valve
        # generator's seed 16 (1.9 t at 12.97 Hz, 3.7 % damping, 256 Hz) the refined best was
        # 13.03 Hz at 5 %, with the mass 37 % high; the true frequency at 4 % scored 124 nats
        # more, with the mass 11 % high
        f0, z0 = setting["specimen_frequency"], setting["specimen_damping"]
        return [{"specimen_frequency": float(np.round(f0 * k, 4)), "specimen_damping": float(np.round(z0 * m, 5))}
                for k in np.geomspace(1 / 1.015, 1.015, 7) for m in (0.8, 0.9, 1.0, 1.12, 1.25)
                if not (k == 1.0 and m == 1.0) and POLISHED_DAMPING[0] <= z0 * m <= POLISHED_DAMPING[1]]

    def at_setting_bound(self, setting):
        return setting["specimen_damping"] >= POLISHED_DAMPING[1] - 1e-12

    def past_bound(self, setting):
        # half as damped again: a smooth filter of a (the delay-following "specimen" of the
        # valve generator's seed 18, 19.5 % unbounded) still gains there; a real resonance the
        # search found at the top does not (the sixth simulator's seed 408, 3.9 t at 20.0 Hz,
        # 5.2 %: at the search's 18.37 Hz, +203.3 nats at 10 %, +204.2 at 12.5 %, +203.5 at 15 %,
        # +199.1 at 20 %, a top flat in damping along the ridge that trades it for frequency)
        return dict(setting, specimen_damping=PAST_BOUND_FACTOR * POLISHED_DAMPING[1])

    def columns(self, test, setting, alpha, base=None):
        # from the record's start, where the table rests, so no start-up transient enters
        shear = sdof_base_shear(test.a_record, setting["specimen_frequency"], setting["specimen_damping"],
                                test.sample_rate_hz)[test.lo:]
        return test.filtered(shear)[None]

    def acceleration_columns(self, test, setting, a):
        shear = sdof_base_shear(a, setting["specimen_frequency"], setting["specimen_damping"], test.sample_rate_hz)
        return test.filtered(shear)[:, None, :]

    def prior_sd(self, base):
        return np.array([abs(base["Me"])])

    def report(self, coef, coef_sd, setting, base):
        return {"specimen_mass": _value(coef[0], coef_sd[0]),
                "specimen_frequency": _value(setting["specimen_frequency"], 0.0),
                "specimen_damping": _value(setting["specimen_damping"], 0.0)}


@dataclass(frozen=True)
class ChannelDelay(Effect):
    """The force channel recorded with a lag d behind the motion channels:

        F_recorded(t) = F(t - d),   so the model is fitted to F_recorded(t + d).

    No linear coefficient (its amplitude gate reads d's distance from null_setting, 0); d uniform
    on -10 to 40 ms, searched in 0.25 ms steps up to 12 ms and 0.5 ms steps beyond (the misfit
    of a delay of 15 ms or more is large, so its peak is broad enough in nats for the coarser
    step), the best step then refined to 0.05 ms. A
    negative d is a force that leads the motion: motion channels read through a slower
    conditioning filter than the load cell's.
    """

    name: str = "channel_delay"
    physics: str = "force channel recorded with a time lag relative to the motion channels"
    equation: str = "F_recorded(t) = F(t - d)"
    parameters: tuple[Parameter, ...] = (Parameter("delay", "s", "uniform -10 to 40 ms"),)
    grid: Mapping[str, tuple[float, ...]] = field(default_factory=lambda: {"delay": tuple(np.round(
        np.concatenate([np.arange(-0.01, 0.01201, 0.00025), np.arange(0.0125, 0.04001, 0.0005)]), 6))})
    null_setting: Mapping[str, float] = field(default_factory=lambda: {"delay": 0.0})

    def _grid_index(self, delay: float) -> tuple[np.ndarray, int]:
        values = np.asarray(self.grid["delay"])
        return values, int(np.argmin(np.abs(values - delay)))

    def refine(self, setting):
        # +-0.8 of the coarse step below the best value (above it, at the grid's first value)
        d0 = setting["delay"]
        values, i = self._grid_index(d0)
        half = 0.8 * (values[i] - values[i - 1] if i > 0 else values[1] - values[0])
        return [{"delay": float(np.round(d0 + step, 6))} for step in np.arange(-half, half + 1e-9, 0.00005)
                if abs(step) > 1e-9]

    def grid_weight(self, setting):
        # the cell between the midpoints to either neighbour (one-sided at the ends), in units of
        # the finest step; rounded as the grid's values are, so that equal steps weigh exactly 1
        values, i = self._grid_index(setting["delay"])
        return float(np.round(np.gradient(values)[i] / np.min(np.diff(values)), 6))

    def response(self, test, setting):
        return test.force_at(setting["delay"])

    def report(self, coef, coef_sd, setting, base):
        return {"delay": _value(setting["delay"], 0.0)}


@dataclass(frozen=True)
class Drift(Effect):
    """Friction and damping falling together over the campaign (oil warming, bearings running in):

        Fmu_j = Fmu*(1 - d*s_j),   Ce_j = Ce*(1 - d*s_j),   s_j in [0, 1] the campaign position,

    i.e. the column -s_j*(Fmu*filter(sign v) + Ce*filter(|v|^alpha sign v)) with Fmu, Ce the
    base fit's values and the coefficient d. One common rate, because within a test friction
    and damping are nearly collinear: two separate rates were tried and traded off against each
    other (0.15 and 0.15 came back as 0.23 and 0.08). Prior: d ~ N(0, 0.5^2).
    """

    name: str = "drift"
    physics: str = "friction and damping falling over the campaign order (oil warming)"
    equation: str = "-d*s*(Fmu + Ce*|v|^alpha)*sign(v)"
    parameters: tuple[Parameter, ...] = (Parameter("drift", "-", "N(0, 0.5^2)"),)
    coefficients: tuple[str, ...] = ("drift",)
    between_tests: tuple[str, ...] = ("Ce", "Fmu")
    z_selectable: bool = True

    def columns(self, test, setting, alpha, base=None):
        if base is None:
            raise ValueError("the drift effect needs the base fit's Fmu and Ce")
        return -test.position * (base["Fmu"] * test.sign() + base["Ce"] * test.damping(alpha))[None]

    def prior_sd(self, base):
        return np.array([0.5])

    def report(self, coef, coef_sd, setting, base):
        return {"drift": _value(coef[0], coef_sd[0])}


@dataclass(frozen=True)
class StrutInertia(Effect):
    """Inertia of the inclined struts, growing with the stroke (the study's strut mass term):

        F_si = M'*(u/h)^2*a,

    the struts' effective mass rising with their inclination. Prior: M' ~ N(0, Me^2).
    """

    name: str = "strut_inertia"
    physics: str = "strut inertia growing with the struts' inclination"
    equation: str = "M'*(u/h)^2*a"
    parameters: tuple[Parameter, ...] = (Parameter("strut_inertia", "kg", "N(0, Me^2)"),)
    coefficients: tuple[str, ...] = ("strut_inertia",)
    positive: tuple[str, ...] = ("strut_inertia",)

    def columns(self, test, setting, alpha, base=None):
        return test.filtered((test.u_full / test.strut_h) ** 2 * test.a_raw)[None]

    def acceleration_columns(self, test, setting, a):
        return test.filtered((test.u_full / test.strut_h) ** 2 * a)[:, None, :]

    def prior_sd(self, base):
        return np.array([abs(base["Me"])])

    def report(self, coef, coef_sd, setting, base):
        return {"strut_inertia": _value(coef[0], coef_sd[0])}


@dataclass(frozen=True)
class StrutDamping(Effect):
    """Viscous damping in the struts' hinges and gas (the study's strut damping term):

        F_sd = Cs*v,

    linear in the velocity, beside the power-law Ce*|v|^alpha. Prior: Cs ~ N(0, (Ce/0.1)^2) N*s/m.
    """

    name: str = "strut_damping"
    physics: str = "linear viscous damping of the struts"
    equation: str = "Cs*v"
    parameters: tuple[Parameter, ...] = (Parameter("strut_damping", "N*s/m", "N(0, (10*Ce)^2)"),)
    coefficients: tuple[str, ...] = ("strut_damping",)
    positive: tuple[str, ...] = ("strut_damping",)

    def columns(self, test, setting, alpha, base=None):
        return test.filtered(test.v_full)[None]

    def prior_sd(self, base):
        return np.array([10.0 * abs(base["Ce"])])

    def report(self, coef, coef_sd, setting, base):
        return {"strut_damping": _value(coef[0], coef_sd[0])}


def steady_amplitude(test: EffectData) -> float:
    """A test's displacement amplitude, half the peak-to-peak of its steady window (a sensor
    offset, up to a quarter of a 2 mm test's amplitude, does not enter it)."""
    return 0.5 * float(np.ptp(test.u_full))


@dataclass(frozen=True)
class AmplitudeFree(Effect):
    """An effect with its amplitude law taken out: in test j its columns times
    (A_ref/A_j)^p, A_j the test's amplitude (steady_amplitude), p the effect's amplitude_power,
    A_ref the largest amplitude of the series. Within each test the shape is the effect's own;
    across tests the force it adds no longer grows as A^p but stays the same at every amplitude.

    The rival an amplitude law is checked against: a misfit that each test's friction leaves at
    its reversals carries a third harmonic of about the same force at every amplitude, and a
    shared cubic fits it (K'e of a few MN/m on clean series of an independent simulator, per
    test K'e falling as 1/A^3 from 2.4e9 N/m at 5 mm to 4e6 at 50 mm). A strut cubic's or a
    hinge's own force grows as A^3 or A^2, so where the tests span amplitudes the data tell the
    two apart. Same coefficient, prior and sign as the effect.
    """

    inner: Effect | None = None
    reference_m: float = 1.0

    @classmethod
    def of(cls, effect: Effect, tests) -> "AmplitudeFree":
        # the accelerometer-noise correction would need the scaled noise columns too
        if effect.amplitude_power is None or effect.reads_acceleration:
            raise ValueError(f"{effect.name}: AmplitudeFree needs an amplitude law and columns that do not "
                             "read the acceleration")
        return cls(name=f"{effect.name}.amplitude_free", physics=f"{effect.physics}, with no amplitude law",
                   equation=f"({effect.equation})*(A_ref/A)^{effect.amplitude_power:g}",
                   coefficients=effect.coefficients, inner=effect,
                   reference_m=max(steady_amplitude(t) for t in tests))

    def columns(self, test, setting, alpha, base=None):
        scale = (self.reference_m / max(steady_amplitude(test), 1e-12)) ** self.inner.amplitude_power
        return self.inner.columns(test, setting, alpha, base) * scale

    def coefficient_signs(self, base):
        return self.inner.coefficient_signs(base)

    def prior_sd(self, base):
        return self.inner.prior_sd(base)


FORCE_EFFECTS: tuple[Effect, ...] = (
    Stiction(), NonlinearStiffness(), PositionFriction(), Specimen(), ChannelDelay(), Drift(),
    StrutInertia(), StrutDamping(),
)


@dataclass(frozen=True)
class OilColumn(Effect):
    """Oil-column compliance in the actuators: a resonance between command and deck motion,

        H(f) = a(f)/a_cmd(f) = g*exp(-2j*pi*f*tau)*f_o^2/(f_o^2 - f^2 + 2j*zeta_o*f_o*f),

    against the base model's rigid table in a lagging loop, H = g*exp(-2j*pi*f*tau)/(1 + j*f/f_c)
    (bayes_sst.diagnosis._oil). Seen in broadband tests (the H1 frequency response of
    bayes_sst.oil). Prior: f_o log-uniform 5-80 Hz, zeta_o 0.02-0.8, tau 0-30 ms, g > 0.
    """

    name: str = "oil_column"
    physics: str = "oil-column compliance: a resonance between command and deck motion"
    equation: str = "H(f) = g*exp(-2j*pi*f*tau)*f_o^2/(f_o^2 - f^2 + 2j*zeta_o*f_o*f)"
    parameters: tuple[Parameter, ...] = (
        Parameter("oil_frequency", "Hz", "log-uniform 5-80 Hz"),
        Parameter("oil_damping", "-", "log-uniform 0.02-0.8"),
    )
    grid: Mapping[str, tuple[float, ...]] = field(default_factory=lambda: {
        "oil_frequency": tuple(np.round(np.geomspace(5.0, 80.0, 121), 4)),
        "oil_damping": tuple(np.round(np.geomspace(0.02, 0.8, 25), 5)),
    })

    @staticmethod
    def frf(frequency_hz: np.ndarray, oil_frequency: float, oil_damping: float) -> np.ndarray:
        """The resonance's shape f_o^2/(f_o^2 - f^2 + 2j*zeta_o*f_o*f) (gain 1)."""
        f = np.asarray(frequency_hz, dtype=float)
        return oil_frequency**2 / (oil_frequency**2 - f * f + 2j * oil_damping * oil_frequency * f)


EFFECTS: tuple[Effect, ...] = FORCE_EFFECTS + (OilColumn(),)


def effect_by_name(name: str) -> Effect:
    """The library's effect of that name; ValueError naming the known ones otherwise."""
    for effect in EFFECTS:
        if effect.name == name:
            return effect
    raise ValueError(f"unknown effect {name!r}; known: {[e.name for e in EFFECTS]}")
