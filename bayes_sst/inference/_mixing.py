"""Rank-normalised split R-hat and bulk ESS for many variables at once.

The same estimators as arviz_stats.rhat(method="rank") and arviz_stats.ess(method="bulk")
(Vehtari et al. 2021, https://arxiv.org/abs/1903.08008), computed for every column of a
(chain, draw, k) array in one pass. Why: the per-test noise parameters of a 200-test fit are
400 variables, and ArviZ's loop over them took 1.2-3 s, more than the fit's posterior step;
the fit checks them after every run (summary.short_of_limits) and the summary again.

Estimators, for each variable, with the chains split in halves (2C chains of N = n//2 draws):

    z = Phi^-1((r - 3/8)/(S + 1/4)),   r the rank among all S = 2C*N draws (ties averaged)
    R-hat(z) = sqrt(((N - 1) W + B)/(N W)),   B = N var_c(mean_c z), W = mean_c var_c z
    R-hat = max(R-hat(z), R-hat(z of |x - median x|))
    rho_t = 1 - (W' - mean_c acov_c(t))/V,   W' = mean_c acov_c(0) N/(N - 1),
            V = W' (N - 1)/N + var_c(mean_c z)
    ESS = S/tau,   tau = -1 + 2 sum_{m < m*} min_{m' <= m} P_m' + rho_(2m*)^+,   P_m = rho_2m + rho_(2m+1)

with m* where Geyer's initial positive sequence of pair sums P_m ends, exactly as ArviZ
truncates it (see _ess); tau is at least 1/log10(S).
"""

from __future__ import annotations

import numpy as np
from scipy import fft, special, stats


def _split(x: np.ndarray) -> np.ndarray:
    """(C, n, k) -> (2C, n//2, k): first and last halves of each chain as chains of their own."""
    half = x.shape[1] // 2
    return np.concatenate([x[:, :half], x[:, x.shape[1] - half:]], axis=0)


def _z_scale(x: np.ndarray) -> np.ndarray:
    """Rank-normalised values: Phi^-1 of the Blom-offset rank among all draws of each variable."""
    flat = x.reshape(-1, x.shape[-1])
    ranks = stats.rankdata(flat, method="average", axis=0)
    return special.ndtri((ranks - 0.375) / (flat.shape[0] + 0.25)).reshape(x.shape)


def _rhat(z: np.ndarray) -> np.ndarray:
    n = z.shape[1]
    between = n * np.var(z.mean(axis=1), axis=0, ddof=1)
    within = np.mean(np.var(z, axis=1, ddof=1), axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):  # a constant variable: NaN, as ArviZ gives
        return np.sqrt((between / within + n - 1) / n)


def rank_rhat_and_bulk_ess(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rank-normalised split R-hat (bulk and folded, the larger) and bulk ESS of each column of
    x (C, n, k); R-hat is NaN with one chain."""
    x = np.asarray(x, dtype=float)
    split = _split(x)
    z = _z_scale(split)
    folded = np.abs(split - np.median(split.reshape(-1, split.shape[-1]), axis=0))
    if x.shape[0] > 1:
        rhat = np.maximum(_rhat(z), _rhat(_z_scale(folded)))
    else:
        rhat = np.full(x.shape[-1], np.nan)
    return rhat, _ess(z, x)


def _ess(z: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Bulk ESS from the split, rank-normalised draws z of x (module docstring)."""
    chains, n, k = z.shape
    total = chains * n
    centred = z - z.mean(axis=1, keepdims=True)
    size = fft.next_fast_len(2 * n)
    spectrum = fft.rfft(centred, n=size, axis=1)
    acov = fft.irfft(spectrum * np.conjugate(spectrum), n=size, axis=1)[:, :n] / n
    mean_var = acov[:, 0].mean(axis=0) * n / (n - 1.0)
    var_plus = mean_var * (n - 1.0) / n
    if chains > 1:
        var_plus = var_plus + np.var(z.mean(axis=1), axis=0, ddof=1)
    with np.errstate(invalid="ignore", divide="ignore"):  # a constant variable: 0/0, handled below
        rho = 1.0 - (mean_var - acov.mean(axis=0)) / var_plus  # (n, k)
    rho[0] = 1.0
    pairs = rho[0:2 * (n // 2):2] + rho[1:2 * (n // 2):2]  # P_m, (n//2, k)
    m = np.arange(pairs.shape[0])[:, None]
    # ArviZ evaluates pair m >= 1 while every earlier pair sum is positive and 2m - 1 < n - 3
    earlier_positive = np.cumprod(np.vstack([np.ones((1, k), bool), pairs[:-1] > 0]), axis=0).astype(bool)
    evaluated = earlier_positive & (m >= 1) & (2 * m - 1 < n - 3)
    last = np.where(evaluated.any(axis=0), (evaluated * m).max(axis=0), 0)  # m*
    columns = np.arange(k)
    monotone = np.minimum.accumulate(pairs, axis=0)
    head = np.where(m < last[None], monotone, 0.0).sum(axis=0)
    rho_last = rho[2 * last, columns]
    last_stored = (last >= 1) & (pairs[last, columns] >= 0)
    tail = np.where(last_stored | (rho_last > 0), rho_last, 0.0)
    tau = np.maximum(-1.0 + 2.0 * head + tail, 1.0 / np.log10(total))
    ess = total / tau
    constant = (x.max(axis=(0, 1)) - x.min(axis=(0, 1))) < np.finfo(float).resolution
    ess = np.where(constant, float(x.shape[0] * x.shape[1]), ess)
    return np.where(np.isnan(rho).any(axis=0) & ~constant, np.nan, ess)
