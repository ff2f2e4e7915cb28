"""Posterior-predictive checks of a run: bands, their coverage, per-test statistics, LOO-PIT.

Everything here is computed from the run's own posterior draws (thinned) and the regressors
the likelihood used (bayes_sst.inference.posterior_predictive); nothing is refitted.

Bands. For test j and kept sample t the replicated force is

    F_rep = m_payload*a + X_t(alpha) . theta_j + e_t,  e AR(1)(phi_j, sigma_j),

one path per posterior draw; the 50 % and 90 % bands are its central quantiles per sample.
At a sample that entered the fit, the draws are reweighted by the PSIS leave-one-point-out
weights of that sample (from ArviZ's PSIS), so that the band is a prediction of the
point rather than a fit to it: with ~40 points a test and 4 coefficients of its own, plain
in-sample bands over-cover (on the 20-test example 94.7 % of the points in the 90 % bands
and only 8 of 20 tests within 85-95 %; with the LOO weights 92.7 % and 14 of 20). Samples
without LOO weights (velocity-reversal band, first sample after a gap) were not fitted, so
their plain posterior-predictive band already predicts them.
Coverage is the share of measured points inside a band, counted at the samples that enter
the likelihood (outside the velocity-reversal band, where the model is not meant to hold).

Per-test statistics T (RMS force, peak force, energy dissipated per cycle over the steady
window): p = P(T(F_rep) >= T(F_obs)), ties counted half. Like the bands, they are computed on
the signals the likelihood sees, in which the reversal band is weighted to zero before the
low-pass (signals.reversal_weight): the model is not meant to hold there, so a check that
included it would only restate that. The energy per cycle is therefore the area of the loop
outside the reversal band, smaller than the recorded loop's (about half on the example). The phase-locked residual
D(F, s) = max over eighths b of the cycle of |mean of F - m_s over the kept samples in b|,
m_s the model force of draw s, is large when a force repeats every cycle at the same phase
and the model has no term for it; it is a realised discrepancy, p = P(D(F_rep,s, s) >=
D(F_obs, s)) over the draws, and its "observed" value is the median of D(F_obs, s).
p near 0 means the measured value is larger than the model reproduces, near 1 smaller.

LOO-PIT. The run's log_likelihood is per test with the test's coefficients integrated out,
and each test has its own noise parameters (phi_j, sigma_j) informed by that test alone;
leaving a whole test out therefore moves the posterior far and PSIS fails on it (Pareto k
above 0.7 for nearly every test, by construction). The report's LOO is leave-one-point-out on
the one-step-ahead predictive of each measured point given its kept predecessor,

    y_t | y_(t-1) ~ N(m_t + phi_j (y_(t-1) - m_(t-1)), sigma_j^2),   m = model force,

the very factors whose product is the fit's conditional likelihood. Under the model these
PIT values are independent and uniform (the innovations are white), so the ECDF envelope of
the LOO-PIT plot is valid, and the Pareto k of each point says whether PSIS can be trusted.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import xarray as xr

from bayes_sst.report._loops import loop_energy, peak_force, rms_force

BAND_PROBS = (0.5, 0.9)
BAND_QUANTILES = (0.05, 0.25, 0.75, 0.95)
STATISTICS = {
    "rms_force": ("RMS force", "kN", 1e-3),
    "peak_force": ("peak force", "kN", 1e-3),
    "energy": ("energy per cycle (reversal band weighted out)", "kJ", 1e-3),
    "phase_residual": ("phase-locked residual", "kN", 1e-3),
}
PHASE_BINS = 8
# a p-value this close to 0 or 1 (two-sided 1 %) marks a statistic the model does not
# reproduce; with 3 statistics per test a 20-test series then gives ~0.6 false alarms
P_EXTREME = 0.005


def thinned_posterior(tree, max_draws: int) -> xr.Dataset:
    """The posterior with each chain thinned evenly so that chains*draws <= max_draws, its
    population values the model's own (model_posterior where the run widened its intervals):
    each draw's test coefficients were drawn with them."""
    from bayes_sst.inference._widening import model_posterior

    post = model_posterior(tree)
    chains, draws = post.sizes["chain"], post.sizes["draw"]
    per_chain = max(1, min(draws, max_draws // max(chains, 1)))
    pick = np.linspace(0, draws - 1, per_chain).round().astype(int)
    return post.isel(draw=np.unique(pick))


@dataclass(frozen=True)
class TestCheck:
    """The posterior-predictive check of one test; arrays over the test's kept (decimated) samples."""

    __test__ = False

    test_id: str
    kind: str
    frequency_hz: float
    amplitude_m: float
    t: np.ndarray
    u: np.ndarray
    v: np.ndarray
    phase: np.ndarray  # cycle phase in [0, 1): 0 where u crosses zero going up
    observed: np.ndarray
    keep: np.ndarray
    mean: np.ndarray  # posterior mean of the model force, N
    bands: dict  # prob -> (low, high) arrays of the replicated force
    coverage: dict  # prob -> share of kept measured points inside the band
    coverage_all: dict  # prob -> share over all window samples (reversals included)
    statistics: dict  # name -> {"observed", "replicated" (draws,), "p_value"}


def _p_value(replicated: np.ndarray, observed: float) -> float:
    """P(T_rep > T_obs) + P(T_rep = T_obs)/2 over the draws."""
    return float(np.mean(replicated > observed) + 0.5 * np.mean(replicated == observed))


def phase_locked_residual(residual, phase, keep, bins: int = PHASE_BINS) -> np.ndarray:
    """max_b |mean of residual over the kept samples whose cycle phase lies in bin b|, N.

    residual may carry leading axes (draws); phase (in cycles) and keep are over samples.
    Empty bins are skipped.
    """
    residual = np.asarray(residual, dtype=float)
    which = np.minimum((np.asarray(phase) * bins).astype(int), bins - 1)
    means = []
    for b in range(bins):
        members = keep & (which == b)
        if members.any():
            means.append(np.abs(residual[..., members].mean(axis=-1)))
    if not means:
        return np.zeros(residual.shape[:-1])
    return np.max(np.stack(means), axis=0)


def test_statistics(t, force, u, frequency_hz: float) -> dict:
    """RMS force, peak force and energy per cycle of force (..., n) over samples t, u (n,)."""
    return {
        "rms_force": rms_force(force),
        "peak_force": peak_force(force),
        "energy": loop_energy(t, force, u, frequency_hz),
    }


def check_test(pred, test, loo_bands=None) -> TestCheck:
    """Bands, coverage and statistic p-values of one TestPredictive and its PreparedTest.

    loo_bands : (sample positions, {q: quantiles}) of this test from PointLoo; the bands take
        these leave-one-point-out quantiles at those samples (see the module docstring).
    """
    bands, coverage, coverage_all = {}, {}, {}
    for prob in BAND_PROBS:
        q_low, q_high = round(0.5 - prob / 2, 10), round(0.5 + prob / 2, 10)
        low, high = np.quantile(pred.replicated, [q_low, q_high], axis=0)
        if loo_bands is not None:
            where, quantiles = loo_bands
            low[where], high[where] = quantiles[q_low], quantiles[q_high]
        inside = (pred.observed >= low) & (pred.observed <= high)
        bands[prob] = (low, high)
        coverage[prob] = float(inside[pred.keep].mean()) if pred.keep.any() else float("nan")
        coverage_all[prob] = float(inside.mean())
    observed_stats = test_statistics(pred.t, pred.observed, pred.u, test.frequency_hz)
    replicated_stats = test_statistics(pred.t, pred.replicated, pred.u, test.frequency_hz)
    # the cycle origin is where u's fundamental crosses zero going up (signals._cycles)
    t0 = test.t[0] - (test.index[0] - test.window.start) / test.sample_rate_hz
    phase = ((pred.t - t0) * test.frequency_hz) % 1.0
    # a realised discrepancy: measured and replicated force against the same draw's model
    # force, so that the draws' own phase-locked differences do not hide a missing effect
    observed_phase = phase_locked_residual(pred.observed - pred.mean, phase, pred.keep)
    replicated_phase = phase_locked_residual(pred.replicated - pred.mean, phase, pred.keep)
    statistics = {
        name: {
            "observed": float(observed_stats[name]),
            "replicated": np.asarray(replicated_stats[name]),
            "p_value": _p_value(np.asarray(replicated_stats[name]), float(observed_stats[name])),
        }
        for name in observed_stats
    }
    statistics["phase_residual"] = {
        "observed": float(np.median(observed_phase)),
        "replicated": replicated_phase,
        "p_value": float(np.mean(replicated_phase > observed_phase) + 0.5 * np.mean(replicated_phase == observed_phase)),
    }
    return TestCheck(
        test_id=pred.test_id, kind=test.kind, frequency_hz=test.frequency_hz, amplitude_m=test.amplitude_m,
        t=pred.t, u=pred.u, v=pred.v, phase=phase, observed=pred.observed, keep=pred.keep,
        mean=pred.mean.mean(axis=0), bands=bands, coverage=coverage, coverage_all=coverage_all,
        statistics=statistics,
    )


def weighted_quantile(values: np.ndarray, log_weights: np.ndarray, q: float) -> np.ndarray:
    """Quantile q of each column of values (draws, N) under normalised weights exp(log_weights).

    The weighted empirical CDF at the sorted draws x_(1) <= ... <= x_(S) is taken at the
    middle of each draw's weight, F_i = sum_(k<i) w_k + w_i/2, and inverted linearly; with
    equal weights this is the usual (i - 1/2)/S plotting position.
    """
    order = np.argsort(values, axis=0)
    x = np.take_along_axis(values, order, axis=0)
    w = np.exp(np.take_along_axis(log_weights, order, axis=0) - log_weights.max(axis=0))
    w /= w.sum(axis=0)
    cdf = np.cumsum(w, axis=0) - 0.5 * w
    out = np.empty(values.shape[1])
    for i in range(values.shape[1]):
        out[i] = np.interp(q, cdf[:, i], x[:, i])
    return out


@dataclass(frozen=True)
class PointLoo:
    """Leave-one-point-out of the one-step-ahead predictive (see the module docstring)."""

    test_index: np.ndarray  # (N,) which test each point belongs to
    sample_index: np.ndarray  # (N,) position within the test's kept samples
    pareto_k: np.ndarray  # (N,)
    good_k: float  # PSIS reliability threshold for this number of draws
    pit: np.ndarray  # (N,) LOO-PIT values
    elpd: float
    elpd_se: float
    tree: object  # DataTree with posterior_predictive, observed_data and log_likelihood "F" for plots
    elpd_data: object  # arviz_stats ELPDData, point-wise
    band_quantiles: dict  # q -> (N,) PSIS-LOO quantile q of the replicated force at each point


def point_loo(predictives, posterior: xr.Dataset, *, seed: int = 0) -> PointLoo:
    """PSIS-LOO and LOO-PIT of every measured point that has a kept predecessor.

    `predictives` are the TestPredictive of the thinned `posterior` (same draw order:
    chains then draws). The log predictive density of point t under draw s is

        log N(y_t; m_st + phi_sj (y_(t-1) - m_s,t-1), sigma_sj^2)

    and one replicated value per draw from the same normal feeds ArviZ's loo_pit.
    """
    from arviz_stats import loo, loo_pit

    chains, draws = posterior.sizes["chain"], posterior.sizes["draw"]
    phi = posterior["phi"].values.reshape(chains * draws, -1)
    sigma = posterior["sigma"].values.reshape(chains * draws, -1)
    rng = np.random.default_rng(seed)
    logs, reps, paths, obs, which, where = [], [], [], [], [], []
    for j, pred in enumerate(predictives):
        pairs = np.flatnonzero(pred.keep[1:] & pred.keep[:-1]) + 1
        if len(pairs) == 0:
            continue
        y, m = pred.observed, pred.mean
        centre = m[:, pairs] + phi[:, j : j + 1] * (y[pairs - 1] - m[:, pairs - 1])
        sd = sigma[:, j : j + 1]
        z = (y[pairs] - centre) / sd
        logs.append(-0.5 * z**2 - np.log(sd) - 0.5 * np.log(2.0 * np.pi))
        reps.append(centre + sd * rng.standard_normal(centre.shape))
        paths.append(pred.replicated[:, pairs])
        obs.append(y[pairs])
        which.append(np.full(len(pairs), j))
        where.append(pairs)
    if not logs:
        raise ValueError("no test has two consecutive kept samples; LOO cannot be computed")
    log_lik = np.concatenate(logs, axis=1).reshape(chains, draws, -1)
    replicated = np.concatenate(reps, axis=1).reshape(chains, draws, -1)
    observed = np.concatenate(obs)
    dims = ("chain", "draw", "point")
    coords = {"chain": posterior["chain"].values, "draw": posterior["draw"].values}
    tree = xr.DataTree.from_dict(
        {
            # loo needs a posterior group for its sample dimensions; alpha is enough
            "posterior": xr.Dataset({"alpha": posterior["alpha"]}),
            "posterior_predictive": xr.Dataset({"F": (dims, replicated)}, coords=coords),
            "log_likelihood": xr.Dataset({"F": (dims, log_lik)}, coords=coords),
            "observed_data": xr.Dataset({"F": (("point",), observed)}),
        }
    )
    import warnings

    with warnings.catch_warnings():
        # a high Pareto k is reported by the health checks, in words; ArviZ's own warning
        # would only repeat it (and the test suite turns warnings into errors)
        warnings.simplefilter("ignore", UserWarning)
        elpd = loo(tree, pointwise=True, var_name="F")
        pit = loo_pit(tree, var_names="F", log_weights=xr.Dataset({"F": elpd.log_weights}),
                      pareto_k=xr.Dataset({"F": elpd.pareto_k}))
    # the bands' leave-one-point-out version: the replicated path at each point, reweighted
    # by the same PSIS weights (ArviZ's loo_expectations would refit a Pareto tail per
    # quantile for its own k diagnostics, several seconds for a 20-test run)
    path = np.concatenate(paths, axis=1)  # (draws, N)
    log_w = np.asarray(elpd.log_weights.transpose("chain", "draw", ...).values).reshape(chains * draws, -1)
    band_quantiles = {q: weighted_quantile(path, log_w, q) for q in BAND_QUANTILES}
    return PointLoo(
        test_index=np.concatenate(which),
        sample_index=np.concatenate(where),
        pareto_k=np.asarray(elpd.pareto_k.values),
        good_k=float(elpd.good_k),
        # a sum of normalised weights can round to 1 + 2e-16; a PIT is a probability
        pit=np.clip(np.asarray(pit["F"].values), 0.0, 1.0),
        elpd=float(elpd.elpd),
        elpd_se=float(elpd.se),
        tree=tree,
        elpd_data=elpd,
        band_quantiles=band_quantiles,
    )
