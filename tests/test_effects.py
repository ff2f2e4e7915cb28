"""The effect library and the twin's effect switches, against closed forms and exact force balances."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bayes_sst.effects import EFFECTS, FORCE_EFFECTS, effect_by_name, sdof_base_shear
from bayes_sst.physics import strut_cubic_stiffness
from bayes_sst.twin import PRESETS, simulate

TRUTH = PRESETS["sst-paper"]
H = TRUTH.strut_h
PLAN = [{"kind": "sine", "frequency_hz": 1.0, "amplitude_m": 0.08},
        {"kind": "sine", "frequency_hz": 2.0, "amplitude_m": 0.03}]
REQUIRED = {"stiction", "nonlinear_stiffness", "position_friction", "specimen", "channel_delay", "drift",
            "oil_column"}


def test_library_names_equations_and_priors():
    names = [e.name for e in EFFECTS]
    assert REQUIRED <= set(names) and len(set(names)) == len(names)
    base = {"Me": 13200.0, "Ke": 7.2e5, "Ce": 2.96e4, "Fmu": 1.25e4, "strut_h": H, "stroke": 0.1}
    for effect in EFFECTS:
        assert effect.equation and effect.physics and effect.parameters
        assert all(p.prior for p in effect.parameters)
        assert len(effect.prior_sd(base)) == len(effect.coefficients)
        assert len(effect.settings()) == math.prod(len(v) for v in effect.grid.values())
    assert effect_by_name("drift").coefficients == ("drift",)
    # the columns that read a (the specimen's base shear, the strut inertia's (u/h)^2*a)
    assert {e.name for e in EFFECTS if e.reads_acceleration} == {"specimen", "strut_inertia"}
    with pytest.raises(ValueError, match="unknown effect 'wobble'"):
        effect_by_name("wobble")


def test_effects_are_off_by_default():
    assert TRUTH.active_effects == {}
    assert set(TRUTH.population()) == {"Me", "Ke", "Ce", "alpha", "Fmu", "static_ratio", "f_oil_hz"}
    with pytest.raises(ValueError, match="friction_drift"):
        TRUTH.replace({"friction_drift": 1.0})


# Up to the specimen's own frequency (where the pre-warped bilinear transform is exact); above it,
# at 20 Hz from 200 Hz samples, the transform's frequency warping costs about 6 %.
@pytest.mark.parametrize("f", [0.5, 3.0, 8.0])
def test_specimen_base_shear_matches_the_sdof_steady_state(f):
    # |S/A| = sqrt(w_s^4 + (2 z w_s w)^2)/sqrt((w_s^2 - w^2)^2 + (2 z w_s w)^2)
    fs_hz, zeta, rate = 8.0, 0.03, 200.0
    t = np.arange(int(60 * rate)) / rate
    a = np.sin(2 * np.pi * f * t)
    shear = sdof_base_shear(a, fs_hz, zeta, rate)
    tail = t > 40.0  # the start-up transient has died out (time constant 1/(zeta*w_s) = 0.66 s)
    design = np.column_stack([np.sin(2 * np.pi * f * t[tail]), np.cos(2 * np.pi * f * t[tail])])
    coef, *_ = np.linalg.lstsq(design, shear[tail], rcond=None)
    ws, w = 2 * np.pi * fs_hz, 2 * np.pi * f
    expected = math.hypot(ws**2, 2 * zeta * ws * w) / math.hypot(ws**2 - w**2, 2 * zeta * ws * w)
    assert np.hypot(*coef) == pytest.approx(expected, rel=5e-3)


@pytest.fixture(scope="module")
def clean():
    return simulate(plan=PLAN, seed=2, noise="quiet", record_velocity=True)


def _balance_residual(series, truth):
    """F - (M a + Ke u + Ce |v|^alpha sign v + Fmu sign v) per test, with the twin's true parameters:
    exactly the effect's force on sliding samples (the twin's recorded signals obey its balance)."""
    out = []
    for record in series.tests:
        tr = record.spec.extra["truth"]
        v = record.columns["v"]
        model = (tr["Me"] * record.columns["a"] + tr["Ke"] * record.u
                 + (tr["Ce"] * np.abs(v) ** tr["alpha"] + tr["Fmu"]) * np.sign(v))
        out.append((record, record.F - model))
    return out


def test_cubic_stiffness_and_hinge_friction_switches_add_their_exact_force():
    k3 = strut_cubic_stiffness(TRUTH.Ke, TRUTH.strut_gamma, TRUTH.strut_h, TRUTH.strut_l0)
    assert k3 == pytest.approx(3.98e5, rel=1e-3)
    series = simulate(plan=PLAN, seed=2, noise="quiet", record_velocity=True,
                      truth_overrides={"cubic_stiffness": k3, "position_friction": 5e4})
    assert series.extra["truth"]["cubic_stiffness"] == k3
    for record, residual in _balance_residual(series, TRUTH):
        v = record.columns["v"]
        sliding = v != 0
        # the hinge raises the friction level at the step's start displacement, recorded as u
        expected = k3 * (record.u / H) ** 2 * record.u + 5e4 * (record.u / H) ** 2 * np.sign(v)
        assert np.max(np.abs(residual[sliding] - expected[sliding])) < 1e-6 * np.max(np.abs(record.F))


def test_force_delay_switch_delays_only_the_force_channel(clean):
    delayed = simulate(plan=PLAN, seed=2, noise="quiet", record_velocity=True, truth_overrides={"force_delay": 0.003})
    for a, b in zip(clean.tests, delayed.tests):
        np.testing.assert_array_equal(a.u, b.u)
        np.testing.assert_allclose(b.F, np.interp(a.t - 0.003, a.t, a.F), rtol=0, atol=1e-9)


def test_specimen_switch_loads_the_deck_with_its_base_shear(clean):
    ms, fs_hz = 3000.0, 8.0
    series = simulate(plan=PLAN, seed=2, noise="quiet", record_velocity=True,
                      truth_overrides={"specimen_mass": ms, "specimen_frequency": fs_hz})
    for record, residual in _balance_residual(series, TRUTH):
        f = record.spec.frequency_hz
        t = record.t
        steady = (t > 0.5 + 2 / f) & (t < 0.5 + 6 / f)
        design = np.column_stack([np.sin(2 * np.pi * f * t[steady]), np.cos(2 * np.pi * f * t[steady])])
        shear_amp = np.hypot(*np.linalg.lstsq(design, residual[steady], rcond=None)[0])
        a_amp = np.hypot(*np.linalg.lstsq(design, record.columns["a"][steady], rcond=None)[0])
        ws, w, z = 2 * np.pi * fs_hz, 2 * np.pi * f, 0.03
        gain = math.hypot(ws**2, 2 * z * ws * w) / math.hypot(ws**2 - w**2, 2 * z * ws * w)
        # residual = F - M a - ... = m_s*(a + x''), the base shear at the fundamental
        assert shear_amp == pytest.approx(ms * gain * a_amp, rel=0.03)


def test_drift_switch_lowers_friction_and_damping_over_the_campaign():
    plan = PLAN * 2
    series = simulate(plan=plan, seed=2, noise="quiet", truth_overrides={"friction_drift": 0.1, "damping_drift": 0.05})
    fmu = np.array([r.spec.extra["truth"]["Fmu"] for r in series.tests])
    ce = np.array([r.spec.extra["truth"]["Ce"] for r in series.tests])
    s = np.arange(len(plan)) / (len(plan) - 1)
    np.testing.assert_allclose(fmu, TRUTH.Fmu * (1 - 0.1 * s), rtol=1e-12)
    np.testing.assert_allclose(ce, TRUTH.Ce * (1 - 0.05 * s), rtol=1e-12)


def test_every_force_effect_gives_columns_of_the_kept_length(clean):
    from bayes_sst.diagnosis import effect_data

    tests = effect_data(clean)
    for effect in FORCE_EFFECTS:
        setting = effect.settings()[len(effect.settings()) // 2]
        cols = effect.columns(tests[0], setting, 0.5, {"Me": 13200.0, "Ke": 7.2e5, "Ce": 2.96e4, "Fmu": 1.25e4})
        assert cols.shape == (len(effect.coefficients), len(tests[0].index))
        assert np.all(np.isfinite(cols))
        response = effect.response(tests[0], setting)
        assert response is None or response.shape == (len(tests[0].index),)


def test_stiction_under_its_least_excess_is_no_finding():
    """Stiction.immaterial: a static excess under LEAST_STATIC_EXCESS is the few-percent
    Stribeck curve every contact has; at the grid's lower Stribeck velocity (not resolved) the
    breakaway check's excess is asked instead."""
    from bayes_sst.effects._library import LEAST_STATIC_EXCESS, UNRESOLVED_STATIC_EXCESS

    stiction = effect_by_name("stiction")

    def reading(ratio):
        return {"static_ratio": {"mean": ratio, "sd": 0.01}, "stribeck_velocity": {"mean": 0.005, "sd": 0.0}}

    assert "2.0 %" in stiction.immaterial(reading(1.02), {})
    assert stiction.immaterial(reading(1.0 + LEAST_STATIC_EXCESS + 0.001), {}) is None
    unresolved = {"stribeck_velocity": "lower"}
    assert "lower end" in stiction.immaterial(reading(1.1), unresolved)
    assert stiction.immaterial(reading(1.0 + UNRESOLVED_STATIC_EXCESS + 0.001), unresolved) is None
    assert stiction.immaterial(reading(1.1), {"stribeck_velocity": "upper"}) is None
    # every other effect's reading counts whatever its size
    assert all(e.immaterial({}, {}, {"Me": 13200.0}) is None for e in EFFECTS if e.name not in ("stiction", "specimen"))


def test_a_specimen_under_a_hundredth_of_the_deck_is_no_finding():
    """Specimen.immaterial: the specimens read where there was none were tens of kilograms;
    one of LEAST_SPECIMEN_SHARE of Me or more counts."""
    from bayes_sst.effects._library import LEAST_SPECIMEN_SHARE

    specimen = effect_by_name("specimen")
    base = {"Me": 15800.0}

    def reading(mass):
        return {"specimen_mass": {"mean": mass, "sd": 10.0}, "specimen_frequency": {"mean": 0.82, "sd": 0.01}}

    assert "47 kg, 0.3 %" in specimen.immaterial(reading(47.0), {}, base)
    assert specimen.immaterial(reading(LEAST_SPECIMEN_SHARE * 15800.0 + 1.0), {}, base) is None
    assert specimen.immaterial(reading(700.0), {}, base) is None
    assert specimen.immaterial(reading(47.0), {}) is None  # no base values: nothing to compare with
