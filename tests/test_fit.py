"""End-to-end: virtual-table series with known truth -> posterior that contains it."""

import json
import os
import subprocess
import sys
from dataclasses import replace

import numpy as np
import pytest

from bayes_sst.inference import fit
from bayes_sst.inference._summary import format_summary, summarize
from bayes_sst.io import TestRecord, load_series, read_run_summary, read_run_tree, write_run
from bayes_sst.signals import SignalOptions
from bayes_sst.twin import default_plan, simulate

NAMES = ("Me", "Ke", "Ce", "alpha", "Fmu")


@pytest.fixture(scope="module")
def noisy_fit():
    """The 20-test sst-paper plan (sines and triangles), 2 % test-to-test spread, the
    twin.s default coloured sensor noise; the default sampler settings."""
    plan = default_plan("sst-paper")
    series = simulate("sst-paper", seed=7, spread=0.02, plan=plan)
    result = fit(series, seed=3)
    return series, result


def test_population_truth_inside_99_percent_intervals_and_close(noisy_fit):
    """One series can miss a calibrated 90 % interval by chance (benchmarks/calibration.py
    measures the coverage over many); a 99 % miss here would mean bias, not chance."""
    series, result = noisy_fit
    truth = series.extra["truth"]
    summary = summarize(result.tree)
    for name in NAMES:
        low, high = np.quantile(result.posterior[name].values, [0.005, 0.995])
        assert low <= truth[name] <= high, (name, low, high, truth[name])
    # accuracy targets of the foundation issue: 3 % Me, Ke; 10 % Ce; 0.05 alpha. Fmu's
    # posterior sd on this plan is about 3 % (it trades off against Ce and alpha), so its
    # 3 % target is a statement over many series (benchmarks/calibration.py); here 6 %.
    for name, tolerance in (("Me", 0.03), ("Ke", 0.03), ("Fmu", 0.06), ("Ce", 0.10)):
        assert abs(summary["parameters"][name]["mean"] / truth[name] - 1) < tolerance, name
    assert abs(summary["parameters"]["alpha"]["mean"] - truth["alpha"]) < 0.05


def test_per_test_coefficients_track_each_tests_own_truth(noisy_fit):
    """The hierarchical layer: per-test Fmu posteriors follow the spread the twin drew."""
    series, result = noisy_fit
    post = result.posterior
    drawn = np.array([t.spec.extra["truth"]["Fmu"] for t in series.periodic_tests])
    estimated = post["Fmu_test"].mean(("chain", "draw")).values
    assert np.corrcoef(drawn, estimated)[0, 1] > 0.5


def test_uncertainty_is_not_the_iid_overconfidence(noisy_fit):
    """An i.i.d. likelihood gives Me to 0.006 %; honest intervals reflect the 2 % test spread
    over 20 tests (about 0.45 %) and must not be an order of magnitude tighter."""
    _, result = noisy_fit
    me = result.posterior["Me"].values.ravel()
    assert me.std() / me.mean() > 0.002


def test_sampler_checks_and_datatree_groups(noisy_fit):
    _, result = noisy_fit
    tree = result.tree
    for group in ("posterior", "sample_stats", "log_likelihood", "observed_data", "constant_data"):
        assert group in tree.children
    summary = summarize(result.tree)
    assert summary["divergences"] == 0
    assert summary["max_r_hat"] <= 1.01
    assert summary["min_ess_bulk"] >= 400
    assert summary["converged"] and summary["warnings"] == []
    # converged within the default draws: not extended
    assert json.loads(tree.attrs["sampler"])["draws"] == 500
    assert tree["log_likelihood"]["F"].dims == ("chain", "draw", "test")


def test_the_jackknife_reads_the_posteriors_values_and_widens_little_where_the_model_holds(noisy_fit):
    """The tests left out one at a time (bayes_sst.inference._widening): with all tests, the
    mode the jackknife starts from sits within a third of a posterior sd of the posterior
    mean; on this series, which the model describes but for the twin's stiction, no interval
    is stretched by more than a fifth (measured: Me, Ke, alpha 1.0, Ce 1.16, Fmu 1.09)."""
    from bayes_sst.inference._widening import model_draws, widening_of

    _, result = noisy_fit
    tree = result.tree
    assert {"jackknife", "model_posterior"} <= set(tree.children)
    assert tree["jackknife"]["without_test"].shape == (20, 5)
    widening = widening_of(tree)
    summary = summarize(tree)
    for name in NAMES:
        model = model_draws(tree, name).values
        full = float(tree["jackknife"]["all_tests"].sel(quantity=name))
        assert abs(full - model.mean()) < 0.35 * model.std(), name
        assert 1.0 <= widening[name]["factor"] <= 1.2, (name, widening[name])
        assert summary["parameters"][name]["sd"] == pytest.approx(widening[name]["factor"] * model.std(ddof=1),
                                                                  rel=1e-6)
    assert summary["widening"] == widening
    assert "intervals widened where the tests" in format_summary(summary)


def test_summary_flags_an_unconverged_run_loudly():
    series = simulate("sst-paper", seed=2, plan=default_plan("sst-paper")[:4])
    result = fit(series, chains=2, draws=15, warmup=15, seed=0, extensions=0)
    summary = summarize(result.tree)
    assert not summary["converged"]
    assert any("ESS" in w for w in summary["warnings"])
    assert "WARNING" in format_summary(summary)


def test_an_unconverged_run_goes_on_from_where_its_chains_stopped():
    """extensions: while R-hat or the bulk ESS misses its limit the chains draw `draws` more;
    the first draws are those of the run without extension (the chains continue, they do not
    restart), and the tree's sampler settings give the total."""
    series = simulate("sst-paper", seed=2, plan=default_plan("sst-paper")[:4])
    short = fit(series, chains=2, draws=15, warmup=15, seed=0, extensions=0)
    longer = fit(series, chains=2, draws=15, warmup=15, seed=0, extensions=2)
    assert json.loads(short.tree.attrs["sampler"])["draws"] == 15
    assert json.loads(longer.tree.attrs["sampler"])["draws"] == 45  # 60 draws cannot reach ESS 400
    assert longer.posterior.sizes["draw"] == 45
    assert np.array_equal(longer.posterior["alpha"].values[:, :15], short.posterior["alpha"].values)
    assert not np.array_equal(longer.posterior["alpha"].values[:, 15:30], short.posterior["alpha"].values)
    with pytest.raises(ValueError, match="chains must be a whole number of at least 1"):
        fit(series, chains=0)
    with pytest.raises(ValueError, match="extensions"):
        fit(series, extensions=-1)


def test_run_folder_round_trip(noisy_fit, tmp_path):
    _, result = noisy_fit
    summary = summarize(result.tree, seconds=1.0)
    write_run(tmp_path / "run", result.tree, summary, format_summary(summary))
    back = read_run_summary(tmp_path / "run")
    assert set(back["parameters"]) == set(NAMES)
    for name in NAMES:
        assert set(back["parameters"][name]) >= {"mean", "sd", "q05", "q50", "q95", "r_hat", "ess_bulk"}
    assert {"divergences", "n_tests", "n_samples", "seconds"} <= set(back)
    tree = read_run_tree(tmp_path / "run")
    assert np.allclose(tree["posterior"]["Me"].values, result.posterior["Me"].values)
    # the widening's record, the model's own draws and the jackknife come back with it
    assert tree.attrs["widening"] == result.tree.attrs["widening"]
    assert np.allclose(tree["model_posterior"]["alpha"].values, result.tree["model_posterior"]["alpha"].values)
    assert np.allclose(tree["jackknife"]["without_test"].values, result.tree["jackknife"]["without_test"].values)
    json.dumps(back)


def test_shipped_example_series_loads_and_is_small():
    series = load_series("data/sst-paper")
    assert len(series.tests) == 20
    assert series.n_samples > 30_000


def test_shared_mass_has_no_between_test_spread_and_recovers_a_constant_mass():
    """--shared Me: a campaign whose moving mass is the same in every test (the twin varies
    only Ke, Ce, Fmu) fitted with Me shared: every test's Me is the population Me in every
    draw, its between-test sd is exactly 0, and the population Me holds the truth."""

    from bayes_sst.inference._priors import make_priors

    series = simulate("sst-paper", seed=11, spread={"Ke": 0.02, "Ce": 0.02, "Fmu": 0.02})
    priors = replace(make_priors("generic"), shared=("Me",))
    result = fit(series, seed=5, prior=priors)
    post = result.posterior
    assert np.all(post["between_test_sd"].sel(coefficient="Me").values == 0.0)
    # the model's own population draws (a widened run stretches the reported ones about their mean)
    from bayes_sst.inference._widening import model_draws

    model_me = model_draws(result.tree, "Me").values
    np.testing.assert_allclose(post["Me_test"].values, model_me[..., None] * np.ones(post.sizes["test"]), rtol=1e-9)
    assert post["between_test_sd"].sel(coefficient="Ke").values.mean() > 0.0
    summary = summarize(result.tree)
    assert summary["converged"], summary["warnings"]
    truth = series.extra["truth"]["Me"]
    low, high = np.quantile(post["Me"].values, [0.005, 0.995])
    assert low <= truth <= high
    assert abs(summary["parameters"]["Me"]["mean"] / truth - 1) < 0.01
    assert "Me     shared by all tests" in format_summary(summary)
    with pytest.raises(ValueError, match="shared coefficients must be among"):
        replace(priors, shared=("mass",)).varying_mask()


def test_a_coefficient_can_have_its_own_spread_prior():
    """Priors.spread_prior: the common (median, log sd) for every coefficient unless one has its
    own (fit's mass refit holds Me's near 2 %); an unknown name is refused."""
    from bayes_sst.inference._fit import HELD_MASS_SPREAD
    from bayes_sst.inference._priors import make_priors

    priors = make_priors("generic")
    medians, log_sds = priors.spread_prior()
    np.testing.assert_array_equal(medians, [priors.spread_median] * 4)
    np.testing.assert_array_equal(log_sds, [priors.spread_log_sd] * 4)
    held = replace(priors, spread_by_coefficient={"Me": HELD_MASS_SPREAD})
    medians, log_sds = held.spread_prior()
    np.testing.assert_array_equal(medians, [0.02, 0.03, 0.03, 0.03])
    np.testing.assert_array_equal(log_sds, [0.35, 1.0, 1.0, 1.0])
    assert held.describe()["between_test_spread"]["by_coefficient"] == {"Me": {"median": 0.02, "log_sd": 0.35}}
    with pytest.raises(ValueError, match="spread priors must be for coefficients among"):
        replace(priors, spread_by_coefficient={"mass": (0.02, 0.3)}).spread_prior()


def test_runs_fitted_before_the_reversal_weight_are_re_prepared_without_it():
    import dataclasses
    from types import SimpleNamespace

    from bayes_sst.inference._predictive import run_signal_options

    current = dataclasses.asdict(SignalOptions())
    assert run_signal_options(SimpleNamespace(attrs={"signal_options": json.dumps(current)})).reversal_window
    older = {k: v for k, v in current.items() if k not in ("reversal_window", "reversal_taper")}
    options = run_signal_options(SimpleNamespace(attrs={"signal_options": json.dumps(older)}))
    assert options.reversal_window is False and options.cutoff_multiple == current["cutoff_multiple"]
    assert run_signal_options(SimpleNamespace(attrs={})) == SignalOptions()
    # and runs from before the accelerometer's synchronous average without that
    assert run_signal_options(SimpleNamespace(attrs={"signal_options": json.dumps(current)})).periodic_acceleration
    older = {k: v for k, v in current.items() if k != "periodic_acceleration"}
    assert run_signal_options(SimpleNamespace(attrs={"signal_options": json.dumps(older)})).periodic_acceleration is False
    # and runs from before the accelerometer's noise estimate without it
    assert run_signal_options(SimpleNamespace(attrs={"signal_options": json.dumps(current)})).accelerometer_noise
    older = {k: v for k, v in current.items() if k != "accelerometer_noise"}
    assert run_signal_options(SimpleNamespace(attrs={"signal_options": json.dumps(older)})).accelerometer_noise is False
    # and runs from before the separate band for tests without an accelerometer used one band
    assert run_signal_options(SimpleNamespace(attrs={"signal_options": json.dumps(current)})).band_for(False).reversal_band == 0.2
    older = {k: v for k, v in current.items() if k != "reversal_band_without_accelerometer"}
    older["reversal_band"] = 0.2
    assert run_signal_options(SimpleNamespace(attrs={"signal_options": json.dumps(older)})).band_for(False).reversal_band == 0.2
    older["reversal_band"] = 0.15
    assert run_signal_options(SimpleNamespace(attrs={"signal_options": json.dumps(older)})).band_for(False).reversal_band == 0.15
    # and runs from before the accelerometer check used every recorded a
    assert run_signal_options(SimpleNamespace(attrs={"signal_options": json.dumps(current)})).check_accelerometer
    older = {k: v for k, v in current.items() if k != "check_accelerometer"}
    assert run_signal_options(SimpleNamespace(attrs={"signal_options": json.dumps(older)})).check_accelerometer is False
    # and runs from before the fourth-difference noise read used second differences
    assert run_signal_options(SimpleNamespace(attrs={"signal_options": json.dumps(current)})).noise_difference_order == 4
    older = {k: v for k, v in current.items() if k != "noise_difference_order"}
    assert run_signal_options(SimpleNamespace(attrs={"signal_options": json.dumps(older)})).noise_difference_order == 2
    # and runs from before the pre-sliding read and the kernel on the force had neither
    assert run_signal_options(SimpleNamespace(attrs={"signal_options": json.dumps(current)})).kernel_on_force
    assert run_signal_options(SimpleNamespace(attrs={"signal_options": json.dumps(current)})).presliding is None
    older = {k: v for k, v in current.items() if k not in ("presliding", "kernel_on_force")}
    options = run_signal_options(SimpleNamespace(attrs={"signal_options": json.dumps(older)}))
    assert options.presliding == 0.0 and options.kernel_on_force is False
    # a run from the day's first pre-sliding read had no floor
    older = {k: v for k, v in current.items() if k != "presliding_floor"}
    assert run_signal_options(SimpleNamespace(attrs={"signal_options": json.dumps(older)})).presliding_floor == 0.0


def _white_force_noise_series(seed: int = 1):
    from bayes_sst.twin import SensorNoise

    return simulate("sst-paper", seed=seed, spread={"Ke": 0.03, "Ce": 0.03, "Fmu": 0.03},
                    noise=SensorNoise(F_colored=0.0))


def test_white_force_noise_sliding_mass_is_caught_and_refitted_with_its_spread_held():
    """With only white force noise and the accelerometer read as recorded (no synchronous
    average, no noise correction), the accelerometer's noise (times Me) dominates the slow sine
    tests' residual, and their per-test Me can slide along the Me-Ke ridge toward 0: the
    posterior has a second mode. On the twin's seed 3, used here, every chain of the first fit
    settles in it (Me -42 %, between-test sd 65 %, R-hat 1.00), from the least-squares start
    used until 2026-11-26 as from starts around the posterior mode: the mode is the
    posterior's, and R-hat cannot see it. fit must notice the implausible mass spread, refit
    with Me's spread prior held near 2 % and say so in the summary; without the automatic
    refit the failure is visible and flagged.

    The held fit is itself bimodal here: measured with sampler seeds 0-3, in two of them one
    chain of four slid (its mean spread 35 %, R-hat 1.53, Me -10 %), and fit went on to share Me
    by all tests (Me -0.05 %); in the other two the held fit stood (Me -0.8 %). Either end
    must be right and say what it did."""
    series = _white_force_noise_series(seed=3)
    truth = series.extra["truth"]["Me"]
    as_recorded = SignalOptions(periodic_acceleration=False, accelerometer_noise=False)
    raw = summarize(fit(series, seed=2, auto_mass_refit=False, signals=as_recorded).tree)
    assert raw["between_test_spread"]["Me"]["relative_sd_mean"] > 0.10
    assert raw["parameters"]["Me"]["mean"] < 0.9 * truth  # the failure itself
    assert any("moving mass varies" in w and "--shared Me" in w for w in raw["warnings"])

    for seed in (1, 2):
        result = fit(series, seed=seed, signals=as_recorded)
        refit = json.loads(result.tree.attrs["mass_refit"])
        assert "Me" in result.priors.spread_by_coefficient and refit["first_fit_mass_spread"] > 0.10
        summary = summarize(result.tree)
        assert summary["converged"], seed
        assert abs(summary["parameters"]["Me"]["mean"] / truth - 1) < 0.015, seed
        assert summary["parameters"]["Me"]["q05"] <= truth <= summary["parameters"]["Me"]["q95"], seed
        if refit.get("shared"):
            assert refit["held_fit_mass_spread"] > 0.10 and "Me" in result.priors.shared
            assert any(w.startswith("Me's between-test spread is zero (Me shared by all tests)") for w in summary["warnings"])
        else:
            assert "Me" not in result.priors.shared
            assert any(w.startswith("Me's between-test spread is held near 2 %") for w in summary["warnings"])
            assert summary["between_test_spread"]["Me"]["relative_sd_q95"] < 0.05


def test_a_mass_spread_the_held_prior_cannot_hold_ends_in_a_shared_mass(monkeypatch):
    """The refit's last step: when the spread is still above the limit with its prior held,
    Me is shared by all tests. Triggered here by lowering the limit below any fitted spread
    (the twin's Me varies by 1 %), so that the first and the held fit both exceed it. The
    campaign's last 8 tests (2-3 Hz sines and triangles) pin a shared Me to 0.23 % by their data
    alone (measured with --shared Me)."""
    import bayes_sst.inference._fit as fit_module

    monkeypatch.setattr(fit_module, "IMPLAUSIBLE_MASS_SPREAD", 1e-4)
    series = simulate("sst-paper", seed=4, spread=0.01, plan=default_plan("sst-paper")[12:])
    messages = []
    result = fit(series, chains=2, draws=150, warmup=150, seed=1, extensions=0, progress=messages.append)
    refit = json.loads(result.tree.attrs["mass_refit"])
    assert refit["shared"] and refit["first_fit_mass_spread"] > 1e-4 and refit["held_fit_mass_spread"] > 1e-4
    assert "Me" in result.priors.shared and "Me" in result.priors.spread_by_coefficient
    assert any(m.startswith("refitting with its between-test spread held") or "held near 2 %" in m for m in messages)
    assert any("refitting with Me shared by all tests" in m for m in messages)
    assert np.all(result.posterior["between_test_sd"].sel(coefficient="Me").values == 0.0)
    summary = summarize(result.tree)
    assert any(w.startswith("Me's between-test spread is zero (Me shared by all tests)") and "held near 2 %" in w
               for w in summary["warnings"])
    truth = series.extra["truth"]["Me"]
    assert abs(summary["parameters"]["Me"]["mean"] / truth - 1) < 0.03
    # the shared mass still allows for the 2 % between tests that sharing left out: over 8
    # tests that adds at least 2 %/sqrt(8) = 0.71 % to Me's sd
    assert result.priors.ignored_spread == {"Me": 0.02} and refit["ignored_spread"] == 0.02
    assert summary["parameters"]["Me"]["sd"] / summary["parameters"]["Me"]["mean"] > 0.0071
    assert any("allows for the tests' masses differing by 2 %" in w for w in summary["warnings"])


def test_the_averaged_acceleration_keeps_the_mass_from_sliding_under_white_force_noise():
    """The same series with the default signals: the accelerometer's cycle-synchronous average
    cuts its noise by the cycle count, the mass stays put and no refit is needed."""
    series = _white_force_noise_series()
    truth = series.extra["truth"]["Me"]
    result = fit(series, seed=1)
    assert "mass_refit" not in result.tree.attrs and "Me" not in result.priors.shared
    summary = summarize(result.tree)
    assert abs(summary["parameters"]["Me"]["mean"] / truth - 1) < 0.02
    assert summary["parameters"]["Me"]["q05"] <= truth <= summary["parameters"]["Me"]["q95"]
    assert summary["between_test_spread"]["Me"]["relative_sd_mean"] < 0.05


def test_without_an_accelerometer_damping_and_friction_stay_close(noisy_fit):
    """The same series with `a` (and `v`) removed: the acceleration then comes from the
    displacement. Measured: Me -1.6 %, Ke -0.0 %, Ce +2.7 %, alpha -0.003, Fmu -2.8 %; with the
    second derivative of the low-passed u used before, Ce +10.3 % and Fmu -8.6 %."""
    series, _ = noisy_fit
    without = replace(series, tests=tuple(
        TestRecord(r.spec, {k: v for k, v in r.columns.items() if k not in ("a", "v")}) for r in series.tests))
    truth = series.extra["truth"]
    summary = summarize(fit(without, seed=3).tree)
    for name, tolerance in (("Me", 0.03), ("Ke", 0.03), ("Ce", 0.06), ("Fmu", 0.05)):
        assert abs(summary["parameters"][name]["mean"] / truth[name] - 1) < tolerance, name
    assert abs(summary["parameters"]["alpha"]["mean"] - truth["alpha"]) < 0.05


@pytest.mark.skipif(not os.path.exists("/proc/self/maps"), reason="needs Linux /proc")
def test_fits_release_their_compiled_programs():
    """Each fit's sampler is a new compiled program of hundreds of memory mappings; kept, ~70
    fits in one process exhausted the kernel's 65,530 and LLVM aborted. Released, the count
    stays flat. Measured on this 4-test series: +3 per fit released, +217 to +278 kept (+410
    to +473 while the warm-up also adapted the mass matrix, whose code made the program
    larger)."""
    def mappings():
        with open("/proc/self/maps") as fh:
            return sum(1 for _ in fh)

    series = simulate("sst-paper", seed=2, plan=default_plan("sst-paper")[:4])
    fit(series, chains=2, draws=50, warmup=50, seed=0, extensions=0)
    before = mappings()
    for seed in (1, 2):
        fit(series, chains=2, draws=50, warmup=50, seed=seed, extensions=0)
    assert (mappings() - before) / 2 < 50
    kept = mappings()
    fit(series, chains=2, draws=50, warmup=50, seed=3, release_compiled=False, extensions=0)
    assert mappings() - kept > 150


def test_a_second_series_of_the_same_size_reuses_the_compiled_sampler(tmp_path):
    """Two different series of six tests, fitted in two fresh processes that share a
    persistent compilation cache: the sampler is compiled once (one cache entry), because the
    data, start values and initial mass matrix reach it as arguments, not as constants.
    (Arrays of up to 32 bytes stay embedded: series of four tests or fewer compile each time.)"""
    script = (
        "import sys\n"
        "from bayes_sst.inference import fit\n"
        "from bayes_sst.twin import default_plan, simulate\n"
        "series = simulate('sst-paper', seed=int(sys.argv[1]), spread=0.02, plan=default_plan('sst-paper')[:6])\n"
        "fit(series, chains=2, draws=50, warmup=50, extensions=0)\n"
    )
    env = dict(os.environ, BAYES_SST_CACHE=str(tmp_path / "cache"))
    env.pop("JAX_USE_SIMPLIFIED_JAXPR_CONSTANTS", None)
    for seed in (1, 2):
        subprocess.run([sys.executable, "-c", script, str(seed)], check=True, env=env, capture_output=True)
    samplers = [p.name for p in (tmp_path / "cache").iterdir() if p.name.startswith("jit__fun")]
    assert len(samplers) == 1, samplers


def test_a_run_whose_series_folder_moved_says_how_to_point_at_it(tmp_path):
    from types import SimpleNamespace

    from bayes_sst.inference._predictive import run_prepared

    gone = SimpleNamespace(attrs={"series_path": str(tmp_path / "moved-away")})
    with pytest.raises(ValueError, match="is not there any more.*--series SERIES"):
        run_prepared(gone)
    with pytest.raises(ValueError, match="does not record its series folder.*--series"):
        run_prepared(SimpleNamespace(attrs={}))
    from bayes_sst.inference._predictive import run_series

    with pytest.raises(ValueError, match=r"bayes-sst design RUN --series SERIES"):
        run_series(gone, "design")


def test_a_coefficient_whose_interval_reaches_zero_is_named():
    from bayes_sst.inference._summary import unphysical_coefficients

    parameters = {name: {"q05": 0.9 * value, "q95": 1.1 * value}
                  for name, value in {"Me": 13_200.0, "Ke": 7.2e5, "Ce": 29_600.0, "Fmu": 12_500.0}.items()}
    assert unphysical_coefficients(parameters) == []
    parameters["Me"]["q05"] = -5_900.0
    parameters["Fmu"]["q05"] = 0.0
    assert unphysical_coefficients(parameters) == ["Me", "Fmu"]


def test_a_loosely_determined_parameter_is_named():
    from bayes_sst.inference._summary import weak_parameters

    means = {"Me": 13_200.0, "Ke": 7.2e5, "Ce": 29_600.0, "alpha": 0.5, "Fmu": 12_500.0}
    parameters = {name: {"mean": m, "sd": 0.02 * m, "q05": 0.97 * m} for name, m in means.items()}
    assert weak_parameters(parameters) == {}
    parameters["Fmu"]["sd"] = 2_000.0  # 16 %
    parameters["alpha"]["sd"] = 0.18
    parameters["Me"].update(sd=7_300.0, q05=-1_000.0)  # left to the interval-reaches-zero note
    weak = weak_parameters(parameters)
    assert list(weak) == ["Fmu", "alpha"]
    assert weak["Fmu"] == pytest.approx(0.16) and weak["alpha"] == 0.18


def test_a_between_test_spread_beyond_a_tables_repeatability_is_named():
    """wide_spreads names the coefficients whose between-test sd exceeds 5 % (the 6.5 Hz
    specimen series read Me 6.9, Ke 4.2, Ce 7.6, Fmu 6.6 %; clean series 0.9-4.0 %), and leaves
    an Me spread beyond the implausible 10 % to that note."""
    from bayes_sst.inference._summary import wide_spreads

    spread = {name: {"relative_sd_mean": value} for name, value in
              {"Me": 0.069, "Ke": 0.042, "Ce": 0.076, "Fmu": 0.066}.items()}
    assert wide_spreads(spread) == {"Me": 0.069, "Ce": 0.076, "Fmu": 0.066}
    spread["Me"]["relative_sd_mean"] = 0.21
    assert list(wide_spreads(spread)) == ["Ce", "Fmu"]
    clean = {name: {"relative_sd_mean": value} for name, value in
             {"Me": 0.021, "Ke": 0.040, "Ce": 0.020, "Fmu": 0.025}.items()}
    assert wide_spreads(clean) == {}


def test_a_start_the_numpy_potential_cannot_evaluate_is_evaluated_by_numpyro(monkeypatch):
    """fit hands NUTS a start with a potential computed in numpy; where that potential is not
    finite NumPyro evaluates the start's potential itself, and the fit still recovers the
    truth of a six-test series."""
    import bayes_sst.inference._model as model

    exact = model.potential_and_gradient
    monkeypatch.setattr(model, "potential_and_gradient", lambda *args, **kwargs: (float("nan"), exact(*args, **kwargs)[1]))
    series = simulate("sst-paper", seed=4, spread=0.02, plan=default_plan("sst-paper")[:6])
    summary = summarize(fit(series, chains=2, draws=150, warmup=150, seed=1).tree)
    truth = series.extra["truth"]
    for name in ("Ke", "Ce", "Fmu"):
        assert abs(summary["parameters"][name]["mean"] / truth[name] - 1) < 0.1, name


def test_a_start_no_potential_can_evaluate_stops_the_fit_with_a_clear_error(monkeypatch):
    """Where neither the numpy potential nor the sampler's own JAX potential is finite at the
    chains' start, fit raises an error that says so instead of handing NUTS an infinite energy
    (NUTS would reject every move and return the start as its draws without complaint)."""
    import jax.numpy as jnp

    import bayes_sst.inference._model as model

    exact = model.potential_and_gradient
    monkeypatch.setattr(model, "potential_and_gradient", lambda *args, **kwargs: (float("nan"), exact(*args, **kwargs)[1]))
    monkeypatch.setattr(model, "whitened_potential",
                        lambda params, table, priors, frame: jnp.nan * jnp.sum(params["global"]))
    series = simulate("sst-paper", seed=4, spread=0.02, plan=default_plan("sst-paper")[:6])
    with pytest.raises(RuntimeError, match="not finite at the chains' start"):
        fit(series, chains=2, draws=20, warmup=20, seed=1)


@pytest.mark.slow
def test_a_drifting_accelerometer_on_the_lugre_generator_does_not_pin_a_wrong_mass(tmp_path):
    """The second independent generator's clean series at 200 Hz (benchmarks/lugre_generator.py,
    seed 0: 13 tests, triangles and payloads among them, an accelerometer with 0.018 m/s^2 of
    white noise and 0.008 m/s^2 of AR(1) drift). Before the drift was read off the record
    (signals.coloured_noise_excess, 2026-11-26) the sine tests' Me slid 20-40 % low, the
    between-test spread of Me came out at 18 %, and the shared-Me refit put Me +3.9 % at 26
    sds (Ke +5.7 %). Now no refit, and every population value lies within 2.5 sds."""
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    from lugre_generator import generate

    folder = tmp_path / "series"
    generate(0, str(folder), rate=200, verbose=False)
    truth = json.loads((folder / "truth.json").read_text())
    result = fit(load_series(folder), seed=0)
    assert not result.tree.attrs.get("mass_refit")
    parameters = summarize(result.tree)["parameters"]
    for name in ("Me", "Ke", "Ce", "alpha", "Fmu"):
        z = (parameters[name]["mean"] - truth[name]) / parameters[name]["sd"]
        assert abs(z) < 2.5, (name, z)
    assert parameters["Me"]["mean"] == pytest.approx(truth["Me"], rel=0.03)


def test_chains_start_apart_by_the_starting_mass_matrix():
    """Each chain starts at mode + dispersion * N(0, inverse mass): over many chains the
    starts' mean is the mode and their covariance is dispersion^2 times the dense global block
    and the per-test variances; the same seed gives the same starts, another seed others."""
    from bayes_sst.inference._fit import _dispersed_starts

    rng = np.random.default_rng(0)
    root = rng.standard_normal((5, 5)) * 0.1 + np.diag([0.5, 0.3, 0.2, 0.4, 0.6])
    global_block = root @ root.T
    inverse_mass = {("alpha", "spread"): global_block, ("phi",): np.array([0.01, 0.04, 0.09]),
                    ("sigma",): np.array([0.25, 0.01, 0.0025])}
    mode = {"alpha": np.asarray(0.3), "spread": np.array([-4.0, -3.5, -3.0, -4.5]),
            "phi": np.array([0.1, 0.5, -0.2]), "sigma": np.array([-1.0, 0.0, 1.0])}
    starts = _dispersed_starts(mode, inverse_mass, 4000, seed=3, dispersion=2.0)
    global_shift = np.stack([np.concatenate([np.atleast_1d(s["alpha"] - mode["alpha"]), s["spread"] - mode["spread"]])
                             for s in starts])
    np.testing.assert_allclose(np.cov(global_shift.T), 4.0 * global_block, atol=0.08 * 4.0 * global_block.max())
    assert np.all(np.abs(global_shift.mean(axis=0)) < 0.1 * np.sqrt(4.0 * np.diag(global_block)))
    for name in ("phi", "sigma"):
        shift = np.stack([s[name] - mode[name] for s in starts])
        np.testing.assert_allclose(shift.var(axis=0), 4.0 * inverse_mass[(name,)], rtol=0.08)
    assert np.shape(starts[0]["alpha"]) == () and starts[0]["phi"].shape == (3,)
    again = _dispersed_starts(mode, inverse_mass, 2, seed=3, dispersion=2.0)
    other = _dispersed_starts(mode, inverse_mass, 2, seed=4, dispersion=2.0)
    np.testing.assert_array_equal(again[0]["phi"], starts[0]["phi"])
    assert not np.allclose(other[0]["phi"], starts[0]["phi"])
    assert not np.allclose(starts[0]["phi"], starts[1]["phi"])


def test_the_payloads_friction_gain_is_learned_where_the_description_misstates_the_load():
    """The twin's friction is mu_e*(F_hd + (m_deck + payload)*g); the series' description here
    halves the struts' pre-charge, so the friction increase it predicts for a payload is
    N_true/N_described times too large and the true gain is kappa = N_described/N_true (0.56 on
    the SST). Eight of twenty tests carry 5 or 10 t. With kappa held at 1 those tests' smaller
    friction pulls the population Fmu down; learned, kappa's 90 % interval holds the truth and
    Fmu is the empty table's."""
    from bayes_sst.inference import make_priors
    from bayes_sst.physics import hold_down_force, normal_force

    plan = [item._replace(payload_kg=(5000.0 if i % 2 else 10000.0) if i % 5 in (1, 3) else 0.0)
            for i, item in enumerate(default_plan("sst-paper"))]
    simulated = simulate("sst-paper", seed=6, spread=0.02, plan=plan)
    strut = simulated.table["strut"]
    described = {**simulated.table, "strut": {**strut, "p0_pa": 0.5 * strut["p0_pa"]}}
    series = replace(simulated, table=described)
    deck = simulated.table["deck_mass_kg"]
    kappa = (normal_force(hold_down_force(0.5 * strut["p0_pa"], strut["area_m2"]), deck)
             / normal_force(hold_down_force(strut["p0_pa"], strut["area_m2"]), deck))
    truth = simulated.extra["truth"]

    learned = summarize(fit(series, seed=2).tree)
    gain = learned["payload_friction_gain"]
    assert gain["q05"] <= kappa <= gain["q95"], (kappa, gain)
    assert abs(gain["mean"] / kappa - 1) < 0.3
    assert gain["r_hat"] <= 1.01 and gain["ess_bulk"] >= 400
    assert f"payload's friction gain {gain['mean']:.2f}" in format_summary(learned)
    assert abs(learned["parameters"]["Fmu"]["mean"] / truth["Fmu"] - 1) < 0.03

    # only the held fit's mean is read: two chains are enough for it
    held = summarize(fit(series, seed=2, chains=2, draws=300, warmup=200,
                         prior=replace(make_priors("generic", described), payload_friction_gain=None)).tree)
    assert "payload_friction_gain" not in held
    held_error = held["parameters"]["Fmu"]["mean"] / truth["Fmu"] - 1
    assert held_error < -0.02
    assert abs(learned["parameters"]["Fmu"]["mean"] / truth["Fmu"] - 1) < 0.5 * abs(held_error)


def test_the_mass_spread_is_read_per_chain():
    """One chain of four settled where Me varies by 35 % between tests, three at 1 %: the
    all-draws mean (9.5 %) is under the 10 % limit, the largest chain mean is not, and both fit's
    mass refit and the summary's warning read the latter (largest_chain_spread)."""
    import xarray as xr

    from bayes_sst.inference._summary import IMPLAUSIBLE_MASS_SPREAD, largest_chain_spread

    rng = np.random.default_rng(0)
    relative = np.array([0.35, 0.01, 0.01, 0.01])[:, None] * (1.0 + 0.05 * rng.standard_normal((4, 200)))
    between = np.zeros((4, 200, 4))
    between[..., 0] = relative * 12_000.0
    posterior = xr.Dataset({"Me": (("chain", "draw"), np.full((4, 200), 12_000.0)),
                            "between_test_sd": (("chain", "draw", "coefficient"), between)},
                           coords={"coefficient": ["Me", "Ke", "Ce", "Fmu"]})
    assert relative.mean() < IMPLAUSIBLE_MASS_SPREAD
    assert largest_chain_spread(posterior, "Me") == pytest.approx(relative[0].mean(), rel=1e-12)
    assert largest_chain_spread(posterior, "Me") > IMPLAUSIBLE_MASS_SPREAD


def test_a_per_test_exponent_is_recovered_and_keeps_its_spread_out_of_ce():
    """Tests whose damping exponents differ (the twin's alpha_spread: 0.08 between tests, a
    damping law read over different speed ranges): with --per-test-alpha the exponent's
    between-test sd must contain the spread the twin drew, the population values their truth,
    and the per-test Ce must no longer carry the exponent's spread as the shared-exponent fit's
    does."""
    from bayes_sst.inference._priors import make_priors

    series = simulate("sst-paper", seed=5, spread=0.02, alpha_spread=0.08)
    drawn = np.array([t.spec.extra["truth"]["alpha"] for t in series.periodic_tests])
    truth = series.extra["truth"]
    per_test = fit(series, seed=1, prior=make_priors("generic", per_test_alpha=True))
    shared = fit(series, seed=1)
    summary, shared_summary = summarize(per_test.tree), summarize(shared.tree)
    assert summary["converged"]
    tau = summary["alpha_between_test_sd"]
    assert tau["q05"] <= drawn.std(ddof=1) <= tau["q95"], (tau, drawn.std(ddof=1))
    for name in NAMES:
        low, high = np.quantile(per_test.posterior[name].values, [0.005, 0.995])
        assert low <= truth[name] <= high, (name, low, high, truth[name])
    assert abs(summary["parameters"]["alpha"]["mean"] - truth["alpha"]) < 0.05
    ce_spread = summary["between_test_spread"]["Ce"]["relative_sd_mean"]
    assert ce_spread < 0.6 * shared_summary["between_test_spread"]["Ce"]["relative_sd_mean"]
    assert "alpha_between_test_sd" not in shared_summary
    # the shared-exponent fit, whose model cannot know the tests' exponents differ, reads alpha
    # 0.418-0.486 against a truth of 0.5; leaving tests out shows the scatter, and its
    # interval, stretched by about 1.5, holds the truth
    from bayes_sst.inference._widening import model_draws

    model_low, model_high = np.quantile(model_draws(shared.tree, "alpha").values, [0.05, 0.95])
    assert not model_low <= truth["alpha"] <= model_high
    assert shared_summary["widening"]["alpha"]["factor"] > 1.3
    assert shared_summary["parameters"]["alpha"]["q05"] <= truth["alpha"] <= shared_summary["parameters"]["alpha"]["q95"]
    # each test's own exponent follows the one the twin drew for it
    own = per_test.posterior["alpha_test"].mean(("chain", "draw")).values
    assert np.corrcoef(own, drawn)[0, 1] > 0.8
    assert np.sqrt(np.mean((own - drawn) ** 2)) < 0.5 * drawn.std()
    # the design's pieces share the exponent: it says so instead of starting from narrower intervals
    from bayes_sst.design._engine import design_posterior

    with pytest.raises(ValueError, match="--per-test-alpha"):
        design_posterior(per_test.tree, per_test.prepared)
    assert "(sd of the exponent itself)" in format_summary(summary)
