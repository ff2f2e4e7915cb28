"""The sim-to-real diagnosis against known truth: noise floor, clean series, a withheld effect, the command.

Default tests use a 10-test campaign so that they stay short; the withheld-effect study over
the whole library on the 20-test reference campaign is marked slow.
"""

from __future__ import annotations

import json
import math
import sys

import numpy as np
import pytest

from bayes_sst.cli import main
from bayes_sst.diagnosis import diagnose, effect_data, noise_floor
from bayes_sst.io import load_series, write_series
from bayes_sst.twin import PRESETS, default_plan, simulate
from bayes_sst.physics import strut_cubic_stiffness

TRUTH = PRESETS["sst-paper"]
SHORT_PLAN = [p for i, p in enumerate(default_plan()) if i % 2 == 0]   # 10 tests over 0.25-3 Hz


def test_noise_floor_of_a_periodic_signal_is_the_noise_sd():
    # a periodic "residual" (model error, repeats every cycle) plus white noise of sd 50 N:
    # the floor must see only the noise.
    from bayes_sst.effects import EffectData

    rate, f = 200.0, 1.0
    n = int(10 * rate)
    t = np.arange(n) / rate
    rng = np.random.default_rng(0)
    periodic = 400.0 * np.sin(2 * np.pi * f * t) ** 3
    residual = periodic + 50.0 * rng.standard_normal(n)
    zeros = np.zeros(n)
    test = EffectData(id="X", frequency_hz=f, amplitude_m=0.01, payload_kg=0.0, position=0.0, strut_h=1.0,
                      sample_rate_hz=rate, cutoff_hz=4.0, lo=0, index=np.arange(100, n - 100, 12),
                      u_full=zeros, v_full=zeros, a_full=zeros, F_full=zeros, a_record=zeros,
                      period_samples=rate / f)
    assert noise_floor(test, residual) == pytest.approx(50.0, rel=0.1)


def test_an_effect_whose_amplitude_is_not_resolved_is_not_selected():
    """The amplitude gate: a large elpd score alone (25 nats over 20 tests, four of them
    carrying it, as a spurious specimen of 1.2 +- 1.7 t did on an independent generator's clean
    series while its sensor offsets still reached the diagnosis) does not select an effect whose coefficient is within MIN_AMPLITUDE_Z sds of zero;
    the same score with a resolved amplitude does."""
    from types import SimpleNamespace

    from bayes_sst.diagnosis._diagnose import MIN_AMPLITUDE_Z, _entry, _selection_rule
    from bayes_sst.effects import FORCE_EFFECTS

    diff = np.array([7.7, 3.8, 0.5, -0.2, -0.1, 0.3, -0.6, -1.5, 10.4, -0.2,
                     0.3, 0.6, -1.5, 7.7, -2.3, -0.2, 0.1, 0.2, -0.4, 0.7])
    specimen = next(e for e in FORCE_EFFECTS if e.name == "specimen")

    def score(amplitude_z):
        return SimpleNamespace(effect=specimen, score=float(diff.sum()), score_se=15.2, params={},
                               fit=SimpleNamespace(alpha=0.5, base=lambda: {"Me": 13200.0}), at_bound=False, grid_edge={}, diff=diff, amplitude_z=amplitude_z, amplitude_law_nats=None, alpha_marginal=((), ()))

    assert MIN_AMPLITUDE_Z == pytest.approx(3.0)
    for amplitude_z, selected in ((1192.0 / 1653.0, False), (2.0, False), (21.4, True)):
        s = score(amplitude_z)
        entry = _entry(s)
        assert entry["z_loss"] >= 5.0  # the rule that let the spurious specimen through
        assert (_selection_rule(s, entry) is not None) is selected, amplitude_z


def test_a_reading_too_small_to_count_is_not_selected_by_any_rule():
    """The same specimen scores with a resolved amplitude, read at 47 kg (under 1 % of a 13.2 t
    deck, Specimen.immaterial) and at 3 t: only the second is selected, and the first's entry
    says why. The breakaway check's excess is the stiction's limit where the Stribeck velocity
    is not resolved."""
    from types import SimpleNamespace

    from bayes_sst.diagnosis._breakaway import BREAKAWAY_EXCESS
    from bayes_sst.diagnosis._diagnose import _entry, _selection_rule
    from bayes_sst.effects import FORCE_EFFECTS
    from bayes_sst.effects._library import UNRESOLVED_STATIC_EXCESS

    assert UNRESOLVED_STATIC_EXCESS == BREAKAWAY_EXCESS
    diff = np.array([7.7, 3.8, 0.5, -0.2, -0.1, 0.3, -0.6, -1.5, 10.4, -0.2,
                     0.3, 0.6, -1.5, 7.7, -2.3, -0.2, 0.1, 0.2, -0.4, 0.7])
    specimen = next(e for e in FORCE_EFFECTS if e.name == "specimen")

    def rule(mass):
        s = SimpleNamespace(effect=specimen, score=float(diff.sum()), score_se=15.2,
                            params={"specimen_mass": {"mean": mass, "sd": 5.0}},
                            fit=SimpleNamespace(alpha=0.5, base=lambda: {"Me": 13200.0}), at_bound=False, grid_edge={},
                            diff=diff, amplitude_z=21.4, amplitude_law_nats=None, alpha_marginal=((), ()))
        entry = _entry(s)
        return _selection_rule(s, entry, best=True), entry

    light, entry = rule(47.0)
    assert light is None and "47 kg" in entry["immaterial"]
    heavy, entry = rule(3000.0)
    assert heavy is not None and entry["immaterial"] is None


def test_a_weak_cubic_is_selected_by_its_coefficient_z_only_as_the_rounds_best():
    """3x the gas strut's K'e on the twin (seed 21, prior sd Ke at the time): 8.1 +- 8.4 nats on
    the stroke view, under MIN_SCORE, the coefficient 4.5 sds from zero (no series without a
    cubic went past 2.9).
    Selected by COEFFICIENT_Z when it is the round's best candidate and lowers its view's RMS;
    not when a higher-scoring candidate exists (strut inertia is u^3 in shape within a sine),
    not below the z, not with a negative score, and the same numbers do not select the hinge,
    whose z reached 7.6 beside an unmodelled delay."""
    from types import SimpleNamespace

    from bayes_sst.diagnosis._diagnose import COEFFICIENT_Z, _entry, _selection_rule
    from bayes_sst.effects import FORCE_EFFECTS

    by_name = {e.name: e for e in FORCE_EFFECTS}
    diff = np.array([0.6, 1.9, -0.4, 0.2, 0.9, -0.8, 0.1, 2.6, 0.3, -0.2,
                     0.4, 1.1, -0.6, 0.0, 0.2, 0.8, -0.3, 1.2, 0.5, -0.4])  # 8.1 nats, as measured

    def selectable(name, amplitude_z, best=True, scale=1.0, rms_ratio=0.995):
        s = SimpleNamespace(effect=by_name[name], score=float(scale * diff.sum()), score_se=8.4, params={},
                            fit=SimpleNamespace(alpha=0.5, base=lambda: {"Me": 13200.0}), at_bound=False, grid_edge={}, diff=scale * diff,
                            amplitude_z=amplitude_z, amplitude_law_nats=None, alpha_marginal=((), ()))
        return _selection_rule(s, dict(_entry(s), rms_ratio=rms_ratio), best=best) is not None

    assert by_name["nonlinear_stiffness"].z_selectable and by_name["drift"].z_selectable
    assert 0 < diff.sum() < 15.0  # under MIN_SCORE: no score rule selects it
    assert selectable("nonlinear_stiffness", 4.5) and selectable("nonlinear_stiffness", COEFFICIENT_Z)
    assert not selectable("nonlinear_stiffness", 4.5, best=False)
    assert not selectable("nonlinear_stiffness", 0.99 * COEFFICIENT_Z)  # above MIN_AMPLITUDE_Z = 3
    assert not selectable("nonlinear_stiffness", 4.5, scale=-1.0)
    assert not selectable("position_friction", 4.5) and not selectable("strut_inertia", 4.5)
    # the cubic acts within each test: it must lower its view's RMS (the sixth simulator's drift
    # series, seed 105: a false cubic at z 4.16 raised it 0.25 %); drift acts between tests, and
    # a true 5 % drift there raised it 0.33 % at z 5.06
    assert not selectable("nonlinear_stiffness", 4.16, rms_ratio=1.0025)
    assert not selectable("nonlinear_stiffness", 4.5, rms_ratio=1.0)
    assert selectable("nonlinear_stiffness", 4.5, rms_ratio=0.9975)
    assert selectable("drift", 5.06, rms_ratio=1.0033)


def test_a_weak_hinge_is_selected_by_its_coefficient_z_above_its_own_threshold():
    """The sixth simulator's hinge friction at 2.6 % of its range (seed 116): 59.7 +- 51.5 nats
    on the stroke view, 50.9 of them in one test, so no score rule takes it; its coefficient
    stands 20.1 sds from zero and it lowers the stroke view's RMS. The hinge's own threshold
    (8) lies above the largest z of the physical sign without a hinge: 5.7 on clean series
    (fifth simulator, seed 56), 7.6 beside an unmodelled delay; at the cubic's 4 those would have
    been claimed. The valve generator's strong hinge stands at 9.7 (10.0 with alpha integrated
    out of the z and the stroke view's noise read from the scored model; seed 116 at 18.6)."""
    from types import SimpleNamespace

    from bayes_sst.diagnosis._diagnose import COEFFICIENT_Z, _entry, _selection_rule
    from bayes_sst.effects import FORCE_EFFECTS

    hinge = next(e for e in FORCE_EFFECTS if e.name == "position_friction")
    diff = np.array([0.459, -1.994, -3.659, 4.603, -0.069, 7.908, -0.024, 1.716, 2.865, -3.827,
                     0.602, 50.854, 0.596, -0.308])  # as measured on seed 116

    def rule(amplitude_z, rms_ratio=0.998, best=True, at_bound=False, law=None):
        s = SimpleNamespace(effect=hinge, score=float(diff.sum()), score_se=51.5, params={},
                            fit=SimpleNamespace(alpha=0.86, base=lambda: {"Me": 13200.0}), at_bound=at_bound, grid_edge={}, diff=diff,
                            amplitude_z=amplitude_z, amplitude_law_nats=law, alpha_marginal=((), ()))
        return _selection_rule(s, dict(_entry(s), rms_ratio=rms_ratio), best=best)

    assert hinge.coefficient_z == pytest.approx(8.0) and hinge.coefficient_z > 7.6 > 5.7 > COEFFICIENT_Z
    assert rule(20.1) == "coefficient_z" and rule(9.7) == "coefficient_z"
    assert rule(7.6) is None and rule(5.7) is None
    assert rule(20.1, best=False) is None
    # a hinge of the wrong sign (valve generator, seed 103: -9.5 sds) is at its bound
    assert rule(9.5, at_bound=True) is None
    # the amplitude-free rival fitting better vetoes it (beside a 2 ms delay: 2.8 nats better)
    assert rule(20.1, law=-2.8) is None and rule(20.1, law=50.7) == "coefficient_z"
    # the sixth's seed 122 (4.4 % of the range, z 17.5) raised the view's RMS 0.9 %: not selected
    # unless it follows its amplitude law (by 59.2 nats there) by AMPLITUDE_LAW_FOLLOWED_NATS
    assert rule(17.5, rms_ratio=1.009) is None and rule(17.5, rms_ratio=1.009, law=5.0) is None
    assert rule(17.5, rms_ratio=1.009, law=59.2) == "coefficient_z"


def test_a_third_harmonic_that_does_not_grow_as_the_cube_of_the_amplitude_is_not_a_strut_cubic(tmp_path):
    """The sixth simulator's clean series, seed 40 (benchmarks/sixth_generator.py: a Stribeck
    bump and sticking at each reversal, tests of 2-50 mm): its friction leaves a third harmonic
    of about the same force at every amplitude, and the stroke view's shared cubic reads it at
    K'e = 5.3 MN/m, 4.46 sds from zero, which the coefficient rule alone would select. The same
    column with no amplitude law (AmplitudeFree) fits 22 nats better, so no rule does. On the
    twin with three times its gas strut's cubic (seed 31) the cubic beats that rival by 14 nats
    and is selected. The rival's column is the cubic's times (A_max/A_j)^3."""
    from dataclasses import replace
    from pathlib import Path

    from bayes_sst.diagnosis._data import STROKE_SIGNALS
    from bayes_sst.diagnosis._diagnose import AMPLITUDE_LAW_NATS, COEFFICIENT_Z, _entry, _rms, _scale, _selection_rule
    from bayes_sst.diagnosis._engine import Scorer
    from bayes_sst.diagnosis._screen import fit_base, score_effect
    from bayes_sst.effects import AmplitudeFree, NonlinearStiffness, steady_amplitude

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    from sixth_generator import make_series

    def scored(series):
        tests = effect_data(series, STROKE_SIGNALS)
        scorer = Scorer(tests, _scale(series, tests))
        base = fit_base(scorer)
        cubic = score_effect(scorer, NonlinearStiffness(), base)
        entry = dict(_entry(cubic), rms_ratio=_rms(cubic.fit.residuals) / _rms(base.residuals))
        return tests, cubic, entry

    make_series(40, str(tmp_path / "clean"))
    tests, cubic, entry = scored(load_series(tmp_path / "clean"))
    amplitudes = np.array([steady_amplitude(t) for t in tests])
    assert amplitudes.max() / amplitudes.min() > 10.0
    rival = AmplitudeFree.of(NonlinearStiffness(), tests)
    for t, amplitude in zip(tests, amplitudes):
        expected = NonlinearStiffness().columns(t, {}, 0.5) * (amplitudes.max() / amplitude) ** 3
        np.testing.assert_allclose(rival.columns(t, {}, 0.5), expected, rtol=1e-12)
    assert cubic.amplitude_z >= COEFFICIENT_Z and entry["rms_ratio"] < 1.0
    assert cubic.amplitude_law_nats < -10.0 * AMPLITUDE_LAW_NATS
    assert _selection_rule(replace(cubic, amplitude_law_nats=None), entry, best=True) == "coefficient_z"
    assert _selection_rule(cubic, entry, best=True) is None

    true_k3 = 3 * strut_cubic_stiffness(TRUTH.Ke, TRUTH.strut_gamma, TRUTH.strut_h, TRUTH.strut_l0)
    series = simulate("sst-paper", seed=31, spread=0.02, truth_overrides={"cubic_stiffness": true_k3})
    _, cubic, entry = scored(series)
    assert cubic.amplitude_law_nats > 5.0
    assert _selection_rule(cubic, entry, best=True) == "coefficient_z"
    assert cubic.params["cubic_stiffness"]["mean"] == pytest.approx(true_k3, rel=0.3)


def test_the_gas_struts_cubic_sign_comes_from_the_table_description():
    from bayes_sst.diagnosis._data import strut_cubic_sign
    from bayes_sst.io import Series

    def sign(strut):
        return strut_cubic_sign(Series(name="s", tests=(), table={"strut": strut}))

    # K'e = 0.5*(gamma*h/l0 - 1)*Ke: 1.4*1.2/0.8 = 2.1 hardens, 1.4*1.2/2.0 = 0.84 softens
    assert sign({"h_m": 1.2, "l0_m": 0.8, "gamma": 1.4}) == 1.0
    assert sign({"h_m": 1.2, "l0_m": 2.0, "gamma": 1.4}) == -1.0
    assert sign({"h_m": 1.2, "gamma": 1.4}) == 1.0            # no l0: the study's hardening
    assert sign({"h_m": 1.2, "l0_m": "x", "gamma": 1.4}) == 1.0
    assert strut_cubic_sign(Series(name="s", tests=())) == 1.0


def test_a_cubic_against_the_struts_sign_is_at_its_bound_and_found_where_the_struts_soften():
    """A softening cubic K'e = -2e6 N/m (10 % of F at 100 mm; a gas column longer than gamma*h)
    on the twin: scored on the stroke view, it is found at its value when the table description
    says the struts soften (l0 = 2 m), and left at its bound (not selectable) when the
    description says they harden (the preset's l0 = 0.8 m). (Seeds 13 and 14 read K'e within
    0.8 sds on this 10-test plan and within 0.6 on the full one; seed 12 reads 1.6x, 2.9 sds,
    and a hardening 2e6 on it 0.35x: that seed's noise, whatever the sign.)"""
    from dataclasses import replace

    from bayes_sst.diagnosis._data import STROKE_SIGNALS
    from bayes_sst.diagnosis._diagnose import _scale
    from bayes_sst.diagnosis._engine import Scorer
    from bayes_sst.diagnosis._screen import fit_base, score_effect
    from bayes_sst.effects import FORCE_EFFECTS

    cubic = next(e for e in FORCE_EFFECTS if e.name == "nonlinear_stiffness")
    true_k3 = -2.0e6
    soft = simulate("sst-paper", seed=14, spread=0.02, plan=SHORT_PLAN,
                    truth_overrides={"cubic_stiffness": true_k3, "strut_l0": 2.0})
    hard_table = dict(soft.table, strut=dict(soft.table["strut"], l0_m=0.8))
    results = {}
    for name, series in (("soft", soft), ("hard", replace(soft, table=hard_table))):
        tests = effect_data(series, STROKE_SIGNALS)
        scorer = Scorer(tests, _scale(series, tests))
        results[name] = score_effect(scorer, cubic, fit_base(scorer))
    found = results["soft"]
    k3 = found.params["cubic_stiffness"]
    assert not found.at_bound and found.amplitude_z > 5.0 and found.score > 0
    assert abs(k3["mean"] - true_k3) <= max(2.0 * k3["sd"], 0.2 * abs(true_k3))
    assert results["hard"].at_bound and results["hard"].score == 0.0
    assert results["hard"].params["cubic_stiffness"]["mean"] < 0


def test_an_effect_that_explains_most_of_a_clear_excess_in_one_test_is_selected():
    """A specimen excited by one triangle test's harmonics (an independent generator's 1000 Hz
    series: +62.5 nats there, -9.8 on a fast sine, about zero elsewhere; 51 +- 64 in all) passes
    none of the score rules, but it removes 96 % of an excess of 676 N over a 275 N floor with
    its mass 32 sds from zero: selected. The same scores without a clear excess (residual at the
    floor), or with a weakly resolved amplitude, are not. The excess is judged over the lesser of
    the floor and the effect's residual."""
    from types import SimpleNamespace

    from bayes_sst.diagnosis._diagnose import _entry, _selection_rule, _with_shrink
    from bayes_sst.effects import FORCE_EFFECTS

    diff = np.array([0.3, 0.0, 0.4, 0.3, -0.0, 0.6, 0.6, -0.3, -0.3, -0.1,
                     -9.8, 0.0, -0.3, 1.3, -0.8, -0.4, 0.6, 62.5, -2.3, -1.0])
    specimen = next(e for e in FORCE_EFFECTS if e.name == "specimen")

    def selected(amplitude_z, before, after, floor):
        s = SimpleNamespace(effect=specimen, score=float(diff.sum()), score_se=64.0, params={},
                            fit=SimpleNamespace(alpha=0.5, base=lambda: {"Me": 13200.0}), at_bound=False, grid_edge={}, diff=diff, amplitude_z=amplitude_z, amplitude_law_nats=None, alpha_marginal=((), ()))
        entry = _with_shrink(_entry(s), before, after, floor)
        return _selection_rule(s, entry) is not None, entry

    chosen, entry = selected(31.9, 675.5, 300.0, 274.8)
    assert chosen and entry["explains_most"] and entry["shrink"] > 0.9
    assert entry["sign_p"] > 0.002 and entry["z_loss"] < 5.0  # the other rules alone would miss it
    assert not selected(31.9, 280.0, 270.0, 274.8)[0]  # no clear excess: 280^2 is 4 % above 274.8^2
    assert not selected(31.9, 374.7, 340.0, 346.8)[0]  # nor 17 % (an 8 % higher RMS)
    assert not selected(4.0, 675.5, 300.0, 274.8)[0]  # amplitude under 5 sds
    assert not selected(31.9, 675.5, 600.0, 274.8)[0]  # removes a third of the excess only
    # a floor lifted by a transient the effect explains: the tenth simulator's strong specimen
    # (a 2.8 Hz test ringing on at 3.58 Hz, its scatter 29 times the other tests') took the base
    # model's 514 N to 127 N under a 515 N floor; what the model fits below is no noise
    chosen, entry = selected(51.6, 514.1, 126.6, 515.5)
    assert chosen and entry["explains_most"] and entry["shrink"] == 1.0
    assert not selected(51.6, 514.1, 480.0, 515.5)[0]  # 7 % down, under the floor: no clear excess


def test_an_effect_that_raises_the_residual_is_not_selected():
    """A clean valve-generator series (seed 103, 256 Hz): a specimen of 11 t at 22 Hz gained
    24,276 nats in one triangle test and lost 10-350 in the thirteen others; the loss-scaled
    rule took it (z_loss 38) while the RMS went from 493 to 4169 N. No rule takes an effect that
    raises the RMS more than MAX_RMS_RISE: not the score rule (the gain spread over the tests as
    a true stiction's beside a ringing specimen on the twin, with a lower score_se); the
    loss-scaled rule asks the RMS to fall, and for a gain held by one test to fall most of the way
    to its floor."""
    from types import SimpleNamespace

    from bayes_sst.diagnosis._diagnose import MAX_RMS_RISE, _entry, _selection_rule, _with_shrink
    from bayes_sst.effects import FORCE_EFFECTS

    one_test = np.array([-9.9, -10.6, -16.7, -44.1, -60.7, -46.1, -186.3, -47.7, -141.1, 0.8, 3.3, -40.6,
                         -350.8, 24276.4])  # as measured
    spread = np.array([94.9, 109.5, 8.1, 36.2, -4.0, 3.5, 52.9, -0.1, 3.7, -0.5, 7.0, -18.7, 9.3, 9.4, -5.7, 1.6,
                       -2.9, -7.4, -11.7, -2.5])
    specimen = next(e for e in FORCE_EFFECTS if e.name == "specimen")

    def rule(diff, before, after, se_factor=1.0):
        s = SimpleNamespace(effect=specimen, score=float(diff.sum()),
                            score_se=se_factor * float(np.sqrt(diff.size) * diff.std()),
                            params={}, fit=SimpleNamespace(alpha=0.5, base=lambda: {"Me": 13200.0}), at_bound=False, grid_edge={}, diff=diff,
                            amplitude_z=237.7, amplitude_law_nats=None, alpha_marginal=((), ()))
        return _selection_rule(s, _with_shrink(_entry(s), before, after, 281.0))

    assert _entry(SimpleNamespace(effect=specimen, score=float(one_test.sum()), score_se=24352.2, params={},
                                  fit=SimpleNamespace(alpha=0.5, base=lambda: {"Me": 13200.0}), at_bound=False, grid_edge={}, diff=one_test,
                                  amplitude_z=237.7, amplitude_law_nats=None, alpha_marginal=((), ())))["z_loss"] > 30.0
    assert rule(one_test, 493.0, 4169.0) is None
    assert rule(one_test, 493.0, 300.0) == "loss_scaled_z"
    assert rule(one_test, 493.0, 493.0) is None  # one test's gain, nothing removed
    assert rule(spread, 493.0, 480.0) == "loss_scaled_z"
    assert rule(spread, 493.0, 493.0) is None  # the loss-scaled rule asks the RMS to fall
    assert rule(spread, 493.0, 0.99 * MAX_RMS_RISE * 493.0, se_factor=0.5) == "score_z"
    assert rule(spread, 493.0, 1.01 * MAX_RMS_RISE * 493.0, se_factor=0.5) is None
    assert rule(spread, 880.0, 986.0, se_factor=0.5) is None  # seed 106's 2 t at 17.7 Hz: the RMS 12 % up


def test_the_loss_scaled_rule_asks_a_resolved_amplitude_and_a_one_test_gain_to_show_in_the_residual():
    """Per-test differences as measured. Clean valve-generator series: a strut damping with 94 of
    its 80 nats in one test, the residual already under its floor (seed 112), and a specimen of
    34 +- 20 nats at 4.8 sds (seed 138), are refused. A true hinge on the LuGre generator with 58
    of 61 nats in its largest-amplitude test, removing 78 % of an excess 2 % over the floor, and
    a true stiction beside a ringing specimen on the twin (the gain spread over the tests) are
    taken, the stiction once the specimen is in the model and the residual falls (with the
    specimen unmodelled the RMS rose 0.8 %, and the rule asks it to fall)."""
    from types import SimpleNamespace

    from bayes_sst.diagnosis._diagnose import ONE_TEST_Z, _entry, _selection_rule, _with_shrink
    from bayes_sst.effects import FORCE_EFFECTS

    effects = {e.name: e for e in FORCE_EFFECTS}

    def rule(name, diff, amplitude_z, before, after, floor):
        diff = np.asarray(diff)
        s = SimpleNamespace(effect=effects[name], score=float(diff.sum()), score_se=float(np.sqrt(diff.size) * diff.std()),
                            params={}, fit=SimpleNamespace(alpha=0.5, base=lambda: {"Me": 13200.0}), at_bound=False, grid_edge={}, diff=diff,
                            amplitude_z=amplitude_z, amplitude_law_nats=None, alpha_marginal=((), ()))
        entry = _with_shrink(_entry(s), before, after, floor)
        assert entry["z_loss"] >= 5.0 and entry["sign_p"] > 0.002 and s.score < 2.5 * s.score_se
        return _selection_rule(s, entry), entry

    damping = [-0.7, -0.1, -0.2, 0.1, -0.1, 1.2, -1.0, 1.8, 2.8, 93.9, -3.7, -1.7, -1.2, -0.5, -3.4, -2.6, -2.6, -1.9]
    chosen, entry = rule("strut_damping", damping, 12.9, 289.8, 286.6, 296.9)
    assert entry["z_loss_without_best"] < ONE_TEST_Z and entry["shrink"] == 1.0 and chosen is None
    # the same gain while the residual stands above its floor and falls most of the way to it
    assert rule("strut_damping", damping, 12.9, 320.0, 298.0, 296.9)[0] == "loss_scaled_z"

    hinge = [-0.9, -0.6, 0.6, -0.7, -1.7, 1.0, 1.9, -1.1, 58.2, -1.6, -1.1, -0.3, -1.0, -0.8, 0.8, -0.1, 0.3, -0.6,
             -0.3, 6.4, 2.5, 0.2]
    chosen, entry = rule("position_friction", hinge, 13.6, 1000.0, 982.5, 977.5)
    assert entry["z_loss_without_best"] < ONE_TEST_Z and entry["shrink"] == pytest.approx(0.78, abs=0.01)
    assert chosen == "loss_scaled_z"
    assert rule("position_friction", hinge, 13.6, 1000.0, 990.0, 977.5)[0] is None  # 45 % of the excess

    specimen = [1.2, -2.6, 0.5, -0.1, 0.9, 0.9, -0.0, -0.6, -0.5, 0.4, -0.7, -0.5, 15.3, 12.6, -0.5, -0.0, -0.1, 0.1,
                0.2, 0.1, 0.8, 4.8, 4.0, -2.0]
    assert rule("specimen", specimen, 4.76, 400.0, 398.0, 380.0)[0] is None  # amplitude under 5 sds
    assert rule("specimen", specimen, 21.0, 400.0, 402.2, 380.0)[0] is None  # the RMS up 0.6 %
    chosen, entry = rule("specimen", specimen, 21.0, 400.0, 398.0, 380.0)
    assert entry["z_loss_without_best"] >= ONE_TEST_Z and chosen == "loss_scaled_z"

    stiction = [94.9, 109.5, 8.1, 36.2, -4.0, 3.5, 52.9, -0.1, 3.7, -0.5, 7.0, -18.7, 9.3, 9.4, -5.7, 1.6, -2.9, -7.4,
                -11.7, -2.5]
    assert rule("stiction", stiction, 43.2, 500.0, 490.0, 450.0)[0] == "loss_scaled_z"
    assert rule("stiction", stiction, 43.2, 500.0, 504.1, 450.0)[0] is None


def test_verdict_says_when_the_residual_had_no_visible_excess(clean_diagnosis):
    """The shrink is measured against min(floor, after), so an effect found while the residual
    sits under its floor estimate reads "100 % of the excess removed"; the verdict says why."""
    from dataclasses import replace

    found = replace(clean_diagnosis, selected=["drift"], shrink=1.0, shrink_basis="residual",
                    rms_before=505.0, rms_after=504.0, noise_floor=513.0)
    assert "100 % of the excess removed (the residual was already under its noise-floor" in found.verdict
    above = replace(found, rms_before=700.0, rms_after=515.0)
    assert above.verdict.endswith("100 % of the excess removed")
    # nothing selected: "none" where the residual is at its floor; where it stands clearly above
    # (mean square 50 % over), the verdict says that something outside the library is missing
    quiet = replace(clean_diagnosis, selected=[], rms_before=520.0, noise_floor=513.0)
    assert quiet.verdict.startswith("verdict: none - no candidate effect improves the fit beyond the noise")
    loud = replace(clean_diagnosis, selected=[], rms_before=1.3 * 513.0, noise_floor=513.0)
    assert loud.verdict.startswith("verdict: none of the candidate effects explains the misfit, but the model misses")


def test_amplitude_z_of_a_scored_effect_is_its_coefficient_over_its_sd(clean_diagnosis):
    """EffectScore.amplitude_z from the extended fit's own coefficient and posterior sd with alpha
    integrated out (drift, one linear coefficient; the reported sd is the largest of that, the
    sd at the profiled alpha and the sandwich sd); the delay, which has none, stands as far from
    its null setting (0) as its read value is in its own sds."""
    steps = clean_diagnosis.to_json()["steps"][0]["candidates"]
    by_name = {c["name"]: c for c in steps}
    drift = by_name["drift"]["params"]["drift"]
    marginal = by_name["drift"]["coefficients_alpha_marginal"]
    assert by_name["drift"]["amplitude_z"] == pytest.approx(abs(marginal["mean"][0]) / marginal["sd"][0], rel=1e-9)
    assert drift["sd"] >= max(drift["sd_posterior"], marginal["sd"][0]) * (1 - 1e-12)
    # the marginal mean is the profiled alpha's coefficient where alpha is well read
    assert marginal["mean"][0] == pytest.approx(drift["mean"], abs=0.5 * marginal["sd"][0])
    assert by_name["channel_delay"]["coefficients_alpha_marginal"] == {"mean": [], "sd": []}
    delay = by_name["channel_delay"]["params"]["delay"]
    assert by_name["channel_delay"]["amplitude_z"] == pytest.approx(abs(delay["mean"]) / delay["sd"], rel=1e-9)
    json.dumps(clean_diagnosis.to_json(), allow_nan=False)  # what diagnosis.json needs


def test_the_coefficient_z_integrates_the_damping_exponent_out():
    """alpha_marginal_coefficients: nodes weighted by exp(log marginal) times the alpha interval
    each stands for (midpoints between nodes), a node repeated between two grids counted once;
    mean = sum w m, var = sum w (s^2 + (m - mean)^2)."""
    from types import SimpleNamespace

    from bayes_sst.diagnosis._screen import alpha_marginal_coefficients

    def node(alpha, logm, coefficient, sd):
        # two base-like coefficients in front of the effect's one
        return SimpleNamespace(alpha=alpha, log_marginal=logm, mu=np.array([7.0, 8.0, coefficient]),
                               mu_sd=np.array([1.0, 1.0, sd]))

    # widths 0.05, 0.1, 0.15 -> weights 1/6, 1/3, 1/2; the repeat of 0.55 (another grid's) is not counted
    nodes = [node(0.5, -3.0, 0.0, 1.0), node(0.55, -3.0, 6.0, 1.0), node(0.7, -3.0, 12.0, 1.0),
             node(0.55, 50.0, 100.0, 1.0)]
    mean, sd = alpha_marginal_coefficients(nodes, 1)
    assert mean[0] == pytest.approx(8.0, rel=1e-12)
    assert sd[0] == pytest.approx(math.sqrt(1.0 + 64 / 6 + 4 / 3 + 16 / 2), rel=1e-12)
    # a node far down in log marginal carries no weight; two effect coefficients are kept apart
    two = [SimpleNamespace(alpha=a, log_marginal=lm, mu=np.array([1.0, c, -c]), mu_sd=np.array([1.0, 2.0, 3.0]))
           for a, lm, c in ((0.5, 0.0, 10.0), (0.6, 0.0, 30.0), (0.7, -800.0, 1e6))]
    mean, sd = alpha_marginal_coefficients(two, 2)
    np.testing.assert_allclose(mean, [20.0, -20.0], rtol=1e-12)
    np.testing.assert_allclose(sd, [math.sqrt(4 + 100), math.sqrt(9 + 100)], rtol=1e-12)
    # one node: the fit's own coefficient and sd
    mean, sd = alpha_marginal_coefficients(two[:1], 1)
    assert (mean[0], sd[0]) == (-10.0, 3.0)


def test_shrink_is_the_share_of_the_excess_over_the_floor_or_over_the_final_residual():
    from bayes_sst.diagnosis._diagnose import _shrink

    # by hand: 1 - (408^2 - 396^2)/(458^2 - 396^2) = 1 - 9648/52948
    assert _shrink(458.0, 408.0, 396.0) == pytest.approx(1 - 9648 / 52948)
    # a residual that starts at the floor and ends below it: all of it removed
    assert _shrink(395.0, 368.0, 395.0) == 1.0
    # no change, or a rise, removes nothing
    assert _shrink(370.0, 370.0, 368.0) == 0.0
    assert _shrink(327.0, 330.0, 340.0) == 0.0
    assert _shrink(757.0, 759.0, 384.0) < 0.0


def test_sensor_offsets_do_not_reach_the_diagnosis():
    """Constant offsets on F, u and a (up to 1 kN, 1 mm, 0.05 m/s^2: what an independent
    generator's sensors had) are removed over the steady window, as the fit removes them: the
    diagnosis sees the same filtered signals with and without them. Before, they stayed in the
    diagnosis's view (not in the fit's) and left a misfit of about 1.3 kN per test that buried
    every withheld effect of that generator."""
    from dataclasses import replace

    from bayes_sst.io import TestRecord

    series = simulate("sst-paper", seed=4, plan=SHORT_PLAN[:3])
    rng = np.random.default_rng(0)
    shifted = []
    for record in series.tests:
        columns = dict(record.columns)
        columns["F"] = columns["F"] + rng.uniform(-1000, 1000)
        columns["u"] = columns["u"] + rng.uniform(-1e-3, 1e-3)
        columns["a"] = columns["a"] + rng.uniform(-0.05, 0.05)
        shifted.append(TestRecord(record.spec, columns))
    plain = effect_data(series)
    offset = effect_data(replace(series, tests=tuple(shifted)))
    for p, q in zip(plain, offset):
        window = slice(p.kept[0], p.kept[-1] + 1)
        for name in ("F_full", "u_full", "a_full"):
            np.testing.assert_allclose(getattr(q, name)[window], getattr(p, name)[window],
                                       atol=1e-6 * np.max(np.abs(getattr(p, name))), err_msg=name)


def test_without_an_accelerometer_a_clean_series_stays_clean():
    """No `a` column: the diagnosis differentiates the 2.5 ms-smoothed displacement twice (as
    the fit's signals do, up to the smoothing), so the clean twin's residual sits at its noise
    floor and nothing is claimed. Measured on this series: with the second derivative of the
    4f-low-passed u used before, the residual was 453 N against a 317 N floor and a channel
    delay was selected (41 +- 13 nats)."""
    from dataclasses import replace

    from bayes_sst.io import TestRecord

    series = simulate("sst-paper", seed=31, spread=0.02)
    without_a = replace(series, tests=tuple(
        TestRecord(r.spec, {k: v for k, v in r.columns.items() if k != "a"}) for r in series.tests))
    d = diagnose(without_a)
    assert d.selected == []
    assert d.rms_before < 1.1 * d.noise_floor


@pytest.mark.parametrize("drift", [0.2, 0.05])
def test_between_test_share_is_the_excess_scatter_of_the_per_test_coefficients_explained(drift):
    """Per-test Fmu (and Ce) that fall linearly by `drift` over the campaign around a 2 %
    natural scatter. The floor is half the mean square of consecutive differences of the
    after-fit's values in campaign order (a smooth trend cancels there), and the share is that of
    the scatter above it, computed here independently. For the weak 5 % drift the plain share of
    the total scatter is under a half whatever the model."""
    from bayes_sst.diagnosis._diagnose import _between_test_share
    from bayes_sst.diagnosis._engine import BASE_COEFFICIENTS, ModelFit

    rng = np.random.default_rng(3)
    n = 20
    natural = 1.0 + 0.02 * rng.standard_normal((n, 2))
    trend = (1.0 - drift * np.arange(n) / (n - 1))[:, None]
    mu = np.array([13_200.0, 7.2e5, 29_600.0, 12_500.0])

    def model(relative):
        theta = np.tile(mu, (n, 1))
        theta[:, 2:] = mu[2:] * relative
        return ModelFit(terms=(), names=BASE_COEFFICIENTS, mu=mu, mu_sd=0.01 * mu, mu_sandwich_sd=0.01 * mu,
                        theta=theta, alpha=0.5,
                        spread=0.02, phi=np.zeros(n), sigma=np.ones(n), log_marginal=0.0, elpd=np.zeros(n),
                        residuals=())

    positions = np.arange(n) / (n - 1)
    before, after = model(natural * trend), model(natural)
    total = np.var(natural * trend, axis=0, ddof=1).sum()
    remaining = np.var(natural, axis=0, ddof=1).sum()
    floor = (np.diff(natural, axis=0) ** 2).mean(axis=0).sum() / 2   # of the after-fit's values
    f = min(floor, remaining)
    expected = 1.0 - (remaining - f) / (total - f)
    share = _between_test_share(before, after, ("Ce", "Fmu"), positions)
    assert share == pytest.approx(expected, rel=1e-9)
    plain = 1.0 - remaining / total   # the share of the total scatter
    if drift == 0.2:
        assert share > 0.9
    else:
        # the floor from 19 differences is itself uncertain by about a quarter, a large part of
        # a weak drift's excess: the share is well above the plain one but not near 1
        assert plain < 0.5 < share
    # more scatter after (the trend left in the after-fit): nothing explained
    assert _between_test_share(after, before, ("Ce", "Fmu"), positions) == 0.0
    # a model that explains nothing (after = before): the trend is left over the floor
    assert _between_test_share(before, before, ("Ce", "Fmu"), positions) == 0.0


def test_a_hinge_shrink_is_read_on_the_per_test_friction_it_took_in_with_the_residual_beside():
    """Hinge friction Fp*(u/h)^2*sign(v) at 20 test amplitudes: without it each test's Fmu takes
    the A^2 level (per-test Fmu = Fmu*(1 + 0.08*(A_j/A_max)^2) on a 1 % natural scatter); with it
    the per-test values agree, and the residual RMS rose a little (the seventh simulator's seed
    110: 107.5 -> 108.1 N over a 103.2 N floor, residual shrink -0.12). The shrink is the share
    of the per-test Ce and Fmu scatter explained (basis "absorbed"), the residual's own beside;
    drift alone keeps "between_tests", and a hinge with a specimen, which has no per-test part,
    the residual."""
    from bayes_sst.diagnosis._diagnose import _between_test_share, _shrink, _shrink_on_basis
    from bayes_sst.diagnosis._engine import BASE_COEFFICIENTS, ModelFit
    from bayes_sst.effects import FORCE_EFFECTS

    effects = {e.name: e for e in FORCE_EFFECTS}
    rng = np.random.default_rng(5)
    n = 20
    amplitude = rng.permutation(np.linspace(0.005, 0.05, n))
    natural = 1.0 + 0.01 * rng.standard_normal((n, 2))
    level = (1.0 + 0.08 * (amplitude / amplitude.max()) ** 2)[:, None]
    mu = np.array([13_200.0, 7.2e5, 29_600.0, 12_500.0])

    def model(relative):
        theta = np.tile(mu, (n, 1))
        theta[:, 2:] = mu[2:] * relative
        return ModelFit(terms=(), names=BASE_COEFFICIENTS, mu=mu, mu_sd=0.01 * mu, mu_sandwich_sd=0.01 * mu,
                        theta=theta, alpha=0.5, spread=(0.01, 0.01), phi=np.zeros(n), sigma=np.ones(n),
                        log_marginal=0.0, elpd=np.zeros(n), residuals=())

    positions = np.arange(n) / (n - 1)
    before, after = model(natural * level), model(natural)
    rms_before, rms_after, floor = 107.5, 108.1, 103.2
    hinge = effects["position_friction"]
    assert hinge.absorbed_by == ("Ce", "Fmu") and not hinge.between_tests
    assert effects["stiction"].absorbed_by == ("Ce", "Fmu")
    assert not effects["nonlinear_stiffness"].absorbed_by and not effects["specimen"].absorbed_by
    shrink, basis, residual = _shrink_on_basis(before, after, [hinge], rms_before, rms_after, floor, positions)
    assert basis == "absorbed"
    assert shrink == pytest.approx(_between_test_share(before, after, ("Ce", "Fmu"), positions), rel=1e-12)
    assert shrink > 0.7
    assert residual == pytest.approx(1 - (108.1**2 - 103.2**2) / (107.5**2 - 103.2**2), rel=1e-12)
    assert residual < 0
    drift = effects["drift"]
    assert _shrink_on_basis(before, after, [drift], rms_before, rms_after, floor, positions)[1:] == (
        "between_tests", None)
    assert _shrink_on_basis(before, after, [hinge, drift], rms_before, rms_after, floor, positions)[1] == "absorbed"
    mixed = _shrink_on_basis(before, after, [hinge, effects["specimen"]], rms_before, rms_after, floor, positions)
    assert mixed == (_shrink(rms_before, rms_after, floor), "residual", None)


def test_text_output_of_a_breakaway_finding_gives_the_resting_misfit_and_locates_the_force_residual():
    """A stiction found by the breakaway check: diagnosis.txt gives the stick-slip misfit where
    the table rests (the json's figures) beside the force residual's own, and whether `where`
    locates a negligible excess is judged on the force residual (here at its floor), not on the
    resting misfit (here far above its own)."""
    from bayes_sst.diagnosis._output import format_diagnosis

    data = {"series": "x", "verdict": "verdict: stiction (static_ratio = 1.3)", "selected": ["stiction"],
            "noise_floor": 861.0, "rms_before": 1503.0, "rms_after": 159.0, "shrink": 1.0,
            "shrink_basis": "breakaway", "notes": [],
            "where": [{"region": "large |v| (> 2/3 of peak)", "share": 3.5, "sample_share": 0.6, "excess_ratio": 0.1}],
            "breakaway_check": {"excess": -0.2, "excess_se": 0.1, "z": -2.0, "tests": 20, "reversals": 240,
                                "thresholds": {"excess": 0.15, "z": 5.0}, "used": True,
                                "misfit": {"force_rms": 211.0, "force_noise_floor": 209.0}},
            "ranking": [{"name": "stiction", "score": 0.0, "score_se": 0.0, "rule": "breakaway",
                         "params": {"static_ratio": {"mean": 1.3, "sd": 0.01}}}],
            "base_shift": {"Me": 0.0, "Ke": 0.0, "Ce": 0.0, "Fmu": 0.0, "alpha": 0.0}}
    lines = format_diagnosis(data).splitlines()
    assert lines[3].startswith("where the table rests at its reversals: noise floor 0.861 kN, stick-slip misfit "
                               "before 1.503 kN, after 0.159 kN (force residual 0.211 kN against its floor 0.209 kN)")
    assert "100 % of the excess removed where the table rests" in lines[3]
    assert any(line.strip().startswith("nowhere:") for line in lines)
    # the same figures read as a force residual (basis "residual") are a clear excess
    assert not any(line.strip().startswith("nowhere:")
                   for line in format_diagnosis(dict(data, shrink_basis="residual")).splitlines())
    # the lag that refuses the reading over every reversal, where the run recorded it
    assert "unless the resting reversals lag" not in format_diagnosis(data)
    check = dict(data["breakaway_check"], thresholds={"excess": 0.15, "z": 5.0, "lagged_lead_z": -4.0})
    assert ("selects stiction from 15 % and z 5, unless the resting reversals lag the sweeping ones by over 4 se)"
            in format_diagnosis(dict(data, breakaway_check=check)))


def test_text_output_says_what_the_shrink_is_a_share_of_and_survives_a_missing_shift():
    from bayes_sst.diagnosis._output import format_diagnosis

    data = {"series": "x", "verdict": "verdict: drift (drift = 0.2)", "selected": ["drift"],
            "noise_floor": 390.0, "rms_before": 392.0, "rms_after": 398.0, "shrink": 0.97,
            "shrink_basis": "between_tests", "where": [], "notes": ["T01.csv: column 'a' set aside"],
            "ranking": [{"name": "drift", "score": 60.8, "score_se": 7.2, "params": {"drift": {"mean": 0.2}}}],
            "base_shift": {"Me": 0.001, "Ke": None, "Ce": -0.1, "Fmu": -0.1, "alpha": 0.0}}
    text = format_diagnosis(data)
    assert "97 % of the test-to-test scatter of the per-test coefficients explained" in text
    assert "of the excess" not in text.splitlines()[3]
    assert "Ke n/a" in text and "Ce -10.0 %" in text
    assert "T01.csv: column 'a' set aside" in text
    residual = format_diagnosis(dict(data, shrink_basis="residual", shrink=0.5))
    assert "50 % of the excess removed" in residual.splitlines()[3]
    absorbed = format_diagnosis(dict(data, shrink_basis="absorbed", shrink=1.0, residual_shrink=-0.12)).splitlines()[3]
    assert "100 % of the test-to-test scatter of the per-test coefficients explained" in absorbed
    assert "within the tests -12 % of the residual's excess removed" in absorbed
    assert "[selected:" not in text  # no steps: no rule to name
    ruled = format_diagnosis(dict(data, steps=[{"given": [], "candidates": [], "chosen": "drift",
                                                 "rule": "coefficient_z"}]))
    assert "coefficient >= 4 sd from zero" in next(line for line in ruled.splitlines() if line.startswith(" * drift"))
    # the rule that first took it, not a later check's; the run's thresholds
    checked = format_diagnosis(dict(data, settings={"min_score": 12.0, "z_select": 2.5}, steps=[
        {"given": [], "candidates": [], "chosen": "drift", "rule": "score_z"},
        {"given": [], "candidates": [], "chosen": "drift", "rule": "coefficient_z", "view": "stroke_check"}]))
    assert "score >= 12 nats and >= 2.5 se" in next(line for line in checked.splitlines() if line.startswith(" * drift"))
    # an unselected reading on its bound says so, and the oil column says what its nats are of
    oil = {"name": "oil_column", "score": 5531.7, "score_se": 401.1, "at_bound": True,
           "domain": "command-to-motion frequency response of the broadband tests",
           "params": {"oil_frequency": {"mean": 21.0}},
           "per_payload": [{"bound": "no resonance peak: |H| rises 0.0 % (under 10 %)"}]}
    line = next(line for line in format_diagnosis(dict(data, ranking=data["ranking"] + [oil])).splitlines()
                if line.startswith("   oil_column"))
    assert line.endswith("(on its bound, the base model: no resonance peak: |H| rises 0.0 % (under 10 %); nats of the "
                         "command-to-motion frequency response of the broadband tests)")
    assert "on its bound" not in next(line for line in text.splitlines() if line.startswith(" * drift"))


def test_effect_data_leaves_out_an_acceleration_the_signals_refused():
    from dataclasses import replace

    from bayes_sst.io import TestRecord

    series = simulate("sst-paper", seed=5, plan=default_plan("sst-paper")[:3])
    first = series.periodic_tests[0]
    dead = TestRecord(first.spec, dict(first.columns, a=np.zeros_like(first.columns["a"])))
    broken = replace(series, tests=(dead,) + tuple(series.tests[1:]))
    without = replace(series, tests=(TestRecord(first.spec, {k: v for k, v in first.columns.items() if k != "a"}),)
                      + tuple(series.tests[1:]))
    refused, derived = effect_data(broken)[0], effect_data(without)[0]
    assert len(refused.notes) == 1 and "column 'a'" in refused.notes[0]
    np.testing.assert_allclose(refused.a_full, derived.a_full)
    assert effect_data(series)[0].notes == ()


def test_stiction_is_found_on_the_reversal_view_and_its_ratio_recovered():
    """Static friction 1.4 x Fmu falling over a Stribeck velocity of 20 mm/s (hydraulic-seal
    scale: several samples per reversal at 200 Hz). The reversal view (12f, samples slower than
    2 % of the peak speed weighted out) must select it and recover the ratio; with the earlier
    view (4f, every sample) the Stribeck coefficient came out negative and at its bound."""
    series = simulate("sst-paper", seed=12, spread=0.02, plan=SHORT_PLAN,
                      truth_overrides={"static_ratio": 1.4, "stribeck_velocity": 0.02})
    d = diagnose(series)
    assert d.selected == ["stiction"]
    assert d.reversal["selected"] == ["stiction"]
    top = d.ranking[0]
    assert top["name"] == "stiction" and top.get("view") == "reversal"
    assert top["params"]["static_ratio"]["mean"] == pytest.approx(1.4, rel=0.1)
    assert top["params"]["stribeck_velocity"]["mean"] == pytest.approx(0.02, rel=0.5)
    # a grid value is known at best to within its node's spacing, however peaked the profile
    from bayes_sst.effects import effect_by_name

    grid = np.asarray(effect_by_name("stiction").grid["stribeck_velocity"])
    velocity = top["params"]["stribeck_velocity"]
    others = np.abs(grid - velocity["mean"])
    assert velocity["sd"] >= 0.999 * others[others > 1e-12].min() / np.sqrt(12)
    # the ratio's sd includes how the reading moves over the Stribeck velocity's grid posterior
    ratio = top["params"]["static_ratio"]
    assert ratio["sd"] >= ratio["sd_given_grid"] > 0.0
    # the reversal view's residual falls to its floor once stiction is in
    assert d.reversal["rms_after"] < 1.05 * d.reversal["noise_floor"] < d.reversal["rms_before"]


def test_without_an_accelerometer_a_clean_table_gets_no_specimen():
    """With `a` removed the acceleration is derived from u. Smoothing and central differences
    leave it short by (s^2/2 + h^2/3)*a'', which a stiff specimen's shear below its resonance,
    m_s*(a - a''/w_s^2), makes up: uncorrected, this clean 20-test campaign had a 1.8 t specimen
    at 22 Hz selected (22.7 +- 13.1 nats); with signals.acceleration_from_velocity it scores
    3.4 nats."""
    from dataclasses import replace

    from bayes_sst.io import TestRecord

    series = simulate("sst-paper", seed=21, spread=0.02)
    without = replace(series, tests=tuple(
        TestRecord(r.spec, {k: v for k, v in r.columns.items() if k not in ("a", "v")}) for r in series.tests))
    d = diagnose(without)
    assert d.selected == []
    specimen = next(r for r in d.ranking if r["name"] == "specimen")
    assert specimen["score"] < 10.0


def test_without_an_accelerometer_a_stiction_finding_carries_a_warning():
    """Stiction 1.3 at 10 mm/s with `a` removed: it is found, but the derived acceleration rounds
    off each breakaway, and the ratio reads several times too far from 1 (5.3 +- 0.4 measured
    here), so the diagnosis must say that the ratio rests on it."""
    from dataclasses import replace

    from bayes_sst.io import TestRecord

    series = simulate("sst-paper", seed=21, spread=0.02, truth_overrides={"static_ratio": 1.3, "stribeck_velocity": 0.01})
    without = replace(series, tests=tuple(
        TestRecord(r.spec, {k: v for k, v in r.columns.items() if k not in ("a", "v")}) for r in series.tests))
    d = diagnose(without)
    assert d.selected == ["stiction"]
    assert any(note.startswith("stiction is read at the reversals from an acceleration derived from u")
               for note in d.notes)


@pytest.mark.parametrize("shared", [True, False])
def test_the_sandwich_sd_matches_the_posterior_sd_and_widens_where_the_tests_disagree(shared):
    """Twelve synthetic tests of four base columns and one effect column with white noise. With
    one effect coefficient for all tests the cluster-robust sd (ModelFit.mu_sandwich_sd) agrees
    with the posterior sd; when each test has its own coefficient (scatter 0.3 about 1, the
    model's single coefficient being wrong for each) the posterior sd stays as small while the
    sandwich sd follows the scatter of the tests' own least-squares coefficients, computed here
    independently, divided by sqrt(J)."""
    from bayes_sst.diagnosis._engine import _fit

    rng = np.random.default_rng(8)
    J, n, noise = 12, 400, 0.3
    effect_coefficient = np.ones(J) if shared else 1.0 + 0.3 * rng.standard_normal(J)
    ys, Xs, own = [], [], []
    for j in range(J):
        X = rng.standard_normal((5, n))
        y = np.array([2.0, -1.0, 0.5, 1.5]) @ X[:4] + effect_coefficient[j] * X[4] + noise * rng.standard_normal(n)
        ys.append(y)
        Xs.append(X)
        own.append(np.linalg.lstsq(X.T, y, rcond=None)[0][4])
    fit = _fit(ys, Xs, ("Me", "Ke", "Ce", "Fmu", "effect.c"), np.array([10.0]), 0.5, 0.0, ())
    posterior, sandwich = fit.mu_sd[4], fit.mu_sandwich_sd[4]
    if shared:
        assert sandwich == pytest.approx(posterior, rel=0.35)
    else:
        expected = np.std(own, ddof=1) / math.sqrt(J)
        assert sandwich == pytest.approx(expected, rel=0.35)
        assert sandwich > 5 * posterior


def test_the_plug_in_noise_read_from_the_scored_models_residual_keeps_a_spiky_column_from_halving_it():
    """Twelve synthetic tests, white noise of sd 0.3, and a column that is non-zero on 2 % of the
    samples (a narrow peak at each reversal) on which every test has a misfit of its own,
    +3 in half the tests and -3 in the other half: no common part. With each test's least-squares plug-in the column takes the
    misfit in every test, its sigma reads well under the residual that the model with one
    shared coefficient leaves, and the log marginal falls far under the base model's. With the
    plug-in read from the scored model's residual (_fit's noise_residuals, the reversal view's
    consistent noise) sigma is that residual's sd, computed here independently, and the column
    costs at most its Occam factor (a few nats)."""
    from bayes_sst.diagnosis._engine import _fit

    rng = np.random.default_rng(11)
    J, n, noise = 12, 500, 0.3
    ys, Xs_base, Xs_spiky = [], [], []
    for j in range(J):
        X = rng.standard_normal((4, n))
        spiky = np.zeros(n)
        where = rng.choice(n, size=n // 50, replace=False)
        spiky[where] = 1.0
        misfit = (3.0 if j % 2 else -3.0) * spiky
        ys.append(np.array([2.0, -1.0, 0.5, 1.5]) @ X + misfit + noise * rng.standard_normal(n))
        Xs_base.append(X)
        Xs_spiky.append(np.vstack([X, spiky]))
    names = ("Me", "Ke", "Ce", "Fmu")
    args = (0.5, 0.0, ())
    base = _fit(ys, Xs_base, names, np.zeros(0), *args)
    least_squares = _fit(ys, Xs_spiky, names + ("effect.c",), np.array([10.0]), *args)
    consistent = _fit(ys, Xs_spiky, names + ("effect.c",), np.array([10.0]), *args,
                      noise_residuals=least_squares.residuals)
    model_residual_sd = np.array([np.std(r, ddof=5) for r in least_squares.residuals])
    assert np.all(model_residual_sd > 0.4)  # the misfit is left in the residual by one shared value
    assert np.all(least_squares.sigma < 0.36)  # the free per-test fit took it out of its plug-in
    assert consistent.sigma == pytest.approx(model_residual_sd, rel=0.03)
    assert least_squares.log_marginal - base.log_marginal < -500.0
    assert -8.0 < consistent.log_marginal - base.log_marginal < 2.0


@pytest.mark.parametrize("sample_rate_hz", [200.0, 1000.0])
def test_derived_acceleration_noise_draws_match_the_error_that_u_noise_makes(sample_rate_hz):
    """A 2 Hz sine of 20 mm with 20 um of white noise on u: the draws that the diagnosis carries
    through its errors-in-variables correction without an accelerometer must be as large as
    the error the noise actually leaves in the derived acceleration (noise-free record's
    derived a subtracted), per sample and below 20 Hz (over as many noise records as draws)."""
    from bayes_sst.diagnosis._data import VELOCITY_SMOOTHING_S, derived_acceleration_noise
    from bayes_sst.signals import derived_acceleration as derived
    from bayes_sst.signals import zero_phase_lowpass

    def derived_acceleration(x, rate):
        return derived(x, rate, VELOCITY_SMOOTHING_S)

    fs, f, sigma = sample_rate_hz, 2.0, 20e-6
    t = np.arange(int(30 * fs)) / fs
    u_clean = 0.02 * np.sin(2 * np.pi * f * t)
    rng = np.random.default_rng(4)
    u = u_clean + rng.normal(0.0, sigma, t.size)
    v = 0.02 * 2 * np.pi * f * np.cos(2 * np.pi * f * t)
    lo, hi = int(2 * fs), int(28 * fs)
    error = (derived_acceleration(u, fs) - derived_acceleration(u_clean, fs))[lo:hi]
    draws = derived_acceleration_noise(u, v, 4 * f, fs, lo, hi, np.random.default_rng(5))
    assert draws.shape[1] == hi - lo
    assert np.std(draws) == pytest.approx(np.std(error), rel=0.05)
    # in the band the diagnosis keeps (up to 20 Hz), over as many noise records as draws
    records = [derived_acceleration(rng.normal(0.0, sigma, t.size), fs)[lo:hi] for _ in range(len(draws))]
    in_band = lambda x: np.mean(zero_phase_lowpass(np.asarray(x), 20.0, fs) ** 2)
    assert in_band(draws) == pytest.approx(in_band(records), rel=0.2)


def test_acceleration_of_a_recorded_velocity_is_second_order_exact_and_its_noise_draws_match():
    """From a recorded v (an 8 Hz sine at 200 Hz) the diagnosis's acceleration is within 0.1 %
    of the true one (the smoothing's and the difference's second-order terms taken out; without
    the correction 1.5 %), and the noise draws it carries for a v with 0.2 mm/s of white noise
    are as large as the error that noise leaves, per sample."""
    from bayes_sst.diagnosis._data import (VELOCITY_SMOOTHING_S, acceleration_of_recorded_velocity,
                                           derived_acceleration_noise)
    from bayes_sst.signals import time_derivative
    from scipy.ndimage import gaussian_filter1d

    fs, f = 200.0, 8.0
    w = 2 * np.pi * f
    t = np.arange(int(30 * fs)) / fs
    v_clean = 0.01 * w * np.cos(w * t)
    a_true = -0.01 * w * w * np.sin(w * t)
    lo, hi = int(2 * fs), int(28 * fs)
    peak = 0.01 * w * w
    a = acceleration_of_recorded_velocity(v_clean, fs, VELOCITY_SMOOTHING_S)
    assert np.max(np.abs(a - a_true)[lo:hi]) < 1e-3 * peak
    plain = time_derivative(gaussian_filter1d(v_clean, VELOCITY_SMOOTHING_S * fs), fs)
    assert np.max(np.abs(plain - a_true)[lo:hi]) > 1e-2 * peak

    rng = np.random.default_rng(4)
    v = v_clean + rng.normal(0.0, 2e-4, t.size)
    error = (acceleration_of_recorded_velocity(v, fs, VELOCITY_SMOOTHING_S) - a)[lo:hi]
    draws = derived_acceleration_noise(v, v_clean, 4 * f, fs, lo, hi, np.random.default_rng(5), of_velocity=True)
    assert draws.shape[1] == hi - lo
    assert np.std(draws) == pytest.approx(np.std(error), rel=0.05)


def test_without_an_accelerometer_the_diagnosis_takes_the_acceleration_from_a_quieter_recorded_v():
    """A test without `a` whose recorded v is quieter (0.2 mm/s) than u's second derivative
    (u with 20 um at 200 Hz) gets its acceleration from v, as the fit does; a noisy v (20 mm/s)
    leaves it to u."""
    from bayes_sst.diagnosis._data import quieter_recorded_velocity
    from types import SimpleNamespace

    fs, f = 200.0, 2.0
    w = 2 * np.pi * f
    t = np.arange(int(20 * fs)) / fs
    rng = np.random.default_rng(7)
    u = 0.02 * np.sin(w * t) + rng.normal(0.0, 20e-6, t.size)

    def record(v_noise):
        v = 0.02 * w * np.cos(w * t) + rng.normal(0.0, v_noise, t.size)
        return SimpleNamespace(u=u, sample_rate_hz=fs, get=lambda name: v if name == "v" else None)

    assert quieter_recorded_velocity(record(2e-4), 4 * f) is not None
    assert quieter_recorded_velocity(record(2e-2), 4 * f) is None
    assert quieter_recorded_velocity(SimpleNamespace(u=u, sample_rate_hz=fs, get=lambda name: None), 4 * f) is None


def test_one_periodic_test_is_refused_with_the_reason():
    """The scores leave one test out at a time: with a single sine there is nothing to score
    against (its score_se was infinite and the JSON could not be written)."""
    series = simulate("sst-paper", seed=5, plan=default_plan("sst-paper")[:1])
    with pytest.raises(ValueError, match="1 sine or triangle test.*at least 2"):
        diagnose(series)


@pytest.fixture(scope="module")
def clean_diagnosis():
    series = simulate("sst-paper", seed=11, spread=0.02, plan=SHORT_PLAN)
    return diagnose(series)


def test_clean_series_selects_nothing(clean_diagnosis):
    d = clean_diagnosis
    assert d.selected == []
    assert d.verdict.startswith("verdict: none")
    # residual close to the model-free noise floor: the base model misses nothing
    assert d.rms_before < 1.15 * d.noise_floor
    assert {r["name"] for r in d.ranking} >= {"stiction", "specimen", "channel_delay", "drift"}
    views = {r["name"]: r.get("view") for r in d.ranking}
    assert views["nonlinear_stiffness"] == views["position_friction"] == "stroke"
    assert views["stiction"] == "reversal" and d.reversal["selected"] == []
    # the true spread is 2 % for every coefficient; (Me, Ke) and (Ce, Fmu) have one each
    assert d.stroke["selected"] == [] and max(d.stroke["base"]["spread"]) <= 0.06
    assert max(d.base["spread"]) <= 0.06
    base = d.base
    assert base["Me"] == pytest.approx(TRUTH.Me, rel=0.03)
    assert base["Ke"] == pytest.approx(TRUTH.Ke, rel=0.03)
    assert base["Fmu"] == pytest.approx(TRUTH.Fmu, rel=0.05)


def test_effect_data_views(clean_diagnosis):
    from bayes_sst.diagnosis._data import REVERSAL_SIGNALS, STROKE_SIGNALS

    series = simulate("sst-paper", seed=11, spread=0.02, plan=SHORT_PLAN[:2], noise="quiet")
    # the default view: the fit's reversal band (10 % of the peak speed) left out, and force and
    # regressors weighted before the low-pass
    test = effect_data(series)[0]
    peak = np.percentile(np.abs(test.v_full[test.kept[0]:test.kept[-1]]), 99.5)
    assert np.abs(test.v).min() >= 0.1 * peak * 0.99
    assert test.weight_full is not None and test.weight_full.min() == 0.0
    assert np.all(test.weight_full[test.kept] > 0.0)
    raw = np.asarray(series.periodic_tests[0].F, dtype=float)
    # F is filter(w*F) of the offset-free force: the same as re-reading the raw force with no shift
    assert np.allclose(test.force_at(0.0), test.F, atol=1e-6 * np.abs(test.F).max())
    assert np.abs(test.F - test.filtered(raw[test.lo:test.lo + len(test.F_full)])).max() < 0.01 * np.abs(test.F).max()
    # the reversal view (stiction): cut-off 12f, only the samples slower than 2 % of the peak
    # speed weighted out (where v crosses zero); those slower than 20 % are there
    reversal = effect_data(series, REVERSAL_SIGNALS)[0]
    assert reversal.cutoff_hz == pytest.approx(3 * test.cutoff_hz)
    assert reversal.weight_full is not None
    # the band and weight are set from the 10 ms kernel's velocity; the regressors read the
    # velocity whose fast part comes from the accelerometer (signals.complementary_velocity)
    from dataclasses import replace

    from bayes_sst.signals import prepare_series

    kernel_only = prepare_series(series, replace(REVERSAL_SIGNALS, velocity_with_accelerometer=False))[0]
    v_kernel = kernel_only.velocity_full[reversal.lo:reversal.lo + len(reversal.v_full)]
    assert np.all(reversal.weight_full[np.abs(v_kernel) < 0.02 * peak * 0.99] == 0.0)
    assert np.abs(v_kernel[np.isin(np.arange(len(v_kernel)) + reversal.lo, reversal.index)]).min() >= 0.02 * peak * 0.95
    assert 0.0005 < np.max(np.abs(reversal.v_full - v_kernel)) < 0.1 * peak
    assert np.mean(np.abs(reversal.v) < 0.2 * np.max(np.abs(reversal.v))) > 0.05
    # the stroke view (effects growing with |u|): cut-off 8f, samples slower than 35 % of the peak left out
    stroke = effect_data(series, STROKE_SIGNALS)
    assert stroke[0].cutoff_hz == pytest.approx(2 * test.cutoff_hz)
    speed = np.abs(stroke[0].v)
    assert speed.min() >= 0.35 * np.percentile(np.abs(stroke[0].v_full), 99.5) * 0.9


def test_accelerometer_noise_does_not_pull_the_base_model_down():
    """Errors in variables: with 0.12 m/s^2 of white accelerometer noise (4x the twin's), least
    squares on the noisy a puts Me and Ke 13-19 % low (measured: the per-test Me and Ke of a
    sine are told apart by a's harmonics alone); the correction subtracts what the noise adds to
    the moments, and the bound on Me's and Ke's spread keeps the population from following the
    per-test values the noise still moves. Read as recorded: the default view averages a over
    the cycles where a period is a whole number of samples, as the twin's are (a test below),
    and the correction is what remains where none is."""
    from dataclasses import replace

    from bayes_sst.diagnosis._data import DIAGNOSIS_SIGNALS
    from bayes_sst.diagnosis._engine import Scorer
    from bayes_sst.diagnosis._screen import fit_base
    from bayes_sst.twin._noise import SensorNoise

    series = simulate("sst-paper", seed=5, spread=0.02, noise=replace(SensorNoise(), a_white=0.12))
    tests = effect_data(series, replace(DIAGNOSIS_SIGNALS, periodic_acceleration=False))
    assert all(t.a_noise_full is not None for t in tests)
    corrected = fit_base(Scorer(tests)).base()
    plain = fit_base(Scorer([replace(t, a_noise_full=None) for t in tests])).base()
    assert corrected["Me"] == pytest.approx(TRUTH.Me, rel=0.02)
    assert corrected["Ke"] == pytest.approx(TRUTH.Ke, rel=0.02)
    assert plain["Me"] < 0.9 * TRUTH.Me and plain["Ke"] < 0.9 * TRUTH.Ke


def test_the_noise_correction_stops_where_the_design_moments_turn_indefinite():
    """noise_scale_limit against a bisection on the smallest eigenvalue of W_x - t*C_x: noise in
    one column (rank 1), in two (an effect column that reads a), and a design with a column that
    repeats two others (singular W_x, the noise outside its null space). The limit must be
    the boundary itself, so that a correction scaled to it is continuous in the design; the
    factor is the smaller of it (less NOISE_KEEP) and the share that leaves NOISE_KEEP of the
    noise in what the other columns leave unexplained in a, computed here by least squares."""
    from bayes_sst.diagnosis._engine import noise_factor, noise_scale_limit
    from bayes_sst.signals._noise import NOISE_KEEP

    rng = np.random.default_rng(11)

    def smallest(W, C, t):
        return np.linalg.eigvalsh(W[1:, 1:] - t * C[1:, 1:]).min()

    for case in ("one", "two", "repeated"):
        Z = rng.standard_normal((6, 80))
        if case == "repeated":
            Z[5] = 0.7 * Z[3] - 1.3 * Z[4]
        W = Z @ Z.T
        noise = np.zeros((6, 80))
        noise[1] = 0.4 * rng.standard_normal(80)
        if case == "two":
            noise[5] = 0.5 * noise[1] + 0.3 * rng.standard_normal(80)
        C = noise @ noise.T
        limit = noise_scale_limit(W, C)
        low, high = 0.0, 1e6
        scale = np.abs(np.linalg.eigvalsh(W[1:, 1:])).max()
        for _ in range(200):
            middle = 0.5 * (low + high)
            low, high = (middle, high) if smallest(W, C, middle) >= -1e-12 * scale else (low, middle)
        assert limit == pytest.approx(low, rel=1e-6), case
        assert smallest(W, C, 1.001 * limit) < 0.0
        # and never more than leaves NOISE_KEEP of the noise in the part of a the others leave
        explained = np.linalg.lstsq(Z[2:].T, Z[1], rcond=None)[0] @ Z[2:]
        first = (np.sum((Z[1] - explained) ** 2) - NOISE_KEEP * C[1, 1]) / C[1, 1]
        assert noise_factor(W, C) == pytest.approx(min(1.0, max(0.0, first), max(0.0, limit - NOISE_KEEP)))
    assert noise_scale_limit(W, np.zeros_like(W)) == math.inf


def test_a_term_that_repeats_the_base_columns_within_each_test_gains_nothing():
    """Drift's column within a test is -s_j*(Fmu*sign + Ce*damping), the base's own columns: with
    the drift coefficient near zero the extended model is the base model, and its score must be
    the Occam cost of one more coefficient, not a gain. Measured before the change: +7.7 nats of
    log marginal and +10.1 of elpd on this series (a solve on the singular moments had turned the
    errors-in-variables correction off, and the repeated column took a degree of freedom from
    the plug-in sigma); after, -3.7 and -1.0."""
    from dataclasses import replace

    from bayes_sst.diagnosis._data import DIAGNOSIS_SIGNALS
    from bayes_sst.diagnosis._engine import Scorer
    from bayes_sst.diagnosis._screen import fit_base
    from bayes_sst.effects import FORCE_EFFECTS
    from bayes_sst.twin._noise import SensorNoise

    series = simulate("sst-paper", seed=5, spread=0.02, noise=replace(SensorNoise(), a_white=0.12))
    tests = effect_data(series, replace(DIAGNOSIS_SIGNALS, periodic_acceleration=False))
    scorer = Scorer(tests)
    base = fit_base(scorer)
    drift = next(e for e in FORCE_EFFECTS if e.name == "drift")
    extended = scorer.fit([(drift, {})], base.alpha, spread=base.spread)
    assert abs(extended.coefficient("drift.drift")) < 2.0 * extended.mu_sd[-1]
    assert extended.log_marginal - base.log_marginal < 0.0
    assert float(np.sum(extended.elpd - base.elpd)) < 2.0


def test_force_read_later_through_the_reversal_weight():
    # force_at(d) = filter(w(t)*F(t + d)) at the kept samples, F(t + d) between samples by a
    # cubic spline: against the same expression with F known in closed form
    from bayes_sst.effects import EffectData

    rate, f = 200.0, 1.3
    n = int(12 * rate)
    t = np.arange(n) / rate

    def force(time):
        return 9000.0 * np.sin(2 * np.pi * f * time) + 2500.0 * np.sin(2 * np.pi * 3 * f * time + 0.4)

    v = np.cos(2 * np.pi * f * t)
    weight = np.clip((np.abs(v) - 0.1) / 0.1, 0.0, 1.0)
    zeros = np.zeros(n)
    test = EffectData(id="X", frequency_hz=f, amplitude_m=0.01, payload_kg=0.0, position=0.0, strut_h=1.0,
                      sample_rate_hz=rate, cutoff_hz=4 * f, lo=0, index=np.arange(200, n - 200, 9),
                      u_full=zeros, v_full=v, a_full=zeros, F_full=zeros, a_record=zeros,
                      period_samples=rate / f, weight_full=weight, F_raw=force(t))
    for delay in (0.0007, 0.003, -0.0011):
        expected = test.filtered(force(t + delay))
        assert np.abs(test.force_at(delay) - expected).max() < 3e-4 * 9000.0


def test_diagnose_command_finds_a_withheld_channel_delay(tmp_path, capsys):
    series = simulate("sst-paper", seed=12, spread=0.02, plan=SHORT_PLAN, truth_overrides={"force_delay": 0.003})
    write_series(series, tmp_path / "series")
    out = tmp_path / "diag"
    assert main(["diagnose", str(tmp_path / "series"), "--out", str(out)]) == 0
    assert "channel_delay" in capsys.readouterr().out
    data = json.loads((out / "diagnosis.json").read_text())
    page = (out / "diagnosis.html").read_text()
    assert page.startswith("<!doctype html>")
    assert "holds through its reversals" not in page  # that figure is a breakaway finding's only
    assert set(data) >= {"selected", "ranking", "where", "noise_floor", "rms_before", "rms_after", "shrink",
                         "base_shift"}
    assert data["selected"][0] == "channel_delay"
    assert data["ranking"][0]["name"] == "channel_delay"
    assert data["ranking"][0]["params"]["delay"]["mean"] == pytest.approx(0.003, rel=0.2)
    assert data["shrink"] >= 0.7
    assert data["rms_after"] < data["rms_before"]
    assert all({"name", "score", "score_se", "params"} <= set(r) for r in data["ranking"])
    assert all({"region", "share"} <= set(w) for w in data["where"])
    # a taken folder is refused with exit code 2
    assert main(["diagnose", str(tmp_path / "series"), "--out", str(out)]) == 2


@pytest.mark.parametrize("delay, edge", [(0.02, None), (0.06, "upper")])
def test_a_long_delay_is_read_on_the_coarse_grid_and_one_beyond_it_is_flagged(delay, edge):
    """Delays of 12-40 ms are searched in 0.5 ms steps (refined to 0.05 ms): 20 ms is read to
    0.1 ms, alone (at the old 12 ms bound a 15 ms delay came back as 12 ms with a spurious
    specimen beside it). 60 ms lies beyond the grid: the delay is still selected, at 40 ms, and
    a note says the value is a bound."""
    series = simulate("sst-paper", seed=12, spread=0.02, plan=SHORT_PLAN, truth_overrides={"force_delay": delay})
    d = diagnose(series)
    assert d.selected[0] == "channel_delay"
    entry = next(r for r in d.ranking if r["name"] == "channel_delay")
    edge_notes = [n for n in d.notes if "end of its searched range" in n]
    if edge is None:
        assert d.selected == ["channel_delay"]
        assert entry["params"]["delay"]["mean"] == pytest.approx(delay, abs=1e-4)
        assert entry["grid_edge"] == {} and edge_notes == []
    else:
        assert entry["grid_edge"] == {"delay": "upper"}
        assert entry["params"]["delay"]["mean"] >= 0.0398
        assert edge_notes and edge_notes[0].startswith("channel_delay: delay is at the upper end")
        from bayes_sst.diagnosis._output import format_diagnosis

        assert edge_notes[0] in format_diagnosis(d.to_json())


def test_the_delay_grid_weights_keep_its_prior_uniform():
    """The delay grid coarsens from 0.25 to 0.5 ms beyond 12 ms; each setting's weight is its
    cell width, so the weights integrate a uniform prior over -10..40 ms."""
    from bayes_sst.effects import effect_by_name

    delay = effect_by_name("channel_delay")
    values = np.array([s["delay"] for s in delay.settings()])
    weights = np.array([delay.grid_weight(s) for s in delay.settings()])
    assert values.min() == pytest.approx(-0.01) and values.max() == pytest.approx(0.04)
    # an inner point's weight is the width between the midpoints to its neighbours (0.25 ms units)
    cells = (values[2:] - values[:-2]) / 2
    np.testing.assert_allclose(weights[1:-1], cells / 0.00025, rtol=1e-6)
    assert weights[values < 0.0119].tolist() == [1.0] * int(np.sum(values < 0.0119))
    assert np.sum(weights[1:-1] * 0.00025) + 0.00025 / 2 + 0.0005 / 2 == pytest.approx(0.05)
    # the refinement spans the coarse step around the best setting either side
    for d0 in (0.005, 0.02):
        steps = np.array([s["delay"] for s in delay.refine({"delay": d0})]) - d0
        step = 0.00025 if d0 <= 0.012 else 0.0005
        assert steps.min() < -step / 2 and steps.max() > step / 2


# --- withheld-effect study (slow): one effect switched on, the 20-test reference campaign --------

K3 = strut_cubic_stiffness(TRUTH.Ke, TRUTH.strut_gamma, TRUTH.strut_h, TRUTH.strut_l0)
WITHHELD = [
    # name, overrides, {reported parameter: true value}, shrink asserted
    pytest.param("channel_delay", {"force_delay": 0.003}, {"delay": 0.003}, True, id="delay-3ms"),
    pytest.param("channel_delay", {"force_delay": 0.001}, {"delay": 0.001}, True, id="delay-1ms-weak"),
    pytest.param("specimen", {"specimen_mass": 3000.0, "specimen_frequency": 8.0},
                 {"specimen_mass": 3000.0, "specimen_frequency": 8.0}, True, id="specimen-3t-8Hz"),
    pytest.param("specimen", {"specimen_mass": 5000.0, "specimen_frequency": 12.0, "specimen_damping": 0.05},
                 {"specimen_mass": 5000.0, "specimen_frequency": 12.0}, True, id="specimen-5t-12Hz"),
    # a tall specimen's first mode among the test frequencies (measured: 2.03 t at 1.49 Hz)
    pytest.param("specimen", {"specimen_mass": 2000.0, "specimen_frequency": 1.5, "specimen_damping": 0.03},
                 {"specimen_mass": 2000.0, "specimen_frequency": 1.5}, True, id="specimen-2t-1.5Hz"),
    # drift acts between tests: the per-test coefficients absorb it in-sample, so its shrink is
    # the share of their excess test-to-test scatter it explains (measured 1.00 for 15 % and 5 %,
    # the scatter left at its floor; residual shrink ~0)
    pytest.param("drift", {"friction_drift": 0.15, "damping_drift": 0.15}, {"drift": 0.15}, True, id="drift-15%"),
    # weak: 6.5 nats, below MIN_SCORE; selected by its coefficient's z (4.5, COEFFICIENT_Z)
    pytest.param("drift", {"friction_drift": 0.05, "damping_drift": 0.05}, {"drift": 0.05}, True, id="drift-5%-weak"),
    # selected by its coefficient's z (score ~8 nats, under MIN_SCORE); K'e reads -13 % on this
    # seed, its posterior sd being 19 % (+21 % and +31 % on seeds 31 and 32: docs/diagnosis.md)
    # (no shrink asserted: the stroke view's RMS is already under its floor, so it is 1 trivially)
    pytest.param("nonlinear_stiffness", {"cubic_stiffness": 3 * K3}, {"cubic_stiffness": 3 * K3}, False,
                 id="cubic-3x"),
    # scored on the stroke view (8f, reversal band 35 %), where the rest-interval misfit is left out
    pytest.param("position_friction", {"position_friction": 1.5e5}, {"position_friction": 1.5e5}, True,
                 id="hinge-1.5e5"),
    # at the twin's default Stribeck velocity, 5 mm/s, the friction peak is shorter than one
    # 5 ms sample at most reversals: found, but near the resolution (1.3 came out at 1.7)
    pytest.param("stiction", {"static_ratio": 1.5}, {"static_ratio": 1.5}, True, id="stiction-1.5"),
    pytest.param("stiction", {"static_ratio": 1.3, "stribeck_velocity": 0.01}, {"static_ratio": 1.3}, True,
                 id="stiction-1.3-10mm/s"),
]


@pytest.mark.slow
@pytest.mark.parametrize("name, overrides, params, check_shrink", WITHHELD)
def test_withheld_effect_is_found_and_recovered(name, overrides, params, check_shrink):
    series = simulate("sst-paper", seed=21, spread=0.02, truth_overrides=overrides)
    d = diagnose(series)
    assert d.ranking[0]["name"] == name
    assert d.selected == [name]
    # a side view's finding is in the model the default view's effects are scored against
    from bayes_sst.diagnosis._diagnose import REVERSAL_EFFECTS, STROKE_EFFECTS

    assert d.steps[0]["given"] == ([name] if name in STROKE_EFFECTS + REVERSAL_EFFECTS else [])
    assert any(step.get("chosen") == name and step["rule"] for step in d.steps)
    if check_shrink:
        assert d.shrink >= 0.7
    if name == "position_friction":  # its shrink is read on the per-test friction it took in
        assert d.shrink_basis == "absorbed" and d.residual_shrink is not None
    for key, true in params.items():
        assert d.ranking[0]["params"][key]["mean"] == pytest.approx(true, rel=0.2)


@pytest.mark.slow
def test_a_weak_cubic_is_found_by_its_coefficient_z_and_read_within_its_uncertainty():
    """3x the gas strut's K'e on the twin (seed 21): under every score rule (about 8 nats), its
    coefficient 4.7 sds from zero. Selected by the coefficient rule alone, with nothing
    beside it, and its K'e within 2 posterior sds of the truth."""
    series = simulate("sst-paper", seed=21, spread=0.02, truth_overrides={"cubic_stiffness": 3 * K3})
    d = diagnose(series)
    assert d.selected == ["nonlinear_stiffness"]
    step = next(step for step in d.steps if step.get("chosen") == "nonlinear_stiffness")
    assert step["rule"] == "coefficient_z"
    cubic = next(r for r in d.ranking if r["name"] == "nonlinear_stiffness")
    assert cubic["score"] < 15.0
    k3 = cubic["params"]["cubic_stiffness"]
    assert abs(k3["mean"] - 3 * K3) <= 2.0 * k3["sd"]


@pytest.mark.slow
def test_a_side_view_finding_beside_a_default_view_finding_is_kept_when_real():
    """A true stiction (1.4 at 20 mm/s) and a true 3 t specimen at 8 Hz: the specimen is found
    on the default view, and the reversal view's second screening, with the specimen in its
    model, adds stiction (alone, the specimen's ringing raised that view's RMS 0.8 % with it and
    the loss-scaled rule asks the RMS to fall; an independent generator's series without an
    accelerometer, where the stiction was the specimen's ringing, lost it in that screening)."""
    series = simulate("sst-paper", seed=21, spread=0.02, truth_overrides={
        "specimen_mass": 3000.0, "specimen_frequency": 8.0, "static_ratio": 1.4, "stribeck_velocity": 0.02})
    d = diagnose(series)
    assert sorted(d.selected) == ["specimen", "stiction"]
    entries = {r["name"]: r["params"] for r in d.ranking}
    assert entries["stiction"]["static_ratio"]["mean"] == pytest.approx(1.4, rel=0.1)
    assert entries["specimen"]["specimen_frequency"]["mean"] == pytest.approx(8.0, rel=0.05)
    assert entries["specimen"]["specimen_mass"]["mean"] == pytest.approx(3000.0, rel=0.2)
    assert "dropped_given_default_view" not in d.reversal
    assert d.reversal["added_given_default_view"] == ["stiction"]
    assert next(r for r in d.ranking if r["name"] == "stiction")["given"] == ["specimen"]
    # the view reports the screening that took stiction: the specimen in its base, stiction lowering it
    assert d.reversal["given"] == ["specimen"] == d.reversal["check"]["given"]
    assert d.reversal["rms_before"] == d.reversal["check"]["rms_before"]
    assert d.reversal["rms_after"] < d.reversal["rms_before"] and d.reversal["shrink"] > 0.0


@pytest.mark.slow
def test_without_an_accelerometer_a_clean_1khz_series_of_the_independent_generator_stays_clean(tmp_path):
    """The independent generator's clean series at 1000 Hz (seed 0) with `a` and `v` removed.
    Before the displacement noise was carried through the derived acceleration (2026-11-26) a
    4.6 t specimen at 17 Hz was selected here (22.7 +- 9.1 nats, 7.3 sds from zero); with the
    draws it stands about 2 sds from zero and nothing is claimed."""
    import sys
    from dataclasses import replace
    from pathlib import Path

    from bayes_sst.diagnosis._diagnose import DERIVED_AMPLITUDE_Z
    from bayes_sst.io import TestRecord, load_series

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    from independent_generator import make_series

    make_series(0, str(tmp_path / "series"), sample_rate_hz=1000)
    series = load_series(tmp_path / "series")
    without = replace(series, tests=tuple(
        TestRecord(r.spec, {k: v for k, v in r.columns.items() if k not in ("a", "v")}) for r in series.tests))
    d = diagnose(without)
    assert d.selected == []
    specimen = next(r for r in d.ranking if r["name"] == "specimen")
    assert specimen["amplitude_z"] < DERIVED_AMPLITUDE_Z / 2


@pytest.mark.slow
def test_a_side_view_finding_that_the_default_views_finding_explains_is_dropped(tmp_path, monkeypatch):
    """The independent generator's series (benchmarks/independent_generator.py, seed 1) with a
    3 t specimen at 9 Hz, recorded without an accelerometer. Its ringing after every reversal
    had stiction selected on the reversal view beside the specimen until the derived
    acceleration's noise went through the errors-in-variables correction (2026-11-26); now the
    reversal view selects nothing. The check that drops such a finding is exercised by putting
    stiction into the reversal view's selection by hand: re-scored with the specimen in that
    view's model it is dropped, and the view reports its base model again."""
    import sys
    from dataclasses import replace
    from pathlib import Path

    from bayes_sst.diagnosis import _diagnose
    from bayes_sst.io import TestRecord, load_series

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    from independent_generator import make_series

    make_series(1, str(tmp_path / "series"), effects={"specimen_mass": 3000.0, "specimen_frequency": 9.0,
                                                      "specimen_damping": 0.03})
    series = load_series(tmp_path / "series")
    without = replace(series, tests=tuple(
        TestRecord(r.spec, {k: v for k, v in r.columns.items() if k not in ("a", "v")}) for r in series.tests))
    d = diagnose(without)
    assert d.selected == ["specimen"] and d.reversal["selected"] == []
    assert "dropped_given_default_view" not in d.reversal

    side_view = _diagnose._side_view

    def with_stiction(series, effects, options, view, say, timings, given=(), scorer=None):
        summary, terms, figures, scorer = side_view(series, effects, options, view, say, timings, given, scorer)
        if view == "reversal":
            stiction = next(e for e in effects if e.name == "stiction")
            terms = terms + [(stiction, {"stribeck_velocity": 0.01})]
            summary = dict(summary, selected=summary["selected"] + ["stiction"])
        return summary, terms, figures, scorer

    monkeypatch.setattr(_diagnose, "_side_view", with_stiction)
    d = diagnose(without)
    assert d.selected == ["specimen"]
    assert d.reversal["dropped_given_default_view"] == ["stiction"]
    assert d.reversal["selected"] == [] and d.reversal["check"]["given"] == ["specimen"]
    assert d.reversal["rms_after"] == d.reversal["rms_before"] and d.reversal["shrink"] == 0.0
    specimen = next(r for r in d.ranking if r["name"] == "specimen")["params"]
    assert specimen["specimen_frequency"]["mean"] == pytest.approx(9.0, rel=0.05)
    assert any("derived from u" in note for note in d.notes)


@pytest.mark.slow
@pytest.mark.parametrize("seed", [31, 32, 33])
def test_clean_reference_campaigns_select_nothing(seed):
    assert diagnose(simulate("sst-paper", seed=seed, spread=0.02)).selected == []


@pytest.mark.slow
@pytest.mark.parametrize("seed", [1, 2])
def test_clean_randomised_tables_select_nothing(seed):
    # independent-lab-like tables (random_series): +-25 % parameters, alpha 0.35-0.9, spread 2-4 %,
    # noise x0.5-2, and a static-to-kinetic ratio up to 1.15 that the twin always had
    from bayes_sst.twin import random_series

    assert diagnose(random_series(seed)).selected == []


def test_coefficient_trends_read_which_coefficient_fell_over_the_campaign():
    """Per-test values with friction falling 20 % over the campaign and damping flat, each with
    2 % scatter: the trend of Fmu reads 0.2 and that of Ce 0, each within 3 of its sds, the sds
    near the least-squares value 0.02*sqrt(12/J) for J evenly spread tests."""
    from types import SimpleNamespace

    from bayes_sst.diagnosis._diagnose import _coefficient_trends

    rng = np.random.default_rng(3)
    J = 40
    s = np.linspace(0.0, 1.0, J)
    mu = {"Me": 13200.0, "Ke": 7.2e5, "Ce": 2.96e4, "Fmu": 1.25e4}
    names = ["Me", "Ke", "Ce", "Fmu"]
    theta = np.column_stack([mu[n] * (1 + 0.02 * rng.standard_normal(J)) for n in names])
    theta[:, 3] *= 1 - 0.2 * s
    fit = SimpleNamespace(names=names, theta=theta, coefficient=lambda n: mu[n])
    trends = _coefficient_trends(fit, ("Ce", "Fmu"), s)
    assert set(trends) == {"Ce", "Fmu"}
    assert abs(trends["Fmu"]["rate"] - 0.2) < 3 * trends["Fmu"]["sd"]
    assert abs(trends["Ce"]["rate"]) < 3 * trends["Ce"]["sd"]
    assert trends["Ce"]["sd"] == pytest.approx(0.02 * math.sqrt(12 / J), rel=0.35)
    # three tests at least, spread over the campaign
    assert _coefficient_trends(fit, ("Fmu",), np.zeros(J)) == {}


# --- oil column (broadband tests) --------------------------------------------------------------------

def _broadband_record(test_id, response, seed, fs=500.0, n=60_000):
    """A broadband test whose deck acceleration is the command through `response` (a function of
    frequency, Hz), with 2 % measurement noise."""
    from bayes_sst.io import TestRecord, TestSpec

    rng = np.random.default_rng(seed)
    x = rng.standard_normal(n)
    f = np.fft.rfftfreq(n, 1.0 / fs)
    y = np.fft.irfft(np.fft.rfft(x) * response(f), n) + 0.02 * rng.standard_normal(n)
    t = np.arange(n) / fs
    return TestRecord(TestSpec(test_id, f"{test_id}.csv", "broadband"), {"t": t, "u": 0 * t, "F": 0 * t, "a": y,
                                                                         "a_cmd": x})


def test_a_loop_that_only_lags_has_no_oil_column_and_a_resonance_in_band_is_found():
    from bayes_sst.diagnosis._oil import oil_column_check
    from bayes_sst.io import Series

    def lag(f):  # 4 ms loop delay and a roll-off at 40 Hz: a closed loop without a resonance
        return np.exp(-2j * np.pi * f * 0.004) / (1.0 + 1j * f / 40.0)

    def resonance(f, f_o=22.0, zeta=0.15):  # the effect's own form: a delay and a resonance
        return np.exp(-2j * np.pi * f * 0.004) * f_o**2 / (f_o**2 - f * f + 2j * zeta * f_o * f)

    quiet = oil_column_check(Series("lag", (_broadband_record("B01", lag, 1),)))
    # a flat base took such a lag for a resonance near its roll-off (an independent generator's
    # clean series: 644,000 nats)
    assert quiet["score"] < 15.0 or quiet["at_bound"], quiet
    ringing = oil_column_check(Series("ring", (_broadband_record("B01", resonance, 2),)))
    peak = ringing["per_payload"][0]
    assert ringing["score"] > 1000.0 and ringing["z"] > 5.0 and not ringing["at_bound"]
    assert peak["oil_frequency"]["mean"] == pytest.approx(22.0, rel=0.02)
    assert peak["oil_damping"]["mean"] == pytest.approx(0.15, rel=0.1)
    assert peak["delay_s"] == pytest.approx(0.004, abs=0.0005)
    assert peak["peak_frequency_hz"] == pytest.approx(22.0 * math.sqrt(1 - 2 * 0.15**2), rel=0.02)
    # the entry's params, which diagnosis.json's ranking and the page show, carry the peak too
    assert ringing["params"]["peak_frequency"]["mean"] == peak["peak_frequency_hz"]
    assert ringing["params"]["oil_frequency"] == peak["oil_frequency"]
    # a series without a table description has no analytic frequency to stand beside it
    assert peak["analytic_frequency_hz"] is None and peak["analytic_ratio"] is None


@pytest.mark.parametrize("zeta, claimed", [(0.7, False), (0.6, False), (0.3, True)])
def test_a_loop_that_tracks_as_a_second_order_response_is_an_oil_column_only_with_a_peak(zeta, claimed):
    """A servo loop modelled as the textbook second-order tracking response, 20 Hz with zeta
    0.7 and 2 ms of delay, has no resonance peak (|H| at most 1.0002 times its gain); it was
    fitted at zeta 0.686 and claimed at 451,000 nats until MIN_PEAK_RISE. zeta 0.6 lifts |H| by
    4 %, under the 10 % asked; zeta 0.3 by 75 %, an oil column."""
    from bayes_sst.diagnosis._oil import MIN_PEAK_RISE, oil_column_check, peak_rise
    from bayes_sst.io import Series

    def loop(f, f_n=20.0):
        return np.exp(-2j * np.pi * f * 0.002) * f_n**2 / (f_n**2 - f * f + 2j * zeta * f_n * f)

    check = oil_column_check(Series("servo", (_broadband_record("B01", loop, 3),)))
    entry = check["per_payload"][0]
    assert check["at_bound"] is (not claimed)
    assert entry["peak_rise"] == pytest.approx(peak_rise(entry["oil_damping"]["mean"]), rel=1e-12)
    if claimed:
        assert entry["oil_damping"]["mean"] == pytest.approx(0.3, rel=0.1) and entry["bound"] is None
        assert entry["oil_frequency"]["mean"] == pytest.approx(20.0, rel=0.02)
    else:
        assert entry["peak_rise"] < MIN_PEAK_RISE and entry["bound"].startswith("no resonance peak")
    # the rise by hand: zeta 0.3 -> 1/(2*0.3*sqrt(0.91)) = 1.747; no peak from 1/sqrt(2) on
    assert peak_rise(0.3) == pytest.approx(1.7471, abs=1e-4) and peak_rise(0.75) == 1.0


def test_the_oil_check_skips_tests_without_a_command_and_a_flat_loop_writes_as_json():
    import json

    from bayes_sst.diagnosis._oil import oil_column_check
    from bayes_sst.io import Series, TestRecord

    flat = _broadband_record("B01", lambda f: np.ones_like(f), 4)
    check = oil_column_check(Series("flat", (flat,)))
    # the best base of a loop that neither lags nor rolls off has no roll-off: null, not infinity
    assert check["per_payload"][0]["base"]["roll_off_hz"] is None
    json.dumps(check, allow_nan=False)
    bare = TestRecord(flat.spec, {k: v for k, v in flat.columns.items() if k != "a_cmd"})
    assert oil_column_check(Series("bare", (bare,))) is None
    with_bare = oil_column_check(Series("mixed", (flat, TestRecord(flat.spec.__class__("B02", "B02.csv", "broadband"),
                                                                   bare.columns))))
    assert with_bare["per_payload"][0]["base"]["roll_off_hz"] is None


def test_the_twins_oil_column_is_found_at_its_closed_loop_resonance():
    from bayes_sst.diagnosis._oil import oil_column_check
    from bayes_sst.twin._plan import broadband_plan

    series = simulate(plan=broadband_plan((0.0, 10_000.0), ("noise",)), seed=1)
    check = oil_column_check(series)
    assert not check["at_bound"] and check["z"] > 5.0
    for entry in check["per_payload"]:
        truth = next(r for r in series.tests if r.spec.payload_kg == entry["payload_kg"]).spec.extra["truth"]
        # measured 2026-11-27: peaks -0.8 % and -0.2 % off, natural frequencies +3.5 % and +5.8 %
        # (the flat base's -3.4 % and +1.0 %: without the loop's delay f_o is the peak's stand-in)
        assert entry["peak_frequency_hz"] == pytest.approx(truth["resonance_hz"], rel=0.03)
        assert entry["oil_frequency"]["mean"] == pytest.approx(truth["resonance_hz"], rel=0.2)
        # the described table's f_oil = sqrt(2*beta*A^2/(V*(deck + payload)))/2pi, by hand
        oil = series.table["oil"]
        by_hand = math.sqrt(2.0 * oil["bulk_modulus_pa"] * oil["piston_area_m2"] ** 2 / oil["oil_volume_m3"]
                            / (series.table["deck_mass_kg"] + entry["payload_kg"])) / (2.0 * math.pi)
        assert entry["analytic_frequency_hz"] == pytest.approx(by_hand, rel=1e-12)
        assert entry["analytic_ratio"] == pytest.approx(entry["oil_frequency"]["mean"] / by_hand, rel=1e-12)


def test_a_twin_with_a_stiff_oil_column_has_no_resonance_to_claim():
    """The twin's oil column is switched off by stiffening it: ten times the oil's bulk modulus
    puts f_oil at sqrt(10) times the nominal, about 91 Hz, where the loop shows no peak (its
    truth's resonance_hz is None; simulate refused such a table until 2026-12-02). The oil
    check then finds a loop that only lags and claims nothing."""
    from bayes_sst.diagnosis._oil import oil_column_check
    from bayes_sst.twin._plan import broadband_plan

    plan = broadband_plan((0.0,), ("noise",))
    nominal = simulate(plan=plan, seed=1).tests[0].spec.extra["truth"]
    stiff = simulate(plan=plan, seed=1, truth_overrides={"bulk_modulus": 10 * TRUTH.bulk_modulus})
    truth = stiff.tests[0].spec.extra["truth"]
    assert truth["resonance_hz"] is None and stiff.extra["truth"]["resonance_hz"] is None
    assert truth["f_oil_hz"] == pytest.approx(math.sqrt(10.0) * nominal["f_oil_hz"], rel=1e-9)
    check = oil_column_check(stiff)
    assert check["at_bound"]


@pytest.mark.slow
def test_broadband_tests_on_a_clean_twin_claim_its_oil_column_only_where_it_rings():
    """A clean campaign with a broadband test: with the preset's column (28.6 Hz) the diagnosis
    selects oil_column, and nothing else; with the column stiffened out of the band, nothing.
    Measured 2026-12-02 (seed 11): f_o 29.6 Hz, peak 28.4 Hz; the stiff table's verdict none
    with its force residual at 213 N against a 229 N floor; 17-19 s each."""
    from bayes_sst.twin._plan import broadband_plan

    plan = list(SHORT_PLAN) + broadband_plan((0.0,), ("noise",))
    series = simulate("sst-paper", seed=11, spread=0.02, plan=plan)
    ringing = diagnose(series)
    assert ringing.selected == ["oil_column"]
    peak = ringing.oil["per_payload"][0]
    broadband = next(r for r in series.tests if r.spec.kind == "broadband")
    assert peak["peak_frequency_hz"] == pytest.approx(broadband.spec.extra["truth"]["resonance_hz"], rel=0.03)
    stiff = diagnose(simulate("sst-paper", seed=11, spread=0.02, plan=plan,
                              truth_overrides={"bulk_modulus": 10 * TRUTH.bulk_modulus}))
    assert stiff.selected == []
    assert stiff.rms_before < 1.15 * stiff.noise_floor


def test_a_reading_on_its_bound_ranks_after_every_other_unselected_effect():
    """The ninth simulator's weak cubic stiffness (2026-12-02): nothing selected, the oil
    column's smooth-loop fit (no peak, on its bound) at 5,532 nats stood first by score, above
    the withheld cubic term's 3.7. Selected effects keep their selection order; among the rest
    a bound reading comes last whatever its score."""
    from bayes_sst.diagnosis._diagnose import ranked

    def entry(name, score, at_bound=False):
        return {"name": name, "score": score, "score_se": 1.0, "at_bound": at_bound}

    ninth_weak_cubic = [entry("nonlinear_stiffness", 3.7), entry("channel_delay", 0.3),
                        entry("specimen", 0.0, at_bound=True), entry("oil_column", 5531.7, at_bound=True),
                        entry("drift", -1.2)]
    assert [r["name"] for r in ranked(ninth_weak_cubic, [])] == [
        "nonlinear_stiffness", "channel_delay", "drift", "oil_column", "specimen"]
    # a selected effect leads even on a bound-free lower score; the selection order is kept
    mixed = [entry("oil_column", 900.0), entry("stiction", 12.0), entry("drift", 40.0),
             entry("specimen", 0.0, at_bound=True)]
    assert [r["name"] for r in ranked(mixed, ["stiction", "oil_column"])] == [
        "stiction", "oil_column", "drift", "specimen"]


def test_local_peaks_of_a_coarse_profile_are_its_local_maxima_best_first():
    from bayes_sst.diagnosis._screen import _local_peaks

    frequencies, dampings = [1.0, 2.0, 4.0, 8.0, 16.0], [0.02, 0.05]
    # log marginal over frequency: a broad hill at 2 Hz and a sharp one at 16 Hz, 5 nats lower
    by_frequency = {1.0: -8.0, 2.0: 0.0, 4.0: -9.0, 8.0: -20.0, 16.0: -5.0}
    profile = [({"f": f, "z": z}, by_frequency[f] - (3.0 if z == 0.05 else 0.0))
               for f in frequencies for z in dampings]
    logm = np.array([lm for _, lm in profile])
    assert _local_peaks(profile, logm, 3) == [{"f": 2.0, "z": 0.02}, {"f": 16.0, "z": 0.02}]
    assert _local_peaks(profile, logm, 1) == [{"f": 2.0, "z": 0.02}]
    # without the best point (as when it is unphysical) the next maxima come first
    rest = [i for i, (st, _) in enumerate(profile) if st["f"] != 2.0]
    assert _local_peaks([profile[i] for i in rest], logm[rest], 2) == [{"f": 16.0, "z": 0.02}, {"f": 1.0, "z": 0.02}]


def test_a_specimen_between_the_grids_points_is_polished_to_its_damping_and_mass():
    """2 t at 10.3 Hz with 3.5 % damping: the coarse grid (12 % steps, 2 and 5 %) and its
    refinement (2 % steps; 1, 2, 3, 5, 8 %) stop at 10.15 Hz and 5 %; Specimen.polish then
    steps 0.5 % in frequency and 10-25 % in damping around each new best. Measured
    2026-11-27: 10.20 Hz, 4 %, 2103 kg (without the polish 10.15 Hz, 5 %, 2109 kg)."""
    from bayes_sst.diagnosis._diagnose import _scale
    from bayes_sst.diagnosis._engine import Scorer
    from bayes_sst.diagnosis._screen import fit_base, score_effect
    from bayes_sst.effects import effect_by_name

    specimen = effect_by_name("specimen")
    polished = specimen.polish({"specimen_frequency": 10.0, "specimen_damping": 0.04})
    frequencies = sorted({s["specimen_frequency"] for s in polished})
    assert np.max(np.diff(np.log(frequencies))) < np.log(1.006)
    assert frequencies[0] == pytest.approx(10.0 / 1.015, rel=1e-3) and frequencies[-1] == pytest.approx(10.15, rel=1e-3)
    assert sorted({s["specimen_damping"] for s in polished}) == pytest.approx([0.032, 0.036, 0.04, 0.0448, 0.05])

    series = simulate("sst-paper", seed=21, spread=0.02,
                      truth_overrides={"specimen_mass": 2000.0, "specimen_frequency": 10.3, "specimen_damping": 0.035})
    tests = effect_data(series)
    scorer = Scorer(tests, _scale(series, tests))
    scored = score_effect(scorer, specimen, fit_base(scorer))
    assert scored.params["specimen_damping"]["mean"] == pytest.approx(0.035, rel=0.2)
    assert scored.params["specimen_frequency"]["mean"] == pytest.approx(10.3, rel=0.02)
    assert scored.params["specimen_mass"]["mean"] == pytest.approx(2000.0, rel=0.1)
    # the grid parameters' sd is the polish stencil's (0.5 % steps), not the coarse grid's
    frequency = scored.params["specimen_frequency"]
    assert 0.005 / np.sqrt(12) * 0.99 <= frequency["sd"] / frequency["mean"] < 0.02
    assert frequency["posterior_mean"] == pytest.approx(frequency["mean"], rel=0.01)


def test_the_local_grid_posterior_resolves_to_its_step_and_flags_a_posterior_wider_than_its_stencil():
    """_local_posterior on a uniform stencil of step 0.1 about 10 with a Gaussian log marginal of
    sd sigma: a sharp one (sigma 0.01) is known to within the step (sd = 0.1/sqrt(12)); one of
    sigma 0.15 inside +-0.3 has sd sqrt(sigma^2 + 0.1^2/12) up to the stencil's truncation; a flat
    one puts its weight on the stencil's ends."""
    from bayes_sst.diagnosis._screen import LOCAL_EDGE_WEIGHT, _local_posterior
    from bayes_sst.effects import effect_by_name

    delay = effect_by_name("channel_delay")
    values = 10.0 + 0.1 * np.arange(-6, 7)
    best = {"delay": 10.0}

    def moments(sigma):
        stencil = [({"delay": float(x)}, -0.5 * ((x - 10.0) / sigma) ** 2 if sigma else 0.0, (np.zeros(0), np.zeros(0)))
                   for x in values]
        return _local_posterior(delay, stencil, best).moments["delay"]

    mean, sd, edge = moments(0.01)
    assert mean == pytest.approx(10.0) and sd == pytest.approx(0.1 / np.sqrt(12), rel=1e-3) and edge < 1e-6
    mean, sd, edge = moments(0.15)
    assert mean == pytest.approx(10.0) and sd == pytest.approx(np.sqrt(0.15 ** 2 + 0.1 ** 2 / 12), rel=0.05)
    assert edge < LOCAL_EDGE_WEIGHT
    mean, sd, edge = moments(0.0)
    assert edge == pytest.approx(2 / 13) and edge > LOCAL_EDGE_WEIGHT
    assert sd == pytest.approx(np.sqrt(np.var(values) + 0.1 ** 2 / 12))


def test_a_specimen_damped_to_the_top_of_its_range_has_no_resonance_and_is_at_its_bound():
    """At 10 % damping (POLISHED_DAMPING's top) the shear is a smooth filter of a, not a
    resonance: beside the valve generator's 2.1 ms delay (seed 18) such a 'specimen' (394 kg at
    8.3 Hz) was selected as a second effect; score_effect now treats it as the base model."""
    from bayes_sst.effects import effect_by_name
    from bayes_sst.effects._library import POLISHED_DAMPING

    specimen = effect_by_name("specimen")
    top = POLISHED_DAMPING[1]
    assert specimen.at_setting_bound({"specimen_frequency": 8.0, "specimen_damping": top})
    assert not specimen.at_setting_bound({"specimen_frequency": 8.0, "specimen_damping": 0.08})
    polished = specimen.polish({"specimen_frequency": 8.0, "specimen_damping": 0.09})
    assert max(s["specimen_damping"] for s in polished) <= top
    assert min(s["specimen_damping"] for s in specimen.polish({"specimen_frequency": 8.0, "specimen_damping": 0.009})) \
        >= POLISHED_DAMPING[0]
    # the other effects have no such bound
    assert not effect_by_name("stiction").at_setting_bound({"stribeck_velocity": 0.04})


def test_a_specimen_bound_binds_only_where_the_likelihood_rises_past_it():
    """The bound makes the specimen the base model only where a fit at 1.5 times the top damping
    is better by more than PAST_BOUND_NATS: a likelihood still rising (the valve generator's
    delay-following 'specimen', 19.5 % unbounded) binds; a top flat in damping (the sixth
    simulator's seed 408, +0.2 nats from 10 to 15 %: a 3.9 t specimen at 20 Hz read at 18.4 Hz
    along the frequency-damping ridge) does not."""
    from types import SimpleNamespace

    from bayes_sst.diagnosis._screen import PAST_BOUND_NATS, _bound_binds
    from bayes_sst.effects import effect_by_name
    from bayes_sst.effects._library import PAST_BOUND_FACTOR, POLISHED_DAMPING

    specimen = effect_by_name("specimen")
    top = {"specimen_frequency": 18.4, "specimen_damping": POLISHED_DAMPING[1]}
    assert specimen.past_bound(top) == {"specimen_frequency": 18.4,
                                        "specimen_damping": PAST_BOUND_FACTOR * POLISHED_DAMPING[1]}

    class Scorer:
        """log marginal of a specimen term = gain(damping); records what was fitted."""

        def __init__(self, gain):
            self.gain, self.calls = gain, []

        def fit(self, terms, alpha, *, spread=None):
            (effect, setting), = terms
            self.calls.append((dict(setting), alpha))
            return SimpleNamespace(log_marginal=self.gain(setting["specimen_damping"]), alpha=alpha)

    def binds(gain, setting=top):
        scorer = Scorer(gain)
        best = SimpleNamespace(log_marginal=gain(setting["specimen_damping"]), alpha=0.55)
        return _bound_binds(scorer, specimen, [], setting, best), scorer.calls

    rising, calls = binds(lambda zeta: 100.0 + 100.0 * zeta)  # +5 nats from 10 to 15 %
    assert rising and len(calls) == 1
    (fitted, alpha), = calls
    assert fitted["specimen_frequency"] == 18.4 and fitted["specimen_damping"] == pytest.approx(0.15) and alpha == 0.55
    flat, _ = binds(lambda zeta: 203.3 + (0.2 if zeta > 0.12 else 0.0))
    assert not flat
    just_over, _ = binds(lambda zeta: 10.0 + (PAST_BOUND_NATS + 0.01 if zeta > 0.12 else 0.0))
    just_under, _ = binds(lambda zeta: 10.0 + (PAST_BOUND_NATS - 0.01 if zeta > 0.12 else 0.0))
    assert just_over and not just_under
    falling, _ = binds(lambda zeta: 50.0 - 100.0 * zeta)
    assert not falling
    # inside the range nothing is fitted and nothing binds
    inside, calls = binds(lambda zeta: 100.0 * zeta, {"specimen_frequency": 18.4, "specimen_damping": 0.08})
    assert not inside and calls == []
    # an effect with a bound but no setting past it: the bound binds as before
    no_past = SimpleNamespace(at_setting_bound=lambda s: True, past_bound=lambda s: None)
    assert _bound_binds(Scorer(lambda zeta: 0.0), no_past, [], top, SimpleNamespace(log_marginal=0.0, alpha=0.5))


def _breakaway_of(series):
    from bayes_sst.diagnosis._diagnose import breakaway_reading

    return breakaway_reading(series)


def test_the_breakaway_check_reads_static_friction_that_drops_at_once():
    """Fs/Fk = 1.4 with a Stribeck velocity of 0.5 mm/s (close to the Karnopp model: stick until
    the force exceeds Fs, then kinetic friction) on the twin at 1 kHz: the reversal view's
    Stribeck column scores it 0.4 +- 0.5 nats, the breakaway check reads the peak force at rest
    0.20 above Fk (measured 2026-11-27 on seeds 21, 31, 32: 0.197-0.228, z 6.8-7.3); the same seed
    without stiction reads 0.00-0.01. The excess reads low (a 1 ms sample misses part of the peak)."""
    from bayes_sst.diagnosis._breakaway import BREAKAWAY_EXCESS, BREAKAWAY_Z

    karnopp = _breakaway_of(simulate("sst-paper", seed=31, spread=0.02, sample_rate_hz=1000.0,
                                     truth_overrides={"static_ratio": 1.4, "stribeck_velocity": 0.0005}))
    assert 0.15 <= karnopp["excess"] <= 0.4 and karnopp["z"] >= BREAKAWAY_Z and karnopp["selectable"]
    assert karnopp["tests"] == 20 and karnopp["reversals"] >= 200
    clean = _breakaway_of(simulate("sst-paper", seed=31, spread=0.02, sample_rate_hz=1000.0))
    assert abs(clean["excess"]) < 0.05 and not clean["selectable"]
    assert clean["excess"] + 3 * clean["excess_se"] < BREAKAWAY_EXCESS


def _coulomb_reversals(Ke_factor=1.0, seed=3):
    """_test_reversals on an ideal Coulomb record (a 0.5 Hz sine, F = Me*a + Ke*u + Fk*sign(v)
    plus white noise of 8 % of Fk), read with the model's Ke times Ke_factor."""
    from bayes_sst.diagnosis._breakaway import _test_reversals

    fs, f, A, Me, Ke, Fk = 500.0, 0.5, 0.05, 13200.0, 7.2e5, 12500.0
    t = np.arange(0.0, 40.0, 1.0 / fs)
    w = 2 * np.pi * f
    u, v, a = A * np.sin(w * t), A * w * np.cos(w * t), -A * w * w * np.sin(w * t)
    rng = np.random.default_rng(seed)
    F = Me * a + Ke * u + Fk * np.sign(v) + rng.normal(0.0, 0.08 * Fk, t.size)
    return _test_reversals(u, F, a, f, fs, 0, t.size, {"Me": Me, "Ke": Ke * Ke_factor, "Ce": 0.0}, 0.5, Fk)


def test_the_noise_share_of_the_breakaway_statistic_is_what_coulomb_friction_reads():
    """On an ideal Coulomb record the range statistic d (over the window widened by the rest,
    here the +-20 ms where u stays within 0.2 % of its extreme) reads below zero (a half window's
    noise range against a whole one's: -0.03..-0.06 over seeds 0-7; d_fixed the same), and
    further with a stiffness error (the mid-stroke window then holds a trend: -0.10..-0.13 at Ke
    10 % off), while d - null, its noise share taken from the detrended mid-stroke window with an
    ideal step added, reads zero within its se (about 0.01) for the exact Ke and for Ke 10 % off
    either way."""
    for factor in (1.0, 0.9, 1.1):
        found = _coulomb_reversals(factor)
        d = np.array([x["d"] for x in found])
        corrected = np.array([x["d"] - x["null"] for x in found])
        se = corrected.std(ddof=1) / math.sqrt(len(found))
        assert len(found) >= 38
        assert d.mean() < -0.02
        assert abs(corrected.mean()) < 3 * se and se < 0.02
    # this slow sine turns with Me*A*w^2 = 0.5 Fk: every reversal is one where the table rests
    assert all(x["inertia"] < 1.0 for x in _coulomb_reversals())


def _resting_record_reversals(static_ratio, rest_s=0.2, seed=4):
    """_test_reversals on a record whose table rests rest_s at every reversal (longer than the
    fixed window's 2h = 160 ms): a 0.25 Hz cycle of half-cosine strokes of 50 mm between rests;
    while it rests, the friction F - Ke*u ramps from +Fk to -Fs (signs of the new direction),
    and from the breakaway on it is kinetic again; white noise of 3 % of Fk on F and of 60 um
    on u (one noisy sample of u must not end the rest)."""
    from bayes_sst.diagnosis._breakaway import _test_reversals

    fs, f, A, Me, Ke, Fk = 500.0, 0.25, 0.05, 13200.0, 7.2e5, 12500.0
    T, n_cycles = 1.0 / f, 10
    stroke = T / 2 - rest_s
    w = np.pi / stroke
    t = np.arange(0.0, n_cycles * T, 1.0 / fs)
    tau = np.mod(t, T / 2)          # time within the half cycle: stroke, then rest
    up = np.mod(t, T) < T / 2        # strokes up in the first half cycle
    sign = np.where(up, 1.0, -1.0)
    moving = tau < stroke
    u = np.where(moving, -sign * A * np.cos(w * tau), sign * A)
    a = np.where(moving, sign * A * w * w * np.cos(w * tau), 0.0)
    share = np.clip((tau - stroke) / rest_s, 0.0, 1.0)
    friction = np.where(moving, Fk * sign, sign * (Fk - share * (Fk + static_ratio * Fk)))
    rng = np.random.default_rng(seed)
    F = Me * a + Ke * u + friction + rng.normal(0.0, 0.03 * Fk, t.size)
    u_recorded = u + rng.normal(0.0, 60e-6, t.size)
    return _test_reversals(u_recorded, F, a, f, fs, 0, t.size, {"Me": Me, "Ke": Ke, "Ce": 0.0}, 0.5, Fk)


def test_the_breakaway_window_widens_over_a_rest_longer_than_itself():
    """A rest of 200 ms against a fixed window of +-80 ms: the fixed window holds only part of
    the resting force's ramp and reads below zero (d_fixed: -0.21 here, -0.53 for Fs = Fk)
    whatever Fs is, while the window widened by the rest reads Fs/Fk - 1 over its noise share,
    and zero for Fs = Fk. Its 0.32 for 0.4 (measured): the last resting sample holds 0.99 of the
    ramp (0.376 without noise), and the ramp's end is one sample where the flat levels of the
    noise share have many to reach their noise's extremes (0.356 at 1 % noise)."""
    sticking = _resting_record_reversals(1.4)
    clean = _resting_record_reversals(1.0)
    assert len(sticking) >= 16 and len(clean) >= 16
    assert all(0.18 <= x["rest_s"] <= 0.3 and x["inertia"] < 1.0 for x in sticking)
    assert np.mean([x["d_fixed"] for x in sticking]) < 0.0
    assert 0.28 <= np.mean([x["d"] - x["null"] for x in sticking]) <= 0.4
    assert abs(np.mean([x["d"] - x["null"] for x in clean])) < 0.05


def test_stick_slip_misfit_is_the_force_beyond_the_limit_at_rest_and_the_kinetic_step_while_sliding():
    """stick_slip_misfit on a hand-made window: sliding at +Fk (old direction), a rest whose
    holding force ramps to -1.4 Fk, sliding at -Fk; the misfit is r - clip(r, -Fs, Fs) at rest,
    r -+ Fk while sliding."""
    from bayes_sst.diagnosis._breakaway import stick_slip_misfit

    Fk = 1000.0
    r = np.array([1000.0, 1010.0, 990.0, 800.0, 0.0, -800.0, -1200.0, -1400.0, -1000.0, -990.0, -1010.0])
    rest = np.zeros(r.size, bool)
    rest[3:8] = True
    window = {"r": r, "rest": rest, "sliding": np.where(np.arange(r.size) < 3, Fk, -Fk), "kinetic": Fk,
              "noise": np.zeros(r.size)}
    np.testing.assert_allclose(stick_slip_misfit(window, 1.0), [0, 10, -10, 0, 0, 0, -200, -400, 0, 10, -10])
    np.testing.assert_allclose(stick_slip_misfit(window, 1.2), [0, 10, -10, 0, 0, 0, 0, -200, 0, 10, -10])
    np.testing.assert_allclose(stick_slip_misfit(window, 1.4), [0, 10, -10, 0, 0, 0, 0, 0, 0, 10, -10])


def test_the_stick_slip_figures_read_the_resting_force_beyond_the_kinetic_limit():
    """_stick_slip_figures over the 200 ms rests of _resting_record_reversals: the resting force
    ramps from -Fk to -1.4 Fk over the last 1/6 of the rest (16.7 samples at 500 Hz), so the
    misfit with the kinetic limit is 0.4 Fk/sqrt(3) RMS over those samples and zero over the
    rest of the samples the check counts as resting (which include the slow ends of the strokes,
    where the table slides at Fk); with the limit at 1.4 Fk only the noise's exceedances at the
    breakaway remain; the noise floor reads the 3 % of Fk (375 N) that was added; a Coulomb
    table's rests read under their floor."""
    from bayes_sst.diagnosis._breakaway import _stick_slip_figures

    reversals = _resting_record_reversals(1.4)
    sticking = _stick_slip_figures([x["window"] for x in reversals], 1.4)
    ramp_samples = len(reversals) * 0.2 / 6.0 * 500.0
    expected = 0.4 * 12500.0 / math.sqrt(3.0) * math.sqrt(ramp_samples / sticking["rest_samples"])
    assert sticking["rms_before"] == pytest.approx(expected, rel=0.1)
    assert sticking["noise_floor"] == pytest.approx(375.0, rel=0.1)
    assert sticking["rms_after"] < 0.25 * sticking["noise_floor"]
    assert sticking["window_rms_before"] > sticking["window_rms_after"] > 0.5 * sticking["noise_floor"]
    clean = _stick_slip_figures([x["window"] for x in _resting_record_reversals(1.0)], 1.0)
    assert clean["rms_before"] < clean["noise_floor"]


def test_the_resting_reading_selects_a_lift_of_the_resting_reversals_only():
    """_resting_reading on hand-made reversals (four tests, twelve reversals each): a lift of 0.2
    at the resting reversals alone selects; the same lift at the sweeping ones as well (an
    anti-alias overshoot or a delay lifts every reversal) does not; nor does the resting lift
    without sweeping reversals to compare, nor one spread over too few tests."""
    from bayes_sst.diagnosis._breakaway import _pooled, _resting_reading

    rng = np.random.default_rng(0)

    def reversals(resting_lift, sweeping_lift, tests=4, sweeping=True):
        out = {}
        for k in range(tests):
            rows = [{"d": resting_lift + rng.normal(0, 0.05), "null": 0.0, "inertia": 0.5} for _ in range(12)]
            if sweeping:
                rows += [{"d": sweeping_lift + rng.normal(0, 0.05), "null": 0.0, "inertia": 5.0} for _ in range(12)]
            rows += [{"d": 1.0, "null": 0.0, "inertia": 2.0}]  # between the groups: in neither
            out[f"T{k}"] = rows
        return out

    alone = _resting_reading(reversals(0.2, 0.0))
    assert alone["selectable"] and alone["resting"]["excess"] == pytest.approx(0.2, abs=0.03)
    assert alone["lead"] == pytest.approx(0.2, abs=0.04) and alone["resting"]["reversals"] == 48
    assert not _resting_reading(reversals(0.2, 0.2))["selectable"]
    assert not _resting_reading(reversals(0.2, 0.0, sweeping=False))["selectable"]
    assert not _resting_reading(reversals(0.2, 0.0, tests=2))["selectable"]
    # the se is the larger of the test means' scatter and the values' own
    pooled = _pooled({"A": [0.1, 0.3], "B": [0.1, 0.3], "C": [0.1, 0.3]}, 3)
    assert pooled["excess"] == pytest.approx(0.2) and pooled["se"] == pytest.approx(0.1 * math.sqrt(6 / 5) / math.sqrt(6))
    assert _pooled({"A": [0.1, 0.3], "B": [0.2]}, 2) is None  # B has one reversal: one test left


def test_the_breakaway_check_reads_stiction_at_the_reversals_where_the_table_rests():
    """The twin's Karnopp-like stiction (Fs/Fk = 1.4, Stribeck velocity 0.5 mm/s) at 200 Hz: over
    every reversal the check reads 0.06-0.08 (the fast tests sweep through v = 0 and show no
    breakaway), at the reversals where the table rests 0.27-0.29 (measured 2026-11-28 on seeds 21,
    31, 32), 0.2 above the sweeping ones, and it selects stiction from there; the clean twin reads
    within 0.05 of zero at rest (0.029 on 2026-11-28) and does not select."""
    from bayes_sst.diagnosis._breakaway import RESTING_EXCESS

    karnopp = _breakaway_of(simulate("sst-paper", seed=21, spread=0.02, sample_rate_hz=200.0,
                                     truth_overrides={"static_ratio": 1.4, "stribeck_velocity": 0.0005}))
    assert karnopp["excess"] < 0.1 and karnopp["selected_by"] == "resting_reversals" and karnopp["selectable"]
    resting = karnopp["resting"]
    assert 0.2 <= resting["resting"]["excess"] <= 0.4 and resting["lead"] >= 0.1
    assert karnopp["static_excess"] == resting["resting"]["excess"]
    clean = _breakaway_of(simulate("sst-paper", seed=21, spread=0.02, sample_rate_hz=200.0))
    assert not clean["selectable"] and clean["selected_by"] is None
    assert abs(clean["resting"]["resting"]["excess"]) < 0.05
    assert clean["resting"]["resting"]["excess"] + 3 * clean["resting"]["resting"]["se"] < RESTING_EXCESS


def test_a_test_that_does_not_repeat_from_cycle_to_cycle_gets_a_note():
    """unsteady_test_notes: the fifth simulator's series with a 2.2 t specimen at 6.5 Hz had one
    test (5.05 Hz) with a cycle-to-cycle residual of 6451 N against a median of 112 N for the
    others (58 times); clean series reach 13 times. Only the first kind gets a note, naming the
    test and how to leave it out (hand-made floors below)."""
    from types import SimpleNamespace

    from bayes_sst.diagnosis._diagnose import UNSTEADY_FLOOR_RATIO, unsteady_test_notes

    tests = [SimpleNamespace(id=f"T{j:02d}", frequency_hz=f) for j, f in enumerate((0.5, 5.05, 1.0, 2.0, 0.3), 1)]
    floors = np.array([92.0, 6451.0, 215.0, 118.0, 112.0])
    (note,) = unsteady_test_notes(tests, floors)
    assert note.startswith("test T02 (5.05 Hz) does not repeat") and "--exclude-test T02" in note
    assert "6451 N" in note and "56 times" in note  # 6451/median(92, 215, 118, 112) = 6451/115
    clean = np.array([92.0, 13 * 115.0, 215.0, 118.0, 112.0])
    assert unsteady_test_notes(tests, clean) == []
    assert UNSTEADY_FLOOR_RATIO * 115.0 > 13 * 115.0
    assert unsteady_test_notes(tests[:1], floors[:1]) == []


def test_a_smaller_excess_over_every_reversal_selects_only_where_the_resting_reversals_do_not_lag():
    """selects_over_every_reversal: 0.15 at z 5 selects unless the resting reversals lag the
    sweeping ones by more than 4 of the lead's se; 0.12-0.15 at z 5 only with a resting reading
    whose lead is above -2 of its se (the numbers of the fifth simulator's stiction 1.15 at 1 kHz,
    0.149 at z 9.6 with lead -0.012 +- 0.015, of a clean valve-generator table, 0.116 at z 8.1
    with lead -0.141 +- 0.009, of a clean seventh-simulator table, 0.77 at z 5.5 with lead
    -1.11 +- 0.177, and of the sixth simulator's stiction 1.55, 0.775 at z 22.1 with lead
    -0.054 +- 0.061)."""
    from bayes_sst.diagnosis._breakaway import selects_over_every_reversal

    no_groups = {"lead": None, "lead_se": None}
    assert selects_over_every_reversal(0.16, 5.1, no_groups)
    assert selects_over_every_reversal(0.16, 5.1, {"lead": -0.035, "lead_se": 0.01})
    assert not selects_over_every_reversal(0.16, 5.1, {"lead": -0.045, "lead_se": 0.01})
    assert not selects_over_every_reversal(0.77, 5.5, {"lead": -1.11, "lead_se": 0.177})
    assert selects_over_every_reversal(0.775, 22.1, {"lead": -0.054, "lead_se": 0.061})
    assert not selects_over_every_reversal(0.16, 4.9, no_groups)
    assert selects_over_every_reversal(0.149, 9.6, {"lead": -0.012, "lead_se": 0.015})
    assert not selects_over_every_reversal(0.149, 9.6, no_groups)
    assert not selects_over_every_reversal(0.149, 9.6, {"lead": -0.035, "lead_se": 0.015})
    assert not selects_over_every_reversal(0.149, 4.9, {"lead": 0.0, "lead_se": 0.015})
    assert not selects_over_every_reversal(0.116, 8.1, {"lead": -0.141, "lead_se": 0.009})
    assert not selects_over_every_reversal(0.116, 8.1, {"lead": 0.0, "lead_se": 0.009})


@pytest.mark.slow
def test_the_fifth_simulators_stiction_at_1_15_is_read_over_every_reversal(tmp_path):
    """The fifth independent simulator (benchmarks/fifth_generator.py, seed 31, 19 tests at 1 kHz)
    with static friction 15 % above kinetic and a Stribeck velocity of 2.6 mm/s: the reversal
    view scores it 64 +- 49 nats and does not select; the breakaway check reads 0.189 +- 0.006 over
    every reversal, z 33, and selects it, the resting reversals ahead of the sweeping ones (lead
    0.045 +- 0.012). With the low-passed displacement's derivative as the check's velocity
    (until 2026-11-29, night) it read 0.149 +- 0.016, lead -0.012 +- 0.015, and the smaller
    UNLAGGED_EXCESS selected it. The same table without stiction reads -0.054 (z -8.5; -0.051
    before) and does not select."""
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    from fifth_generator import make_series

    make_series(31, str(tmp_path / "stiction"), effect="stiction", size=1.15)
    stiction = _breakaway_of(load_series(tmp_path / "stiction"))
    assert stiction["selected_by"] == "all_reversals" and stiction["z"] >= 10.0
    assert 1.0 + stiction["static_excess"] == pytest.approx(1.15, abs=0.06)
    assert stiction["resting"]["lead"] > 0.0
    make_series(31, str(tmp_path / "clean"))
    clean = _breakaway_of(load_series(tmp_path / "clean"))
    assert not clean["selectable"] and clean["excess"] < 0.0


@pytest.mark.slow
def test_a_sharp_resonance_behind_a_broad_coarse_peak_is_found_where_the_residual_is_well_above_its_floor(tmp_path):
    """The fifth simulator's seed 214 (16 tests at 256 Hz, at most 1.9 Hz) with a 3.26 t specimen
    at 8.08 Hz, 2.2 % damping, which two triangle tests' fifth harmonics excite: the base
    model's residual is 889 N against a 303 N floor. The resonance falls between two coarse
    nodes, and refining only the coarse best read a broad 1.5 t at 6.16 Hz (173 +- 81 nats, not
    selected; measured 2026-11-29). With the residual that far above its floor the best local
    peaks are refined as well (wide_search): the specimen is selected, read within 20 % in mass
    and 2 % in frequency, and removes the excess."""
    from pathlib import Path

    from bayes_sst.diagnosis._diagnose import _scale
    from bayes_sst.diagnosis._engine import Scorer
    from bayes_sst.diagnosis._screen import fit_base, score_effect
    from bayes_sst.effects import effect_by_name

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    from fifth_generator import make_series

    truth = make_series(214, str(tmp_path / "specimen"), effect="specimen")["effect"]
    series = load_series(tmp_path / "specimen")
    tests = effect_data(series)
    scorer = Scorer(tests, _scale(series, tests))
    narrow = score_effect(scorer, effect_by_name("specimen"), fit_base(scorer))
    assert narrow.params["specimen_frequency"]["mean"] < 0.85 * truth["specimen_frequency"]

    data = diagnose(series).to_json()
    assert data["selected"] == ["specimen"]
    read = data["ranking"][0]["params"]
    assert read["specimen_mass"]["mean"] == pytest.approx(truth["specimen_mass"], rel=0.2)
    assert read["specimen_frequency"]["mean"] == pytest.approx(truth["specimen_frequency"], rel=0.02)
    assert data["rms_before"] > 2.5 * data["noise_floor"] and data["shrink"] >= 0.7


@pytest.mark.slow
def test_a_delay_a_side_view_effect_takes_in_part_is_kept_when_it_explains_that_effect_away(tmp_path):
    """The fifth simulator's six-test series (seed 112, 0.66-1.54 Hz, near the table's own
    resonance) with a 3.05 ms force-channel delay: the stroke view takes hinge friction first
    (48 +- 37 nats), and with it given the delay scored 5 nats and nothing was selected but the
    hinge. Without it the default view selects the delay, the stroke view then no longer selects
    the hinge, and the delay fits the default view better: the delay is the verdict, read within
    20 % (2.65 ms measured 2026-11-28), and the hinge is reported as dropped."""
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    from fifth_generator import make_series

    truth = make_series(112, str(tmp_path / "delay"), effect="channel_delay", size=0.003, n_tests=6)
    data = diagnose(load_series(tmp_path / "delay")).to_json()
    assert data["selected"] == ["channel_delay"]
    read = next(r for r in data["ranking"] if r["name"] == "channel_delay")["params"]["delay"]["mean"]
    assert read == pytest.approx(truth["effect"]["delay"], rel=0.2)
    assert data["stroke_view"]["selected"] == []
    assert data["stroke_view"].get("dropped_given_default_view") == ["position_friction"]


@pytest.mark.slow
def test_stiction_without_a_stribeck_velocity_is_selected_by_the_breakaway_check_and_ranked_first():
    """diagnose() on the Karnopp-like twin of the test above: nothing else is selected, so the
    check's finding stands; stiction leads the ranking with the check's static ratio (within 20 %
    of 1.4); the shrink is that of stick-slip friction where the table rests (basis "breakaway")."""
    series = simulate("sst-paper", seed=21, spread=0.02, sample_rate_hz=1000.0,
                      truth_overrides={"static_ratio": 1.4, "stribeck_velocity": 0.0005})
    from bayes_sst.diagnosis._output import figures

    diagnosis = diagnose(series)
    data = diagnosis.to_json()
    json.dumps(data)  # the windows behind the page's figure stay out of the json
    assert data["selected"] == ["stiction"]
    assert data["ranking"][0]["name"] == "stiction" and data["ranking"][0]["rule"] == "breakaway"
    assert data["ranking"][0]["params"]["static_ratio"]["mean"] == pytest.approx(1.4, rel=0.2)
    assert data["shrink_basis"] == "breakaway" and data["breakaway_check"]["used"]
    # where the table rests, stick-slip friction with the static limit read takes the resting
    # force that the kinetic limit leaves (measured: 947 -> 90 N against a floor of 525 N)
    assert data["rms_before"] > 1.5 * data["noise_floor"] > 3 * data["rms_after"]
    assert data["shrink"] >= 0.7 and "at rest at its reversals" in data["located_region"]["region"]
    # the page shows the force held through the windows that selected, one per window
    windows = diagnosis.figures["breakaway_windows"]
    assert len(windows) == data["breakaway_check"]["misfit"]["windows"] > 10
    assert any(caption.startswith("Force the table holds through its reversals") for caption, _ in figures(diagnosis))


def test_the_diagnosis_reads_the_averaged_acceleration_where_the_fit_does():
    """The twin's round test frequencies at 200 Hz give whole-sample periods, so the fit replaces
    the measured a by its cycle-synchronous average, and so does the diagnosis's default view
    (its stroke and reversal views keep the recorded a, as their thresholds were set). With an
    accelerometer noise of 0.2 m/s^2 (seven times the twin's) the base model of the averaged
    acceleration reads Me and Ke within 1 % (measured 13285 kg, 723 kN/m against 13200, 720);
    the recorded one reads Me 7 % and Ke 4 % low (12294 kg, 692 kN/m): the noise left after the
    errors-in-variables correction pulls the slow sines' own Me toward zero. (17 % and 10 % low
    until the correction's scale was read from an eigenvalue instead of halved, 2026-11-29.)"""
    import dataclasses

    from bayes_sst.diagnosis._data import DIAGNOSIS_SIGNALS, REVERSAL_SIGNALS, STROKE_SIGNALS
    from bayes_sst.diagnosis._diagnose import _scale
    from bayes_sst.diagnosis._engine import Scorer
    from bayes_sst.diagnosis._screen import fit_base

    assert DIAGNOSIS_SIGNALS.periodic_acceleration
    assert not REVERSAL_SIGNALS.periodic_acceleration and not STROKE_SIGNALS.periodic_acceleration
    series = simulate("sst-paper", seed=3, spread=0.02, noise={"a_white": 0.2})

    def base_of(options):
        tests = effect_data(series, options)
        return tests, fit_base(Scorer(tests, _scale(series, tests))).base()

    tests, averaged = base_of(DIAGNOSIS_SIGNALS)
    recorded_tests, recorded = base_of(dataclasses.replace(DIAGNOSIS_SIGNALS, periodic_acceleration=False))
    # the correction's noise draws are averaged as the record is: less noise in every test, and
    # in the sum less than half (the ramps either side of the steady window are not averaged)
    power = np.array([[float(np.mean(t.a_noise_full**2)) for t in view] for view in (tests, recorded_tests)])
    assert np.all(power[0] < power[1]) and power[0].sum() < 0.5 * power[1].sum()
    assert averaged["Me"] == pytest.approx(13200.0, rel=0.01) and averaged["Ke"] == pytest.approx(7.2e5, rel=0.01)
    assert recorded["Me"] < 0.96 * 13200.0 and recorded["Ke"] < 0.98 * 7.2e5


def test_the_breakaway_velocity_keeps_the_corner_where_the_friction_flips():
    """At a reversal the friction flips and the acceleration jumps (here by 1.45 m/s^2, 0.7 of a
    500 Hz sample after the last sample before it), so v has a corner. The low-passed
    displacement's derivative (30 Hz) rounds it and still reads +1.4 mm/s a sample after the
    crossing (2.2 mm/s off at worst); with the integrated acceleration above the cut-off the
    velocity crosses zero where the motion does (0.3 mm/s off: the trapezoid's share of the
    jump), and an offset of the accelerometer changes nothing."""
    from bayes_sst.diagnosis._breakaway import reversal_velocity
    from bayes_sst.signals._filters import time_derivative, zero_phase_lowpass

    fs, f, A, jump = 500.0, 1.5, 0.03, 1.45
    w = 2 * np.pi * f
    t = (np.arange(-1500, 1500) + 0.3) / fs
    after = np.clip(t, 0.0, None)
    u = A * np.cos(w * t) + 0.5 * jump * after**2
    v = -A * w * np.sin(w * t) + jump * after
    a = -A * w * w * np.cos(w * t) + jump * (t > 0)
    smooth_u = zero_phase_lowpass(u, 30.0, fs)
    plain = time_derivative(smooth_u, fs)
    kept = reversal_velocity(smooth_u, a, 30.0, fs)
    near = slice(1490, 1510)
    first_after = 1500  # t = +0.6 ms
    assert v[first_after] < 0.0 < plain[first_after] and kept[first_after] < 0.0
    assert np.max(np.abs(plain[near] - v[near])) > 2e-3
    assert np.max(np.abs(kept[near] - v[near])) < 0.4e-3
    np.testing.assert_allclose(reversal_velocity(smooth_u, a + 0.05, 30.0, fs)[500:-500], kept[500:-500], atol=1e-5)


def test_a_low_damping_exponent_does_not_read_as_a_breakaway_at_the_sweeping_reversals():
    """The twin without stiction, alpha 0.34, Ce 44 kN, Fk 4.5 kN, 500 Hz (a clean series of the
    sixth simulator with these values had stiction selected, 0.98 at z 6.2): where the velocity
    crossed zero a sample late, Ce*|v|^alpha flipped late and r spiked at every reversal the
    table sweeps through. Measured on seed 21: 0.61 (z 3.9) over every reversal with the
    low-passed displacement's derivative, 0.21 (z 3.3) with the integrated acceleration's
    corner (bayes_sst.diagnosis._breakaway.reversal_velocity); nothing selected."""
    check = _breakaway_of(simulate("sst-paper", seed=21, spread=0.02, sample_rate_hz=500.0,
                                   truth_overrides={"alpha": 0.34, "Ce": 44000.0, "Fmu": 4500.0}))
    assert check["excess"] < 0.3 and not check["selectable"]
    assert check["resting"]["sweeping"]["excess"] < 0.4


def test_the_breakaway_null_holds_the_velocity_noise_through_a_low_exponent_damping():
    """A Coulomb table with power-law damping of a low exponent (Ce = 32.6 kN, alpha = 0.33,
    Fk = 6 kN, a 0.25 Hz sine of 30 mm at 200 Hz) and 20 um of displacement noise: near v = 0 the
    damping's slope grows without bound, and the velocity's noise (about 1 mm/s under the check's
    30 Hz low-pass) puts kilonewtons into r at each reversal. Without the damping's share in the
    null the resting reversals read a static excess of about 0.9 (measured 0.87-1.04 over five
    records; a sixth simulator's clean series read 0.73, and stiction was selected); with it,
    d - null reads zero (-0.27..+0.11 record by record, about 0.17 their se; -0.05 pooled)."""
    from bayes_sst.diagnosis._breakaway import _test_reversals

    fs, f, A, Me, Ke, Fk, Ce, alpha = 200.0, 0.25, 0.03, 12000.0, 4.5e5, 6000.0, 32600.0, 0.33
    t = np.arange(0.0, 48.0, 1.0 / fs)
    w = 2 * np.pi * f
    u, v, a = A * np.sin(w * t), A * w * np.cos(w * t), -A * w * w * np.sin(w * t)
    resting = []
    for seed in range(5, 10):
        rng = np.random.default_rng(seed)
        F = Me * a + Ke * u + (Ce * np.abs(v) ** alpha + Fk) * np.sign(v) + rng.normal(0.0, 100.0, t.size)
        found = _test_reversals(u + rng.normal(0.0, 20e-6, t.size), F, a + rng.normal(0.0, 0.03, t.size), f, fs,
                                0, t.size, {"Me": Me, "Ke": Ke, "Ce": Ce}, alpha, Fk)
        resting += [x for x in found if x["window"] is not None and x["inertia"] < 1.0]
    assert len(resting) >= 100
    corrected = np.array([x["d"] - x["null"] for x in resting])
    without_share = np.array([x["d"] - x["null"] + x["window"]["damping_share"] for x in resting])
    assert abs(corrected.mean()) < 0.15
    assert without_share.mean() > 0.6


def test_the_selected_effects_are_listed_strongest_first_whichever_view_chose_them():
    """The side views' findings are given to the default view, whose own selections follow: the
    list is ordered by the best score each had in a round that chose it, not by view."""
    from bayes_sst.diagnosis._diagnose import _by_evidence

    def step(chosen, scores, view=None):
        entry = {"candidates": [{"name": n, "score": s} for n, s in scores.items()]}
        if chosen is not None:
            entry["chosen"] = chosen
        if view:
            entry["view"] = view
        return entry

    steps = [step("strut_damping", {"channel_delay": 31.8, "strut_damping": 16.2}),
             step(None, {"drift": 5.4}),
             step("nonlinear_stiffness", {"nonlinear_stiffness": 162.7, "strut_inertia": 0.0}, "stroke"),
             # a second screening that chooses it again with a lower score keeps its best
             step("nonlinear_stiffness", {"nonlinear_stiffness": 150.0}, "stroke_check")]
    assert _by_evidence(["strut_damping", "nonlinear_stiffness"], steps) == ["nonlinear_stiffness", "strut_damping"]
    # ties and names no round chose keep their order, the unchosen last
    assert _by_evidence(["stiction", "strut_damping"], steps) == ["strut_damping", "stiction"]
    assert _by_evidence(["a", "b"], []) == ["a", "b"]


def _lugre_friction(v, fs, Fk, static_ratio, stribeck_velocity, presliding_m):
    """LuGre's bristles without damping, each sample advanced exactly with its velocity held:
    dz/dx = sign(v) - z*sigma0/g(v), F = sigma0*z, sigma0 = Fk/presliding_m and the Stribeck
    curve g(v) = Fk*(1 + (static_ratio - 1)*exp(-(v/v_s)^2))."""
    sigma0 = Fk / presliding_m
    g = Fk * (1.0 + (static_ratio - 1.0) * np.exp(-(v / stribeck_velocity) ** 2))
    steady = np.sign(v) * g / sigma0
    decay = np.exp(-np.abs(v) / fs * sigma0 / g)
    z = np.empty_like(v)
    state = steady[0]
    for n in range(len(v)):
        state = steady[n] + (state - steady[n]) * decay[n]
        z[n] = state
    return sigma0 * z


def _lugre_series(static_ratio, seed=0):
    """Eight sines of 3-20 mm at 0.2-4 Hz, 1 kHz, with LuGre friction of 8 kN turning over
    100 um of bristle travel and a Stribeck velocity of 8 mm/s; white noise on F, u and a."""
    from bayes_sst.io import Series, TestRecord, TestSpec

    rng = np.random.default_rng(seed)
    fs, Me, Ke, Ce, alpha, Fk = 1000.0, 12000.0, 7e5, 3e4, 0.6, 8000.0
    records = []
    for k, (f, amplitude) in enumerate([(0.2, 0.01), (0.3, 0.004), (0.5, 0.02), (0.8, 0.006), (1.2, 0.01),
                                        (2.0, 0.004), (3.0, 0.006), (4.0, 0.003)]):
        period = 1.0 / f
        t = np.arange(0.0, 8 * period, 1.0 / fs)
        ramp = np.clip(t / (1.5 * period), 0.0, 1.0) * np.clip((8 * period - t) / (1.5 * period), 0.0, 1.0)
        u = amplitude * (0.5 - 0.5 * np.cos(np.pi * ramp)) * np.sin(2 * np.pi * f * t)
        v = np.gradient(u, 1.0 / fs)
        a = np.gradient(v, 1.0 / fs)
        F = (Me * a + Ke * u + Ce * np.abs(v) ** alpha * np.sign(v)
             + _lugre_friction(v, fs, Fk, static_ratio, 0.008, 100e-6) + rng.normal(0.0, 60.0, t.size))
        spec = TestSpec(id=f"S{k}", file=f"S{k}.csv", kind="sine", frequency_hz=f, amplitude_m=amplitude)
        records.append(TestRecord(spec, {"t": t, "u": u + rng.normal(0.0, 2e-6, t.size), "F": F,
                                         "a": a + rng.normal(0.0, 0.01, t.size)}))
    return Series(name=f"lugre-{static_ratio}", tests=tuple(records))


def test_stiction_inside_a_pre_sliding_turn_is_read_with_the_turn_left_out():
    """LuGre friction: after each reversal the bristles turn the friction over about 100 um,
    and a Stribeck curve raises it 35 % toward rest. The reversal view reads the turn and leaves
    it out (the table's approach to each reversal stays); kept, the turn's deficit under sign(v)
    cancelled the stiction's excess and the Stribeck coefficient came out negative, at its bound
    (static ratio -0.89; 1.2 read -0.85). Measured with the turn left out: 1.22 at 6.4 mm/s."""
    from bayes_sst.effects import effect_by_name

    stiction = [effect_by_name("stiction")]
    d = diagnose(_lugre_series(1.35), effects=stiction)
    assert d.selected == ["stiction"]
    assert any(note.startswith("pre-sliding friction") for note in d.notes)
    ratio = d.ranking[0]["params"]["static_ratio"]["mean"]
    # the bristles lag the Stribeck curve's rise as the table slows, so the excess reads low
    assert ratio == pytest.approx(1.35, rel=0.12) and ratio > 1.15
    assert d.ranking[0]["params"]["stribeck_velocity"]["mean"] == pytest.approx(0.008, rel=0.5)


def test_a_few_percent_of_static_friction_is_read_but_not_claimed():
    """The same table with a 2 % Stribeck excess, the kind every simulated clean table carries:
    the reversal view resolves it (1.020 read) but stiction is not selected, and a note says why."""
    from bayes_sst.effects import effect_by_name

    stiction = [effect_by_name("stiction")]
    d = diagnose(_lugre_series(1.02), effects=stiction)
    assert d.selected == []
    entry = next(r for r in d.ranking if r["name"] == "stiction")
    assert entry["params"]["static_ratio"]["mean"] == pytest.approx(1.02, abs=0.006)
    assert entry["immaterial"] and "under the 5 %" in entry["immaterial"]
    assert any(note.startswith("stiction is resolved") and "not counted" in note for note in d.notes)


def test_a_test_too_short_to_tell_its_noise_takes_the_others_pooled_sigma():
    """Eleven synthetic tests of 300 samples (white noise of sd 0.3) and one of 4 samples, no
    more than the four base coefficients: its least-squares residual is zero, so its own sigma
    would be nothing, and the collapsed precision stopped being positive definite. It takes the
    others' pooled sigma instead, and the population values stay those of the long tests."""
    from bayes_sst.diagnosis._engine import _fit

    rng = np.random.default_rng(3)
    truth = np.array([2.0, -1.0, 0.5, 1.5])
    ys, Xs = [], []
    for n in [300] * 11 + [4]:
        X = rng.standard_normal((4, n))
        ys.append(truth @ X + 0.3 * rng.standard_normal(n))
        Xs.append(X)
    fit = _fit(ys, Xs, ("Me", "Ke", "Ce", "Fmu"), np.zeros(0), 0.5, 0.0, ())
    assert fit.sigma[-1] == pytest.approx(0.3, rel=0.1)
    assert fit.sigma[-1] == pytest.approx(np.sqrt(np.mean(fit.sigma[:-1] ** 2)), rel=0.02)
    np.testing.assert_allclose(fit.mu, truth, atol=0.03)
    assert np.all(np.isfinite(fit.elpd))
