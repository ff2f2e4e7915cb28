"""Sampler health: every check a reviewer needs before reading any number, with a verdict.

Each check is a Check(name, value, limit, ok, message); `message` is a plain-language
sentence used as the warning at the top of the report when the check fails. Limits:

* R-hat (rank-normalised split R-hat, ArviZ) <= 1.01 for the population values and the
  between-test spreads; <= 1.1 for the per-test noise parameters (nuisances, as in the
  fit's own summary);
* bulk ESS >= 400 for the population values and spreads, tail ESS >= 400 for the population
  values (bulk ESS >= 20 for the nuisances);
* no divergent transitions;
* E-BFMI >= 0.3 in every chain, E-BFMI = sum (E_n - E_(n-1))^2 / sum (E_n - mean E)^2;
* at most 1 % of the transitions stopped at the maximum tree depth (as the fit's summary:
  beyond that the sampler explores too slowly for R-hat and ESS to be read at face value);
* PSIS-LOO Pareto k of the measured points (see _checks.point_loo): at most 5 % of the
  points above 0.7, the limit beyond which importance sampling is unreliable. A few such
  points are normal in short tests (40-odd points each, so every point moves its test's
  coefficients); many mean outliers or a missing effect, and an unreliable LOO-PIT.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from bayes_sst.inference._summary import (
    ESS_LIMIT,
    NUISANCE_ESS_LIMIT,
    NUISANCE_RHAT_LIMIT,
    POPULATION,
    RHAT_LIMIT,
    SATURATED_SHARE,
)

BFMI_LIMIT = 0.3
PARETO_K_LIMIT = 0.7
PARETO_K_SHARE = 0.05


@dataclass(frozen=True)
class Check:
    """One health check: the worst value found, the limit, and what a failure means."""

    name: str
    value: float
    limit: float
    ok: bool
    message: str

    def to_json(self) -> dict:
        out = asdict(self)
        out["value"] = float(self.value) if np.isfinite(self.value) else None
        return out


def _worst(dataset, reduce) -> tuple[float, str]:
    """The worst value over all variables and coordinates of an ArviZ result, and where."""
    best_value, best_where = None, ""
    for name, da in dataset.data_vars.items():
        values = np.asarray(da.values, dtype=float).ravel()
        if values.size == 0 or not np.isfinite(values).any():
            continue
        i = int(reduce(np.where(np.isfinite(values), values, np.nan)))
        value = float(values[i])
        where = name
        if da.ndim:
            coords = np.unravel_index(i, da.shape)
            labels = [str(da[dim].values[c]) if dim in da.coords else str(c) for dim, c in zip(da.dims, coords)]
            where = f"{name}[{', '.join(labels)}]"
        if best_value is None or (value > best_value if reduce is np.nanargmax else value < best_value):
            best_value, best_where = value, where
    return (float("nan") if best_value is None else best_value), best_where


def sampler_checks(tree) -> list[Check]:
    """R-hat, bulk and tail ESS, divergences, E-BFMI and tree depth of a run's DataTree."""
    from arviz_stats import bfmi, ess, rhat

    population = list(POPULATION) + ["between_test_sd"]
    nuisance = ["phi", "sigma"]
    stats = tree["sample_stats"].to_dataset()
    n_draws = int(stats.sizes["chain"] * stats.sizes["draw"])
    checks = []
    # a coefficient shared by all tests (--shared) has a spread of exactly
    # 0 in every draw: no R-hat or ESS to compute, so it is left out of these checks
    spreads = tree["posterior"]["between_test_sd"]
    varying = [c for c in spreads["coefficient"].values
               if float(spreads.sel(coefficient=c).std()) > 0.0]
    if len(varying) < spreads.sizes["coefficient"]:
        tree = tree.copy()
        posterior = tree["posterior"].to_dataset()
        tree["posterior"] = posterior.assign(between_test_sd=posterior["between_test_sd"].sel(coefficient=varying))

    value, where = _worst(rhat(tree, var_names=population), np.nanargmax)
    checks.append(Check("R-hat (population values)", value, RHAT_LIMIT, value <= RHAT_LIMIT,
                        f"R-hat of {where} is {value:.3f} (limit {RHAT_LIMIT}): the chains disagree, "
                        "so the posterior is not yet found; do not use these numbers, run more warm-up and draws."))
    # bulk ESS over the spreads too; tail ESS (interval ends) for the reported values, as
    # the fit's own summary does
    for method, names in (("bulk", population), ("tail", list(POPULATION))):
        value, where = _worst(ess(tree, var_names=names, method=method), np.nanargmin)
        checks.append(Check(f"{method} ESS (population values)", value, ESS_LIMIT, value >= ESS_LIMIT,
                            f"{method} effective sample size of {where} is {value:.0f} (needs {ESS_LIMIT}): "
                            f"too few independent draws for reliable {'means' if method == 'bulk' else 'intervals'}; "
                            "draw more samples."))
    value, where = _worst(rhat(tree, var_names=nuisance), np.nanargmax)
    checks.append(Check("R-hat (per-test noise)", value, NUISANCE_RHAT_LIMIT, value <= NUISANCE_RHAT_LIMIT,
                        f"R-hat of the per-test noise parameter {where} is {value:.3f} "
                        f"(limit {NUISANCE_RHAT_LIMIT}): chains disagree on that test's noise; run longer."))
    value, where = _worst(ess(tree, var_names=nuisance, method="bulk"), np.nanargmin)
    checks.append(Check("bulk ESS (per-test noise)", value, NUISANCE_ESS_LIMIT, value >= NUISANCE_ESS_LIMIT,
                        f"bulk ESS of the per-test noise parameter {where} is {value:.0f} "
                        f"(needs {NUISANCE_ESS_LIMIT}): draw more samples."))

    divergent = int(np.asarray(stats["diverging"].values).sum())
    checks.append(Check("divergent transitions", divergent, 0, divergent == 0,
                        f"{divergent} of {n_draws} transitions diverged: the sampler missed part of the "
                        "posterior and the intervals may be biased; rerun with more warm-up."))
    e_bfmi = np.asarray(bfmi(tree)["energy"].values, dtype=float).ravel()
    low = float(e_bfmi.min())
    checks.append(Check("E-BFMI (lowest chain)", low, BFMI_LIMIT, low >= BFMI_LIMIT,
                        f"E-BFMI of a chain is {low:.2f} (needs {BFMI_LIMIT}): momentum resampling explores "
                        "the energy poorly, so tails may be missed; the model may need reparametrising."))
    saturated = int(np.asarray(stats["reached_max_treedepth"].values).sum()) if "reached_max_treedepth" in stats else 0
    limit = SATURATED_SHARE * n_draws
    checks.append(Check("maximum tree depth reached", saturated, limit, saturated <= limit,
                        f"{saturated} of {n_draws} transitions stopped at the maximum tree depth: "
                        "sampling was cut short and is inefficient; the draws may not explore well."))
    return checks


def loo_check(pareto_k: np.ndarray, labels: list[str]) -> Check:
    """Pareto k of the point-wise PSIS-LOO: fails when over 5 % of the points exceed 0.7."""
    pareto_k = np.asarray(pareto_k, dtype=float)
    bad = pareto_k > PARETO_K_LIMIT
    share = float(bad.mean()) if len(pareto_k) else 0.0
    worst = [labels[i] for i in np.argsort(-pareto_k)[: min(5, int(bad.sum()))]]
    return Check(
        "PSIS-LOO Pareto k > 0.7 (share of points)", share, PARETO_K_SHARE, share <= PARETO_K_SHARE,
        f"{int(bad.sum())} of {len(pareto_k)} measured points ({100 * share:.1f} %) have Pareto k above "
        f"{PARETO_K_LIMIT} (worst: {', '.join(worst)}): each of them alone moves the posterior a lot, so "
        "leave-one-out and LOO-PIT are unreliable there; look at those points for outliers or a missing effect.",
    )
