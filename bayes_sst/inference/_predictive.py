"""Posterior predictive force of a run, test by test, from the same regressors as the likelihood.

For test j and posterior draw s the replicated force at the kept samples is

    F_rep = m_payload*a + X(alpha_s) . theta_js + e,   e_t = phi_js*e_(t-1) + w_t,  w ~ N(0, sigma_js^2)

with X = (a, u, filter(|v|^alpha sign v), filter(sign v)) exactly as in
bayes_sst.inference._statistics (at test j's own exponent alpha_js where the fit let it vary
between tests), and e started from its stationary law sd sigma/sqrt(1-phi^2).
"""

from __future__ import annotations

import json
from dataclasses import dataclass

import numpy as np

from bayes_sst.inference._statistics import COEFFICIENTS, damping_columns
from bayes_sst.inference._summary import run_left_out
from bayes_sst.inference._widening import flat_model_draws
from bayes_sst.signals import PreparedTest, SignalOptions


def design_matrix(test: PreparedTest, alpha: float) -> np.ndarray:
    """(n, 4) regressors [a, u, filter(|v|^alpha sign v), filter(sign v)] at the kept samples."""
    damping = test.regressor(damping_columns(np.array([float(alpha)])))[0]
    return np.column_stack([test.a, test.u, damping, test.friction_sign])


def response(test: PreparedTest) -> np.ndarray:
    """y = F - m_payload*a: the force the table's own parameters must explain."""
    return test.F - test.payload_kg * test.a


def run_signal_options(tree) -> SignalOptions:
    """The signal options a run was fitted with (defaults for runs that did not record them).

    A run whose options predate the reversal weight (no "reversal_window" key) or the
    synchronous average of a (no "periodic_acceleration"), the removal of the steady window's
    offsets (no "remove_offsets"), the payload's friction load (no "payload_friction") or the
    accelerometer's noise estimate (no "accelerometer_noise") was fitted without it, and is
    re-prepared without it; one from before the separate band for tests without an
    accelerometer (no "reversal_band_without_accelerometer") used its reversal_band for all,
    one from before the accelerometer check (no "check_accelerometer") used every recorded a,
    one from before the band's speed floor (no "reversal_speed") had none, and one from before
    the accelerometer-drift estimate (no "coloured_accelerometer_noise"), its displacement
    covariate (no "drift_displacement_covariate") or each test's free constant (no
    "free_constant") was fitted without it; one from before the fourth-difference noise read (no
    "noise_difference_order") read the accelerometer's noise from second differences; one from
    before the pre-sliding read (no "presliding") or its floor (no "presliding_floor") left no
    such turn out, and one from before the
    kernel on the force (no "kernel_on_force") filtered the raw force of a test without an
    accelerometer.
    """
    text = tree.attrs.get("signal_options", "")
    if not text:
        return SignalOptions()
    recorded = json.loads(text)
    recorded.setdefault("reversal_window", False)
    recorded.setdefault("periodic_acceleration", False)
    recorded.setdefault("remove_offsets", False)
    recorded.setdefault("payload_friction", False)
    recorded.setdefault("accelerometer_noise", False)
    recorded.setdefault("reversal_band_without_accelerometer", None)
    recorded.setdefault("check_accelerometer", False)
    recorded.setdefault("reversal_speed", 0.0)
    recorded.setdefault("coloured_accelerometer_noise", False)
    recorded.setdefault("drift_displacement_covariate", False)
    recorded.setdefault("free_constant", False)
    recorded.setdefault("noise_difference_order", 2)
    recorded.setdefault("presliding", 0.0)
    recorded.setdefault("presliding_floor", 0.0)
    recorded.setdefault("kernel_on_force", False)
    return SignalOptions(**recorded)


def run_series(tree, command: str = "report", path=None, exclude=()):
    """The series a run was fitted on, read without the tests the run left out (those the
    manifest still lists; their files are not read) nor those in `exclude`. From `path`, else
    from the folder the run records (and then `exclude` must be empty: the run's series is its
    own); the errors say how to point `bayes-sst COMMAND RUN --series SERIES` at it when that
    folder is gone."""
    from pathlib import Path

    from bayes_sst.io import load_series
    from bayes_sst.io._read import manifest_test_ids
    from bayes_sst.io._series import as_test_ids

    if path is None:
        if exclude:
            raise ValueError("--exclude-test applies to a series given with --series; without one the run's own "
                             "series is read, less the tests the run left out")
        path = tree.attrs.get("series_path", "")
        if not path:
            raise ValueError("the run does not record its series folder; pass the series explicitly "
                             f"(bayes-sst {command} RUN --series SERIES)")
        if not Path(path).is_dir():
            raise ValueError(f"the series folder this run was fitted on, {path}, is not there any more; "
                             f"pass its new location (bayes-sst {command} RUN --series SERIES)")
    exclude = as_test_ids(exclude)
    listed = set(manifest_test_ids(path))
    exclude += [x for x in run_left_out(tree) if x in listed and x not in exclude]
    series = load_series(path, exclude=exclude)
    fitted = tree.attrs.get("series", "")
    if fitted and series.name != fitted:
        # a run read against another series' records gives bands, diagnoses and designs of
        # nothing; a moved series keeps its manifest's name
        raise ValueError(f"the series at {path} is named '{series.name}', but the run was fitted on '{fitted}'; "
                         f"pass the series the run was fitted on (bayes-sst {command} RUN --series SERIES)")
    return series


def run_prepared(tree, series=None) -> list[PreparedTest]:
    """Re-prepare the run's series exactly as the fit did, in the run's test order.

    `series` may be given (a Series); otherwise it is read from the path the run recorded
    (run_series).
    """
    from bayes_sst.signals import prepare_series

    if series is None:
        series = run_series(tree)
    series = series.without(run_left_out(tree))
    prepared = {t.id: t for t in prepare_series(series, run_signal_options(tree))}
    wanted = [str(t) for t in tree["posterior"]["test"].values]
    missing = [t for t in wanted if t not in prepared]
    if missing:
        raise ValueError(f"series {series.name!r} lacks the run's tests {missing[:5]}")
    return [prepared[t] for t in wanted]


@dataclass(frozen=True)
class TestPredictive:
    """Posterior predictive of one test at its kept samples (all arrays over the test's samples)."""

    __test__ = False

    test_id: str
    t: np.ndarray
    u: np.ndarray
    v: np.ndarray
    observed: np.ndarray  # measured force after the low-pass, N
    keep: np.ndarray  # samples that enter the likelihood
    mean: np.ndarray  # (draws, n) model force without residual, N
    replicated: np.ndarray  # (draws, n) model force plus an AR(1) residual draw, N


def _ar1_paths(phi, sigma, n, rng):
    """(draws, n) stationary AR(1) paths with coefficient phi and innovation sd sigma per draw."""
    draws = len(phi)
    w = rng.standard_normal((draws, n)) * sigma[:, None]
    e = np.empty((draws, n))
    e[:, 0] = w[:, 0] / np.sqrt(np.maximum(1.0 - phi**2, 1e-6))
    for t in range(1, n):
        e[:, t] = phi * e[:, t - 1] + w[:, t]
    return e


def posterior_predictive(tree, prepared: list[PreparedTest], *, n_draws: int = 200, seed: int = 0):
    """TestPredictive for every test, from n_draws posterior draws picked evenly over the chains."""
    rng = np.random.default_rng(seed)
    # the model's own alpha, the one each draw's test coefficients were drawn with (a widened
    # run keeps it in model_posterior; bayes_sst.inference._widening)
    alpha = flat_model_draws(tree, "alpha")
    total = len(alpha)
    pick = np.linspace(0, total - 1, min(n_draws, total)).round().astype(int)
    theta = np.stack([flat_model_draws(tree, f"{name}_test") for name in COEFFICIENTS], axis=-1)[pick]  # (d, J, 4)
    phi = flat_model_draws(tree, "phi")[pick]
    sigma = flat_model_draws(tree, "sigma")[pick]
    alpha = alpha[pick]
    # a fit with the exponent varying between tests (fit --per-test-alpha) has each test's own
    exponents = flat_model_draws(tree, "alpha_test")[pick] if "alpha_test" in tree["posterior"] else None
    out = []
    for j, test in enumerate(prepared):
        test_alpha = alpha if exponents is None else exponents[:, j]
        # one filtering pass for all draws' alphas: the damping column is the only one that moves
        damping = test.regressor(damping_columns(test_alpha))[: len(test_alpha)]  # (d, n)
        th = theta[:, j]
        mean = (
            test.payload_kg * test.a
            + th[:, 0:1] * test.a
            + th[:, 1:2] * test.u
            + th[:, 2:3] * damping
            + th[:, 3:4] * test.friction_sign
        )
        noise = _ar1_paths(phi[:, j], sigma[:, j], len(test.index), rng)
        out.append(
            TestPredictive(
                test_id=test.id, t=test.t, u=test.u, v=test.v, observed=test.F, keep=test.keep,
                mean=mean, replicated=mean + noise,
            )
        )
    return out
