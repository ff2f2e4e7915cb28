"""Turning sampler output into a labelled ArviZ DataTree in SI units."""

from __future__ import annotations

import json
from dataclasses import asdict

import numpy as np
import xarray as xr

from bayes_sst.inference._statistics import COEFFICIENTS


def _padded(arrays, fill=np.nan):
    width = max(len(a) for a in arrays)
    out = np.full((len(arrays), width), fill, dtype=float)
    for i, a in enumerate(arrays):
        out[i, : len(a)] = a
    return out


def build_tree(seed, samples, extra, scaled, moments, prepared, priors, settings, series, signals=None):
    """posterior, sample_stats, log_likelihood, observed_data, constant_data as one DataTree."""
    from bayes_sst.inference._collapsed import draw_coefficients, friction_factors, moment_table
    from bayes_sst.inference._priors import ALPHA_SPREAD_SITE, ALPHA_SPREAD_VARIABLE, GAIN_SITE

    chains, draws = samples["alpha"].shape
    flat = {name: np.reshape(np.asarray(value), (chains * draws,) + value.shape[2:]) for name, value in samples.items()}
    n_draws, n_tests = chains * draws, moments.n_tests
    # numpy, in blocks of draws: the same equations as the sampler's, without an XLA compilation
    host_table = moment_table(moments, np)
    with_gain = GAIN_SITE in samples
    if not with_gain:
        host_table = host_table._replace(load_share=None)
    gain = flat[GAIN_SITE] if with_gain else np.ones(n_draws)
    with_deviation = ALPHA_SPREAD_SITE in samples
    deviation = flat[ALPHA_SPREAD_SITE] * scaled.deviation_scale if with_deviation else None
    prior_mean, prior_sd = np.asarray(scaled.mean), np.asarray(scaled.sd)
    spread = np.asarray(samples["spread"]) * np.asarray(scaled.varying)  # a shared coefficient's spread is 0
    flat["spread"] = np.reshape(spread, (chains * draws, 4))
    rng = np.random.default_rng(seed)
    normal_mu = rng.standard_normal((n_draws, 4))
    normal_theta = rng.standard_normal((n_draws, n_tests, 4))
    ignored = priors.ignored_spread_vector()
    # drawn after the others, so that a fit without an ignored spread keeps its draws
    normal_ignored = rng.standard_normal((4, n_draws, n_tests)) if ignored is not None else None
    # drawn last, so that a fit without the exponent's spread keeps its draws
    normal_deviation = rng.standard_normal((n_draws, n_tests)) if with_deviation else None
    exponents = np.empty((n_draws, n_tests))
    mu = np.empty((n_draws, 4))
    theta = np.empty((n_draws, n_tests, 4))
    per_test = np.empty((n_draws, n_tests))
    # blocks of about 20,000 (draw, test) pairs: a few MB of intermediates each
    block = max(1, 20_000 // max(n_tests, 1))
    for lo in range(0, n_draws, block):
        part = slice(lo, min(lo + block, n_draws))
        drawn = draw_coefficients(
            normal_mu[part].T, normal_theta[part], host_table, flat["alpha"][part], flat["spread"][part].T,
            flat["phi"][part], flat["sigma"][part], prior_mean, prior_sd, xp=np, gain=gain[part],
            ignored_spread=ignored, normal_ignored=None if ignored is None else normal_ignored[:, part],
            deviation=None if deviation is None else deviation[part],
            normal_deviation=None if normal_deviation is None else normal_deviation[part],
        )
        mu[part], theta[part], per_test[part] = drawn.mu, drawn.theta, drawn.log_likelihood
        if with_deviation:
            exponents[part] = drawn.exponents
    if with_gain:
        # each test's Coulomb coefficient as that of its column friction_load*filter(sign v),
        # the column the report, the predictive checks and the diagnosis rebuild
        theta[:, :, 3] *= friction_factors(host_table, gain, np)
    scale = moments.coefficient_scale
    mu = mu * scale
    theta = theta * scale
    log_lik = per_test - moments.n_pairs * np.log(moments.force_scale)

    def shaped(x):
        return np.reshape(x, (chains, draws) + x.shape[1:])

    test_ids = list(moments.test_ids)
    coords = {"chain": np.arange(chains), "draw": np.arange(draws), "test": test_ids, "coefficient": list(COEFFICIENTS)}
    posterior = {}
    for k, name in enumerate(COEFFICIENTS):
        posterior[name] = (("chain", "draw"), shaped(mu[:, k]))
    posterior["alpha"] = (("chain", "draw"), np.asarray(samples["alpha"]))
    if with_gain:
        posterior[GAIN_SITE] = (("chain", "draw"), np.asarray(samples[GAIN_SITE]))
    if with_deviation:
        posterior[ALPHA_SPREAD_VARIABLE] = (("chain", "draw"), np.asarray(samples[ALPHA_SPREAD_SITE]))
        posterior["alpha_test"] = (("chain", "draw", "test"), shaped(exponents))
    posterior["between_test_sd"] = (
        ("chain", "draw", "coefficient"),
        spread * scale,
    )
    for k, name in enumerate(COEFFICIENTS):
        posterior[f"{name}_test"] = (("chain", "draw", "test"), shaped(theta[:, :, k]))
    posterior["phi"] = (("chain", "draw", "test"), np.asarray(samples["phi"]))
    posterior["sigma"] = (("chain", "draw", "test"), np.asarray(samples["sigma"]) * moments.force_scale)
    units = {
        "Me": "kg", "Ke": "N/m", "Ce": "N/(m/s)^alpha", "Fmu": "N", "alpha": "1",
        "between_test_sd": "SI units of each coefficient", "sigma": "N", "phi": "1", ALPHA_SPREAD_VARIABLE: "1",
        "alpha_test": "1",
        GAIN_SITE: "1",
    }
    post_ds = xr.Dataset(posterior, coords={k: coords[k] for k in ("chain", "draw", "test", "coefficient")})
    for name, unit in units.items():
        if name in post_ds:
            post_ds[name].attrs["units"] = unit
    if with_deviation:
        post_ds[ALPHA_SPREAD_VARIABLE].attrs["meaning"] = (
            "between-test sd of the damping exponent: test j's damping is Ce_j |v|^(alpha + delta_j) sign v "
            "with delta_j ~ N(0, sd^2), to first order in delta_j, each delta_j integrated out")
    if with_gain:
        post_ds[GAIN_SITE].attrs["meaning"] = (
            "share of the payload's friction increase predicted by the table description that is real: "
            "test j's friction is Fmu*(1 + kappa*(friction_load_j - 1)); Fmu_test is the coefficient "
            "of friction_load_j*filter(sign v)")

    diverging = np.asarray(extra["diverging"])
    n_steps = np.asarray(extra["num_steps"])
    stats_ds = xr.Dataset(
        {
            "diverging": (("chain", "draw"), diverging.astype(bool)),
            "n_steps": (("chain", "draw"), n_steps.astype(int)),
            "tree_depth": (("chain", "draw"), np.ceil(np.log2(n_steps + 1)).astype(int)),
            "reached_max_treedepth": (("chain", "draw"), n_steps >= 2**settings.max_tree_depth - 1),
            "acceptance_rate": (("chain", "draw"), np.asarray(extra["accept_prob"])),
            "energy": (("chain", "draw"), np.asarray(extra["energy"])),
            "lp": (("chain", "draw"), -np.asarray(extra["potential_energy"])),
            "step_size": (("chain", "draw"), np.asarray(extra["adapt_state.step_size"])),
        },
        coords={"chain": coords["chain"], "draw": coords["draw"]},
    )
    loglik_ds = xr.Dataset(
        {"F": (("chain", "draw", "test"), shaped(log_lik))},
        coords={"chain": coords["chain"], "draw": coords["draw"], "test": test_ids},
    )
    loglik_ds["F"].attrs["meaning"] = "log p(force of test | population values), test coefficients integrated out"
    observed = xr.Dataset(
        {"F": (("test", "sample"), _padded([t.F for t in prepared]))},
        coords={"test": test_ids},
    )
    observed["F"].attrs["meaning"] = ("force after the reversal weight and the zero-phase low-pass, at the kept "
                                      "(decimated) samples, less its test's free constant (project_out), N")
    constant = xr.Dataset(
        {
            "t": (("test", "sample"), _padded([t.t for t in prepared])),
            "u": (("test", "sample"), _padded([t.u for t in prepared])),
            "v": (("test", "sample"), _padded([t.v for t in prepared])),
            "a": (("test", "sample"), _padded([t.a for t in prepared])),
            "keep": (("test", "sample"), _padded([t.keep.astype(float) for t in prepared], fill=0.0)),
            "frequency_hz": (("test",), np.array([t.frequency_hz for t in prepared])),
            "amplitude_m": (("test",), np.array([t.amplitude_m for t in prepared])),
            "payload_kg": (("test",), np.array([t.payload_kg for t in prepared])),
            "friction_load": (("test",), np.array([t.friction_load for t in prepared])),
            "kind": (("test",), np.array([t.kind for t in prepared])),
            "cutoff_hz": (("test",), np.array([t.cutoff_hz for t in prepared])),
            "n_cycles": (("test",), np.array([t.window.n_cycles for t in prepared])),
            "recorded_samples": (("test",), np.array([len(t.velocity_full) for t in prepared])),
            "steady_samples": (("test",), np.array([t.window.stop - t.window.start for t in prepared])),
        },
        coords={"test": test_ids},
    )
    from bayes_sst import __version__

    attrs = {
        "series": series.name,
        "bayes_sst_version": __version__,
        "sampler": json.dumps(asdict(settings)),
        "priors": json.dumps(priors.describe()),
        "model": "hierarchical power-law damping + Coulomb friction, AR(1) residuals, coefficients collapsed",
        # where the series lay and how its signals were prepared: enough to rebuild the
        # exact regressors (report, diagnosis, design) from the run folder alone
        "series_path": str(series.path.resolve()) if series.path is not None else "",
        "signal_options": json.dumps(asdict(signals)) if signals is not None else "",
        # tests of the manifest left out of the fit (load_series(..., exclude=...)): the run's
        # series is read back without them
        "left_out": json.dumps(list(series.left_out)),
    }
    tree = xr.DataTree.from_dict(
        {
            "posterior": post_ds,
            "sample_stats": stats_ds,
            "log_likelihood": loglik_ds,
            "observed_data": observed,
            "constant_data": constant,
        }
    )
    tree.attrs.update(attrs)
    return tree
