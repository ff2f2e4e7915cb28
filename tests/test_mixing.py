"""The vectorised R-hat and bulk ESS against ArviZ's own estimators, and against known mixing."""

from __future__ import annotations

import numpy as np
import pytest
from arviz_stats.base import array_stats

from bayes_sst.inference._mixing import rank_rhat_and_bulk_ess


def _ar1(rng, chains, draws, k, phi, chain_offset_sd=0.0):
    e = rng.normal(size=(chains, draws, k))
    x = np.zeros_like(e)
    for t in range(1, draws):
        x[:, t] = phi * x[:, t - 1] + e[:, t]
    return x + chain_offset_sd * rng.normal(size=(chains, 1, k))


@pytest.mark.parametrize("chains, draws, phi, offset", [(4, 500, 0.0, 0.0), (4, 500, 0.9, 0.0), (4, 501, -0.6, 0.0),
                                                        (2, 15, 0.5, 0.0), (4, 500, 0.95, 1.0), (1, 100, 0.3, 0.0),
                                                        (4, 7, 0.2, 0.0)])
def test_matches_arviz_rank_rhat_and_bulk_ess_column_by_column(chains, draws, phi, offset):
    rng = np.random.default_rng(chains * 1000 + draws)
    x = _ar1(rng, chains, draws, 25, phi, offset)
    x[:, ::7, 0] = x[:, :1, 0]  # repeated draws (a NUTS chain can stay put): tied ranks
    rhat, ess = rank_rhat_and_bulk_ess(x)
    by_variable = np.moveaxis(x, -1, 0)
    assert ess == pytest.approx(array_stats.ess(by_variable, method="bulk"), rel=1e-10)
    if chains > 1:
        assert rhat == pytest.approx(array_stats.rhat(by_variable, method="rank"), rel=1e-12)
    else:
        assert np.isnan(rhat).all()


def test_known_mixing_white_chains_near_their_size_and_stuck_chains_flagged():
    rng = np.random.default_rng(5)
    white = rng.normal(size=(4, 1000, 50))
    rhat, ess = rank_rhat_and_bulk_ess(white)
    assert np.all(rhat < 1.01) and np.median(ess) == pytest.approx(4000, rel=0.1)
    # AR(1) with phi = 0.9: ESS = N (1 - phi)/(1 + phi) = 4000/19, about 210
    _, ess = rank_rhat_and_bulk_ess(_ar1(rng, 4, 1000, 50, 0.9))
    assert np.median(ess) == pytest.approx(4000 / 19, rel=0.2)
    # chains stuck at different levels (offsets of 1 sd between chains)
    rhat, _ = rank_rhat_and_bulk_ess(_ar1(rng, 4, 1000, 20, 0.0, chain_offset_sd=1.0))
    assert np.median(rhat) > 1.1
    constant = np.full((4, 50, 2), 3.0)
    rhat, ess = rank_rhat_and_bulk_ess(constant)
    assert np.isnan(rhat).all() and np.all(ess == 200)
