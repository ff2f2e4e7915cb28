"""The jackknife widening of the population intervals (bayes_sst.inference._widening)."""

import json

import numpy as np
import pytest
import xarray as xr

from bayes_sst.inference._widening import (
    MAX_WIDENING,
    MAX_GROUPS,
    MIN_TESTS,
    POPULATION,
    jackknife_factors,
    jackknife_variance,
    left_out_groups,
    model_draws,
    widen,
    widening_of,
)


def _jackknife_of_means(values: np.ndarray) -> xr.Dataset:
    """The jackknife group of an estimator that is the mean over tests, the same for all five
    quantities: without test j it reads the mean of the others."""
    n = len(values)
    without = (values.sum() - values) / (n - 1)
    return xr.Dataset(
        {"all_tests": (("quantity",), np.full(5, values.mean())),
         "without_test": (("left_out", "quantity"), np.repeat(without[:, None], 5, axis=1))},
        coords={"quantity": list(POPULATION), "left_out": [f"T{j:02d}" for j in range(n)]},
    )


def _posterior(sd: float, centre: float = 10.0, chains: int = 4, draws: int = 2000, seed: int = 0) -> xr.Dataset:
    rng = np.random.default_rng(seed)
    return xr.Dataset({name: (("chain", "draw"), centre + sd * rng.standard_normal((chains, draws)))
                       for name in POPULATION})


def test_the_jackknife_of_a_mean_over_tests_is_its_classical_standard_error():
    """For a mean of J values the delete-one jackknife variance is exactly s^2/J (s the sample sd),
    so a posterior half as wide as that is stretched by 2, and one twice as wide is left alone."""
    values = np.random.default_rng(1).normal(10.0, 0.3, size=12)
    standard_error = values.std(ddof=1) / np.sqrt(len(values))
    narrow = _posterior(0.5 * standard_error)
    factors = jackknife_factors(_jackknife_of_means(values), narrow)
    for name in POPULATION:
        sd = narrow[name].values.std(ddof=1)
        assert factors[name]["ratio"] == pytest.approx(standard_error / sd, rel=1e-9)
        assert factors[name]["factor"] == pytest.approx(factors[name]["ratio"])
        assert 1.9 < factors[name]["factor"] < 2.1
    wide = jackknife_factors(_jackknife_of_means(values), _posterior(2.0 * standard_error))
    assert all(0.45 < f["ratio"] < 0.55 and f["factor"] == 1.0 for f in wide.values())


def test_few_tests_are_not_widened_and_an_outlying_test_is_capped_and_named():
    values = np.random.default_rng(2).normal(10.0, 0.3, size=MIN_TESTS - 1)
    few = jackknife_factors(_jackknife_of_means(values), _posterior(0.01))
    assert all(f["ratio"] > 5 and f["factor"] == 1.0 for f in few.values())

    values = np.random.default_rng(3).normal(10.0, 0.01, size=15)
    values[7] = 13.0  # one test far from the rest
    post = _posterior(0.01)
    capped = jackknife_factors(_jackknife_of_means(values), post)
    for name, f in capped.items():
        assert f["ratio"] > MAX_WIDENING and f["factor"] == MAX_WIDENING
        assert f["shift_test"] == "T07"
        # leaving T07 out lowers the estimate to the others' mean: about 0.2, or 20 posterior sds
        shift = (values.sum() - values[7]) / 14 - values.mean()
        assert f["shift_sd"] == pytest.approx(shift / post[name].values.std(ddof=1), rel=1e-9)
        assert -21 < f["shift_sd"] < -19


def test_widen_stretches_the_draws_about_their_mean_and_keeps_the_models_own():
    values = np.random.default_rng(4).normal(10.0, 0.3, size=20)
    standard_error = values.std(ddof=1) / np.sqrt(len(values))
    post = _posterior(0.5 * standard_error)
    tree = xr.DataTree.from_dict({"posterior": post, "jackknife": _jackknife_of_means(values)})
    widened = widen(tree)
    record = widening_of(widened)
    assert set(record) == set(POPULATION)
    assert json.loads(widened.attrs["widening"]) == record
    for name in POPULATION:
        model = model_draws(widened, name).values
        stretched = widened["posterior"][name].values
        np.testing.assert_allclose(model, post[name].values)
        assert stretched.mean() == pytest.approx(model.mean(), abs=1e-12)
        assert stretched.std() / model.std() == pytest.approx(record[name]["factor"], rel=1e-9)
        assert stretched.std() == pytest.approx(standard_error, rel=0.05)
    # a run without a jackknife (fit(..., widen=False)) is left as it is
    plain = xr.DataTree.from_dict({"posterior": post})
    assert widening_of(widen(plain)) == {} and "model_posterior" not in plain.children
    assert model_draws(plain, "Me") is not None


def test_beyond_forty_tests_groups_of_tests_are_left_out_and_read_with_the_unequal_group_formula():
    assert left_out_groups(12) == [[j] for j in range(12)]
    groups = left_out_groups(45)
    assert len(groups) == MAX_GROUPS == 40
    assert sorted(j for g in groups for j in g) == list(range(45))
    assert groups[0] == [0, 40] and groups[4] == [4, 44] and groups[5] == [5]
    # with one test per group the unequal-group formula is the plain (J-1)/J sum of squares
    rng = np.random.default_rng(5)
    values = rng.normal(0.0, 1.0, size=12)
    without = np.array([np.delete(values, j).mean() for j in range(12)])
    plain = 11 / 12 * np.sum((without - without.mean()) ** 2)
    assert jackknife_variance(np.array([values.mean()]), without[:, None], np.ones(12))[0] == pytest.approx(plain)
    # and over many draws of 45 values (40 groups: five pairs and 35 single tests) it reads the
    # variance of the mean, 1/45, within a few percent
    ratios = []
    sizes = np.array([len(g) for g in groups])
    for _ in range(2000):
        values = rng.normal(0.0, 1.0, size=45)
        without = np.array([np.delete(values, g).mean() for g in groups])
        ratios.append(jackknife_variance(np.array([values.mean()]), without[:, None], sizes)[0] * 45)
    assert 0.97 < np.mean(ratios) < 1.03
