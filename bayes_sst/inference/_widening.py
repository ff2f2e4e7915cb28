"""Widening the population intervals where the tests disagree more than the model allows.

The model's posterior is honest when its assumptions hold: tests that scatter around the
population values by the between-test spread, AR(1) residuals, the force equation. Where a
table breaks them in a way each test feels a little differently (a friction law that is not
Coulomb plus power-law damping, sticking at the reversals under a servo loop, a coloured or
humming sensor), the posterior stays as narrow as if they held. The tests themselves show it:
leaving one out moves the estimate, and how far those moves scatter is a second, model-free
reading of the estimate's uncertainty, the delete-one-test jackknife

    V_g = (J-1)/J * sum_j (g_(-j) - mean_j g_(-j))^2,

g_(-j) the estimate of g (Me, Ke, Ce, alpha, Fmu) from every test but j. Whole tests are left
out because samples within a test are correlated and the tests are the independent units.
Each g_(-j) is read at the posterior mode of the series without test j (alpha at the mode,
the coefficients at their conditional mean E[mu | hyperparameters], mu integrated out as in
the sampler): one L-BFGS search in numpy for the whole series from the sampler's most probable
draw, then one per left-out test from that mode, about 0.3-2 s for 10-40 tests. Beyond
MAX_GROUPS tests, G = MAX_GROUPS groups of tests are left out instead, so that the cost stays
that of MAX_GROUPS searches; the groups' sizes m_g may differ by one, and the delete-a-group
jackknife for unequal groups (Busing, Meijer and van der Leeden 1999) is used,

    h_g = J/m_g,  p_g = h_g g_all - (h_g - 1) g_(-g),  g_J = G g_all - sum_g (1 - m_g/J) g_(-g),
    V_g = (1/G) sum_g (p_g - g_J)^2 / (h_g - 1),

g_all the estimate from all tests; with one test per group it is the formula above.

The population draws of g are then stretched about their mean by

    f_g = min(MAX_WIDENING, max(1, sqrt(V_g / Var_post(g)))),

never narrowed: with 10-30 tests V_g is itself uncertain (about sqrt(2/(J-1)) relative). The
stretch is affine, so R-hat and the effective sample sizes are those of the model's draws,
which are kept in the tree's model_posterior group; the jackknife's estimates are the group
jackknife.

What it does (docs/measurements.md, 2026-11-30): the jackknife reads alpha and Fmu 1.15-1.8
times as uncertain as the posterior does (mean over series, by simulator), Me and Ke about as
uncertain. On the sixth simulator, where the posterior was too narrow (alpha and Fmu covered in
70 and 72.5 % of 40 series, z sd 1.4), the stretched intervals cover 85 and 82.5 %; on the
virtual table, where it was not (93 %), they cover 95 %. The jackknife is conservative where
the model holds: the price of not trusting the model further than the tests agree.
"""

from __future__ import annotations

import json
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # xarray is imported where it is used, to keep `import bayes_sst` light
    import xarray as xr

POPULATION = ("Me", "Ke", "Ce", "alpha", "Fmu")
# fewer tests than this: leaving one out changes the plan too much to read an uncertainty from
MIN_TESTS = 6
# a stretch beyond this is no longer a correction of the model's width but a sign that one test
# or a few disagree with the rest outright: capped, and the summary names the test
MAX_WIDENING = 3.0
QUANTITY = "quantity"
LEFT_OUT = "left_out"
# beyond this many tests the jackknife leaves out groups of tests: one search per group keeps
# its cost that of 40 tests (each search reads every remaining test's moments, so one per test
# would grow as J^2: 200 tests would take some 30 s)
MAX_GROUPS = 40


def _without_tests(table, left_out):
    """The MomentTable without the tests `left_out` (tests are the last axis of every per-test
    field)."""
    keep = np.ones(table.n_pairs.shape[0], dtype=bool)
    keep[list(left_out)] = False
    fields = {}
    for name in ("constant", "cross", "gram", "n_pairs"):
        fields[name] = np.asarray(getattr(table, name))[..., keep]
    if table.load_share is not None:
        fields["load_share"] = np.asarray(table.load_share)[keep]
    return table._replace(**fields), keep


def left_out_groups(n_tests: int, max_groups: int = MAX_GROUPS) -> list[list[int]]:
    """Which tests each jackknife estimate leaves out: one test at a time up to max_groups
    tests, beyond that max_groups groups taking every max_groups-th test (so that each group
    mixes the plan's kinds, frequencies and amplitudes as the series does)."""
    groups = min(n_tests, max_groups)
    return [list(range(g, n_tests, groups)) for g in range(groups)]


def mode_estimates(z: dict, table, priors) -> np.ndarray:
    """(Me, Ke, Ce, alpha, Fmu) in the table's scaled units at the unconstrained sites z (a
    posterior mode): alpha there, the coefficients at their conditional mean
    E[mu | hyperparameters] = Q^-1 r (bayes_sst.inference._collapsed)."""
    from bayes_sst.inference._collapsed import draw_coefficients
    from bayes_sst.inference._model import constrained_sites
    from bayes_sst.inference._priors import ALPHA_SPREAD_SITE, GAIN_SITE

    sites = constrained_sites(z, priors)
    deviation = None if priors.alpha_spread is None else sites[ALPHA_SPREAD_SITE] * priors.deviation_scale
    n_tests = table.n_pairs.shape[0]
    # zero deviates: the conditional mean of mu (and of each theta_j, unused)
    mu = draw_coefficients(np.zeros(4), np.zeros((n_tests, 4)), table, sites["alpha"],
                           np.asarray(sites["spread"]) * np.asarray(priors.varying), np.asarray(sites["phi"]),
                           np.asarray(sites["sigma"]), np.asarray(priors.mean), np.asarray(priors.sd), xp=np,
                           gain=sites.get(GAIN_SITE, 1.0), deviation=deviation).mu
    return np.array([mu[0], mu[1], mu[2], float(sites["alpha"]), mu[3]])


def mode_jackknife(z: dict, table, priors, scales: dict, groups, max_iterations: int = 200) -> np.ndarray:
    """(G, 5) mode_estimates of the series without each group of tests in turn, every search
    started from the whole series' mode z (the left-out tests' own sites removed)."""
    from bayes_sst.inference._model import posterior_mode

    out = np.empty((len(groups), 5))
    for g, left_out in enumerate(groups):
        table_g, keep = _without_tests(table, left_out)

        def kept(sites):
            return {name: (np.asarray(value)[keep] if name in ("phi", "sigma") else value)
                    for name, value in sites.items()}

        mode_g = posterior_mode(kept(z), table_g, priors, kept(scales), max_iterations=max_iterations)
        out[g] = mode_estimates(mode_g, table_g, priors)
    return out


def jackknife_modes(samples: dict, potential_energy, table, priors, scales: dict, coefficient_scale,
                    test_ids) -> xr.Dataset:
    """The jackknife group of a run: the estimates of (Me, Ke, Ce, alpha, Fmu) in SI units from
    all tests (all_tests) and without each test or group of tests (without_test, dims
    left_out x quantity; each left_out label joins its tests' ids with '+'), at the
    posterior modes found from the sampler's most probable draw (a search from the sampler's
    own start can end on a lesser mode that the chains left: on one sixth-simulator series it
    read alpha 0.586 where the chains sat at 0.533)."""
    import xarray as xr

    from bayes_sst.inference._model import posterior_mode, unconstrained_start

    potential = np.asarray(potential_energy).reshape(-1)
    best = int(np.argmin(np.where(np.isfinite(potential), potential, np.inf)))
    values = {name: np.asarray(value).reshape((-1,) + np.shape(value)[2:])[best] for name, value in samples.items()}
    z = posterior_mode(unconstrained_start(values, priors), table, priors, scales)
    si = np.append(np.asarray(coefficient_scale, dtype=float), 1.0)[[0, 1, 2, 4, 3]]
    groups = left_out_groups(len(test_ids))
    labels = ["+".join(str(test_ids[j]) for j in left_out) for left_out in groups]
    group = xr.Dataset(
        {"all_tests": ((QUANTITY,), mode_estimates(z, table, priors) * si),
         "without_test": ((LEFT_OUT, QUANTITY), mode_jackknife(z, table, priors, scales, groups) * si)},
        coords={QUANTITY: list(POPULATION), LEFT_OUT: labels},
    )
    group.attrs["meaning"] = ("posterior-mode estimates (SI) from all tests and with each test (beyond "
                              f"{MAX_GROUPS} tests, each group of tests) left out; their scatter sets the widening "
                              "of the population intervals (bayes_sst.inference._widening)")
    return group


def jackknife_variance(all_tests: np.ndarray, without: np.ndarray, sizes: np.ndarray) -> np.ndarray:
    """The delete-a-group jackknife variance (module docstring) of each column of `without`
    (G, P), the estimates without each group, groups of `sizes` (G,) tests, all_tests (P,)."""
    sizes = np.asarray(sizes, dtype=float)
    n_tests, n_groups = sizes.sum(), len(sizes)
    h = (n_tests / sizes)[:, None]
    pseudo = h * all_tests[None, :] - (h - 1.0) * without
    centre = n_groups * all_tests - np.sum((1.0 - sizes / n_tests)[:, None] * without, axis=0)
    return np.sum((pseudo - centre) ** 2 / (h - 1.0), axis=0) / n_groups


def jackknife_factors(jackknife, posterior) -> dict:
    """{name: {factor, ratio, shift_test, shift_sd}} for each population value: the stretch
    f_g, the ratio sqrt(V_g / Var_post(g)) it comes from, and the test (or group of tests)
    whose removal moves the estimate furthest, by how many posterior sds (signed, from the mean
    of the removals). A jackknife of fewer than MIN_TESTS removals stretches nothing.
    `posterior` holds the model's own draws."""
    without = np.asarray(jackknife["without_test"].transpose(LEFT_OUT, QUANTITY).values, dtype=float)
    all_tests = np.asarray(jackknife["all_tests"].sel({QUANTITY: list(POPULATION)}).values, dtype=float)
    labels = [str(t) for t in jackknife[LEFT_OUT].values]
    sizes = np.array([label.count("+") + 1 for label in labels])
    variance = jackknife_variance(all_tests, without, sizes)
    centred = without - without.mean(axis=0)
    out = {}
    for k, name in enumerate(POPULATION):
        sd = float(np.asarray(posterior[name].values).std(ddof=1))
        ratio = float(np.sqrt(variance[k]) / sd) if sd > 0 else 1.0
        factor = min(MAX_WIDENING, max(1.0, ratio)) if len(labels) >= MIN_TESTS else 1.0
        j = int(np.argmax(np.abs(centred[:, k])))
        out[name] = {"factor": factor, "ratio": ratio, "shift_test": labels[j],
                     "shift_sd": float(centred[j, k] / sd) if sd > 0 else 0.0}
    return out


def widen(tree):
    """The tree with its population draws stretched about their mean by jackknife_factors (read
    from its jackknife group); the model's own draws move to the group model_posterior, and the
    attribute 'widening' holds the factors as JSON. A tree without a jackknife group is returned
    as it is."""
    import xarray as xr

    if "jackknife" not in tree.children:
        return tree
    post = tree["posterior"].to_dataset()
    factors = jackknife_factors(tree["jackknife"], post)
    model = xr.Dataset({name: post[name] for name in POPULATION})
    model.attrs["meaning"] = ("the model's own population draws, before the widening by the tests' jackknife "
                              "(attribute 'widening' of the tree; bayes_sst.inference._widening)")
    bounds = _alpha_bounds(tree)
    stretched = {}
    for name in POPULATION:
        x = post[name]
        centre = x.mean()
        y = centre + factors[name]["factor"] * (x - centre)
        if name == "alpha" and bounds is not None:
            # the exponent's prior support: a stretch does not carry draws where the model has none
            y = y.clip(*bounds)
        stretched[name] = y.assign_attrs(x.attrs)
    tree["posterior"] = post.assign(stretched)
    tree["model_posterior"] = model
    tree.attrs["widening"] = json.dumps(factors)
    return tree


def _alpha_bounds(tree) -> tuple[float, float] | None:
    """The support of the exponent's prior, from the run's priors record."""
    priors = json.loads(tree.attrs.get("priors", "") or "{}").get("alpha") or {}
    if "low" in priors and "high" in priors:
        return float(priors["low"]), float(priors["high"])
    return None


def widening_of(tree) -> dict:
    """The run's widening record ({} for a run fitted without it)."""
    text = tree.attrs.get("widening", "")
    return json.loads(text) if text else {}


def model_posterior(tree):
    """The run's posterior dataset with its population values the model's own (model_posterior
    where the run was widened): the draws each draw's spreads and test coefficients belong to."""
    post = tree["posterior"].to_dataset()
    if "model_posterior" in tree.children:
        post = post.assign(tree["model_posterior"].to_dataset().data_vars)
    return post


def model_draws(tree, name: str):
    """The model's own draws of a population value (its model_posterior where the run was widened)."""
    if "model_posterior" in tree.children and name in tree["model_posterior"]:
        return tree["model_posterior"][name]
    return tree["posterior"][name]


def flat_model_draws(tree, name: str) -> np.ndarray:
    """model_draws of `name` (any site) as a float array with chains and draws joined:
    (chains*draws, ...)."""
    values = np.asarray(model_draws(tree, name).values, dtype=float)
    return values.reshape((-1,) + values.shape[2:])
