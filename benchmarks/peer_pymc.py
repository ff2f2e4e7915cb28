"""Peer implementation of the bayes_sst force model in PyMC, sampled with nutpie.

The same model, the same priors and the same data as bayes_sst.inference.fit, written out
the plain way instead of collapsed: every test coefficient theta_j is a sampled parameter
(non-centred), the AR(1) likelihood runs over every consecutive pair of kept samples, and
the damping regressor filter(|v|^alpha sign v) is interpolated in alpha per sample.

Scaled units exactly as in bayes_sst.inference._statistics.lagged_moments: the response is
y = (F - payload*a) / force_scale (force_scale = RMS of F - payload*a over kept samples),
the regressors are x_k * centre_k / force_scale, so a coefficient theta_k in SI units is
centre_k * theta_k(scaled).

    mu_k      ~ Normal(1, 1)                   k in Me, Ke, Ce, Fmu (= N(centre, centre) in SI)
    rho_k     ~ LogNormal(log 0.03, 1)         between-test sd, scaled units
    z_jk      ~ Normal(0, 1);  theta_jk = mu_k + rho_k z_jk
    alpha     ~ TruncatedNormal(0.75, 0.5, 0.05, 1.95)
    phi_j     ~ Uniform(-0.999, 0.999)
    sigma_j   ~ LogNormal(log 0.05, 2)
    for consecutive kept pairs (t-1, t) of test j, r_t = y_t - x_t(alpha).theta_j:
        r_t - phi_j r_(t-1) ~ Normal(0, sigma_j^2)

The damping column is tabulated on the package's alpha grid (bayes_sst.inference._statistics,
0.05 to 1.95) together with its exact alpha-derivative filter(|v|^alpha log|v| sign v), both
through PreparedTest.regressor (the filter the force saw), and interpolated between nodes by
cubic Hermite polynomials, as the package's likelihood interpolates that column, so alpha has
a smooth gradient. (The package's likelihood also floors the noise sd at 1e-4 of the RMS
force; at the benchmark's noise that changes the noise variance by about 0.1 %.)

Run alone (20-test sst-paper virtual table, spread 0.02):

    PYTHONPATH=. .venv/bin/python benchmarks/peer_pymc.py --tests 20

From another script: build_peer_data(series) -> PeerData; run_peer(series, ...) -> dict.
Needs the optional extra `peer` (pymc, nutpie).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from dataclasses import dataclass

import numpy as np

from bayes_sst.inference._priors import Priors, make_priors
from bayes_sst.inference._statistics import ALPHA_MAX, ALPHA_MIN, ALPHA_STEP, COEFFICIENTS, damping_columns
from bayes_sst.signals import SignalOptions, prepare_series

POPULATION = ("Me", "Ke", "Ce", "alpha", "Fmu")
PHI_BOUND = 0.999  # as bayes_sst.inference._model.PHI_BOUND


@dataclass
class PeerData:
    """Per consecutive kept pair (t-1, t): response, regressors and damping tables."""

    test_ids: tuple[str, ...]
    pair_test: np.ndarray  # (P,) test index of each pair
    n_pairs: np.ndarray  # (J,)
    y_now: np.ndarray  # (P,)
    y_before: np.ndarray
    fixed_now: np.ndarray  # (P, 3): a, u, sign columns (scaled)
    fixed_before: np.ndarray
    damping_now: np.ndarray  # (G, P) filter(|v|^alpha sign v) * centre_Ce / force_scale
    damping_before: np.ndarray
    slope_now: np.ndarray  # (G, P) d/dalpha of the above
    slope_before: np.ndarray
    alpha_grid: np.ndarray
    centres: np.ndarray  # (4,) coefficient scale: SI = centre * scaled
    force_scale: float
    n_samples: int  # decimated samples of all tests (kept or not)


def build_peer_data(series, signals: SignalOptions = SignalOptions(), priors: Priors | None = None,
                    prepared=None) -> PeerData:
    """The pairs the AR(1) likelihood runs over, from prepare_series(series, signals)."""
    prepared = prepare_series(series, signals) if prepared is None else prepared
    priors = priors or make_priors("generic")
    centres = priors.centre_vector()
    grid = np.arange(ALPHA_MIN, ALPHA_MAX + 0.5 * ALPHA_STEP, ALPHA_STEP)
    g = len(grid)
    force_scale = float(
        np.sqrt(np.mean(np.concatenate([(t.F - t.payload_kg * t.a)[t.keep] ** 2 for t in prepared])))
    )
    parts = {k: [] for k in ("test", "y_now", "y_before", "fx_now", "fx_before", "d_now", "d_before",
                             "s_now", "s_before")}
    n_pairs = []
    for j, test in enumerate(prepared):
        y = (test.F - test.payload_kg * test.a) / force_scale
        both = test.regressor(damping_columns(grid)) * centres[2] / force_scale  # (2G, n)
        fixed = np.stack([
            test.a * centres[0] / force_scale,
            test.u * centres[1] / force_scale,
            test.friction_sign * centres[3] / force_scale,
        ], axis=1)  # (n, 3)
        now = np.flatnonzero(test.keep[1:] & test.keep[:-1]) + 1
        before = now - 1
        n_pairs.append(len(now))
        parts["test"].append(np.full(len(now), j, dtype=np.int64))
        parts["y_now"].append(y[now])
        parts["y_before"].append(y[before])
        parts["fx_now"].append(fixed[now])
        parts["fx_before"].append(fixed[before])
        parts["d_now"].append(both[:g, now])
        parts["d_before"].append(both[:g, before])
        parts["s_now"].append(both[g:, now])
        parts["s_before"].append(both[g:, before])
    cat = {k: np.concatenate(v, axis=-1 if k.startswith(("d_", "s_")) else 0) for k, v in parts.items()}
    return PeerData(
        test_ids=tuple(t.id for t in prepared),
        pair_test=cat["test"],
        n_pairs=np.asarray(n_pairs, dtype=float),
        y_now=cat["y_now"], y_before=cat["y_before"],
        fixed_now=cat["fx_now"], fixed_before=cat["fx_before"],
        damping_now=cat["d_now"], damping_before=cat["d_before"],
        slope_now=cat["s_now"], slope_before=cat["s_before"],
        alpha_grid=grid, centres=centres, force_scale=force_scale,
        n_samples=int(sum(len(t.index) for t in prepared)),
    )


def build_model(data: PeerData, priors: Priors | None = None, *, centred: bool = False):
    """The PyMC model of the module docstring (scaled units)."""
    import pymc as pm
    import pytensor.tensor as pt

    priors = priors or make_priors("generic")
    scale = data.centres  # the moment scale of lagged_moments is the prior centre vector
    prior_mean = priors.centre_vector() / scale
    prior_sd = priors.relative_sd * priors.centre_vector() / scale
    coords = {"coefficient": list(COEFFICIENTS), "test": list(data.test_ids)}
    a0, step, n_grid = float(data.alpha_grid[0]), float(data.alpha_grid[1] - data.alpha_grid[0]), len(data.alpha_grid)
    with pm.Model(coords=coords) as model:
        pair_test = pm.Data("pair_test", data.pair_test)
        y_now = pm.Data("y_now", data.y_now)
        y_before = pm.Data("y_before", data.y_before)
        fx_now = pm.Data("fixed_now", data.fixed_now)
        fx_before = pm.Data("fixed_before", data.fixed_before)
        d_now = pm.Data("damping_now", data.damping_now)
        d_before = pm.Data("damping_before", data.damping_before)
        s_now = pm.Data("slope_now", data.slope_now)
        s_before = pm.Data("slope_before", data.slope_before)
        n_pairs = pm.Data("n_pairs", data.n_pairs)

        alpha = pm.TruncatedNormal("alpha", mu=priors.alpha_mean, sigma=priors.alpha_sd,
                                   lower=priors.alpha_low, upper=priors.alpha_high)
        mu = pm.Normal("mu", mu=prior_mean, sigma=prior_sd, dims="coefficient")
        rho = pm.LogNormal("rho", mu=np.log(priors.spread_median), sigma=priors.spread_log_sd, dims="coefficient")
        if centred:
            theta = pm.Normal("theta", mu=mu, sigma=rho, dims=("test", "coefficient"))
        else:
            z = pm.Normal("z", 0.0, 1.0, dims=("test", "coefficient"))
            theta = pm.Deterministic("theta", mu + rho * z, dims=("test", "coefficient"))
        phi = pm.Uniform("phi", -PHI_BOUND, PHI_BOUND, dims="test")
        sigma = pm.LogNormal("sigma", mu=math.log(priors.noise_scale), sigma=priors.noise_log_sd, dims="test")

        # cubic Hermite interpolation of the damping column in alpha
        position = (alpha - a0) / step
        g = pt.cast(pt.clip(pt.floor(position), 0, n_grid - 2), "int64")
        s = position - g
        s2, s3 = s * s, s * s * s
        h00, h10, h01, h11 = 2 * s3 - 3 * s2 + 1, s3 - 2 * s2 + s, -2 * s3 + 3 * s2, s3 - s2

        def damping(table, slopes):
            return h00 * table[g] + h10 * step * slopes[g] + h01 * table[g + 1] + h11 * step * slopes[g + 1]

        th = theta[pair_test]  # (P, 4)
        r_now = y_now - pt.sum(fx_now * th[:, [0, 1, 3]], axis=1) - damping(d_now, s_now) * th[:, 2]
        r_before = y_before - pt.sum(fx_before * th[:, [0, 1, 3]], axis=1) - damping(d_before, s_before) * th[:, 2]
        innovation = (r_now - phi[pair_test] * r_before) / sigma[pair_test]
        pm.Potential(
            "force",
            -0.5 * pt.sum(innovation**2) - pt.sum(n_pairs * pt.log(sigma)) - 0.5 * np.log(2 * np.pi) * data.pair_test.size,
        )
    return model


def summarize_peer(trace, data: PeerData, seconds_sampling: float) -> dict:
    """Population parameters in SI units, bulk ESS, R-hat, divergences."""
    import xarray as xr
    from arviz_stats import ess, mcse, rhat

    post = trace["posterior"].to_dataset()
    si = {}
    for k, name in enumerate(COEFFICIENTS):
        si[name] = post["mu"].isel(coefficient=k, drop=True) * data.centres[k]
    si["alpha"] = post["alpha"]
    ds = xr.Dataset({n: si[n] for n in POPULATION})
    tree = xr.DataTree.from_dict({"posterior": ds})
    e = ess(tree, method="bulk")
    r = rhat(tree)
    m = mcse(tree)
    params = {}
    for name in POPULATION:
        x = ds[name].values.ravel()
        params[name] = {"mean": float(x.mean()), "sd": float(x.std(ddof=1)), "ess_bulk": float(e[name]),
                        "r_hat": float(r[name]), "mcse_mean": float(m[name])}
    between = (post["rho"] * xr.DataArray(data.centres, dims="coefficient", coords={"coefficient": list(COEFFICIENTS)}))
    stats = trace["sample_stats"].to_dataset() if "sample_stats" in trace.children else None
    divergences = int(stats["diverging"].values.sum()) if stats is not None and "diverging" in stats else -1
    steps = float(stats["n_steps"].values.mean()) if stats is not None and "n_steps" in stats else float("nan")
    min_ess = min(p["ess_bulk"] for p in params.values())
    return {
        "parameters": params,
        "between_test_sd_mean": {n: float(between.sel(coefficient=n).mean()) for n in COEFFICIENTS},
        "min_ess_bulk": min_ess,
        "max_r_hat": max(p["r_hat"] for p in params.values()),
        "divergences": divergences,
        "mean_leapfrog_steps": steps,
        "sampling_s": seconds_sampling,
        "ess_per_s": min_ess / seconds_sampling if seconds_sampling > 0 else float("nan"),
        "n_draws": int(post.sizes["chain"] * post.sizes["draw"]),
    }


def run_peer(series, *, runs=((500, 500), (1000, 1000)), chains: int = 4, cores: int | None = None,
             seed: int = 0, centred: bool = False, budget_s: float | None = None, checkpoint=None,
             progress=print) -> dict:
    """Prepare, compile (numba) and sample the peer model once per (tune, draws) in `runs`.

    Returns timings (signals, model build, compile), and per run the sampling time and the
    summary of summarize_peer. A run whose time, extrapolated from the previous one by the
    number of iterations, exceeds budget_s is skipped (and says so). checkpoint(dict) is
    called after every run, so a caller that stops the process keeps what finished. The caller
    should start from a fresh process (and a fresh PyTensor compiledir) for a cold compile time.
    """
    import nutpie

    cores = cores or os.cpu_count() or 1
    out = {"chains": chains, "cores": cores, "centred": centred, "backend": "numba", "runs": []}
    start = time.perf_counter()
    data = build_peer_data(series)
    out["signals_s"] = time.perf_counter() - start
    out["n_tests"] = len(data.test_ids)
    out["n_pairs"] = int(data.pair_test.size)
    start = time.perf_counter()
    model = build_model(data, centred=centred)
    out["model_build_s"] = time.perf_counter() - start
    start = time.perf_counter()
    compiled = nutpie.compile_pymc_model(model, backend="numba")
    out["compile_s"] = time.perf_counter() - start
    progress(f"peer: {out['n_tests']} tests, {out['n_pairs']} pairs; pymc model {out['model_build_s']:.1f} s, "
             f"nutpie/numba compile {out['compile_s']:.1f} s")
    if checkpoint:
        checkpoint(out)
    last = None  # (iterations, seconds) of the previous run
    for tune, draws in runs:
        if budget_s is not None and last is not None:
            predicted = last[1] * (tune + draws) / last[0]
            if predicted > budget_s:
                out["runs"].append({"tune": tune, "draws": draws, "n_draws": chains * draws,
                                    "skipped": f"predicted {predicted:.0f} s > budget {budget_s:.0f} s"})
                progress(f"peer: {chains} x ({tune}+{draws}) skipped, predicted {predicted:.0f} s")
                continue
        start = time.perf_counter()
        trace = nutpie.sample(compiled, draws=draws, tune=tune, chains=chains, cores=cores, seed=seed,
                              progress_bar=False)
        seconds = time.perf_counter() - start
        last = (tune + draws, seconds)
        summary = summarize_peer(trace, data, seconds)
        summary.update({"tune": tune, "draws": draws})
        out["runs"].append(summary)
        progress(f"peer: {chains} x ({tune}+{draws}) sampled in {seconds:.1f} s, min bulk ESS "
                 f"{summary['min_ess_bulk']:.0f}, max R-hat {summary['max_r_hat']:.3f}, "
                 f"{summary['divergences']} divergences")
        if checkpoint:
            checkpoint(out)
    return out


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tests", type=int, default=20, choices=(20, 200))
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--centred", action="store_true", help="centred theta_j instead of non-centred")
    parser.add_argument("--tune", type=int, nargs="+", default=[500, 1000])
    parser.add_argument("--draws", type=int, nargs="+", default=[500, 1000])
    args = parser.parse_args()
    from bench_fit import make_series  # same folder

    series = make_series(args.tests, args.seed)
    result = run_peer(series, runs=list(zip(args.tune, args.draws)), centred=args.centred,
                      progress=lambda message: print(message, file=sys.stderr, flush=True))
    print(json.dumps(result, indent=1))


if __name__ == "__main__":
    main()
