"""Scoring a force model (base plus effects) on a series: collapsed hierarchical AR(1) GLS.

Model, for test j with design X_j = [a, u, filter(|v|^alpha sign v), filter(sign v), effect
columns] and response y_j = F_j (or an effect's re-read force) - m_payload*a_j:

    y_j = X_j theta_j + e_j,   e_jt = phi_j e_j(t-1) + w_jt,  w ~ N(0, sigma_j^2)
    theta_jk ~ N(mu_k, (s*mu_k)^2) for the four base coefficients (test-to-test spread s),
    theta_jk = mu_k for effect coefficients (one value for the campaign),
    mu ~ N(0, S0),  S0 flat for the base coefficients, the effect's prior for its own.

theta_j and mu are integrated out exactly (as in bayes_sst.inference._collapsed); phi_j and
sigma_j are plugged in from the test's own least-squares residual, s and alpha are profiled.

Score: the leave-one-test-out log predictive density

    elpd_j = log p(y_j | y_-j) = c_j + 1/2 log|Q - H_j| - 1/2 log|Q| + 1/2 r'Q^-1 r
             - 1/2 (r - h_j)'(Q - H_j)^-1 (r - h_j),

with c_j, h_j, H_j the test's Gaussian pieces and Q = S0^-1 + sum H_j, r = sum h_j. Whole
tests are held out because samples within a test are correlated; the tests are independent,
so the standard error of a sum of per-test differences is sqrt(J*var(diff_j)).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np

from bayes_sst.effects import Effect, EffectData

BASE_COEFFICIENTS = ("Me", "Ke", "Ce", "Fmu")
SPREAD_GRID = (0.001, 0.0025, 0.005, 0.01, 0.02, 0.035, 0.06, 0.1, 0.18)
FLAT_SD = 1e4          # prior sd of base coefficients, scaled units: flat in practice
LOG_2PI = math.log(2.0 * math.pi)
MAX_PHI = 0.98

Term = tuple[Effect, Mapping[str, float]]


@dataclass(frozen=True)
class ModelFit:
    """One model scored on a series (SI coefficients).

    names : coefficient names; mu, mu_sd : population coefficients and their sd (given the
    profiled alpha, spread, noise); theta : (J, p) per-test coefficients (posterior means);
    alpha, spread; phi, sigma : (J,) noise; log_marginal; elpd : (J,) leave-one-test-out log
    predictive densities; residuals : per-test y - X theta_j at the kept samples, N.
    """

    terms: tuple
    names: tuple[str, ...]
    mu: np.ndarray
    mu_sd: np.ndarray
    theta: np.ndarray
    alpha: float
    spread: float
    phi: np.ndarray
    sigma: np.ndarray
    log_marginal: float
    elpd: np.ndarray
    residuals: tuple[np.ndarray, ...]

    def coefficient(self, name: str) -> float:
        return float(self.mu[self.names.index(name)])

    def base(self) -> dict[str, float]:
        return {**{n: self.coefficient(n) for n in BASE_COEFFICIENTS}, "alpha": self.alpha}


class Scorer:
    """Scores models on a fixed list of tests, caching base and effect columns."""

    def __init__(self, tests: Sequence[EffectData], base_scale: Mapping[str, float] | None = None):
        self.tests = list(tests)
        self._base_cache: dict[float, list[np.ndarray]] = {}
        self._effect_cache: dict = {}
        self.sign = [t.sign() for t in self.tests]
        self.base_scale = dict(base_scale or {})

    # --- design -----------------------------------------------------------------------------
    def base_columns(self, alpha: float) -> list[np.ndarray]:
        key = round(float(alpha), 6)
        if key not in self._base_cache:
            self._base_cache[key] = [np.vstack([t.a, t.u, t.damping(alpha), s])
                                     for t, s in zip(self.tests, self.sign)]
            if len(self._base_cache) > 64:
                self._base_cache.pop(next(iter(self._base_cache)))
        return self._base_cache[key]

    def _effect_columns(self, effect: Effect, setting, alpha):
        depends_on_base = effect.name == "drift"
        key = (effect.name, tuple(sorted(setting.items())),
               (round(alpha, 6), tuple(sorted(self.base_scale.items()))) if depends_on_base else None)
        if key not in self._effect_cache:
            cols = [effect.columns(t, setting, alpha, self.base_scale) for t in self.tests]
            resp = [effect.response(t, setting) for t in self.tests]
            self._effect_cache[key] = (cols, resp)
            if len(self._effect_cache) > 4096:
                self._effect_cache.pop(next(iter(self._effect_cache)))
        return self._effect_cache[key]

    def design(self, terms: Sequence[Term], alpha: float):
        """Per-test y (n,), X (p, n), coefficient names and effect prior sds (SI)."""
        base = self.base_columns(alpha)
        ys = [t.F - t.payload_kg * t.a for t in self.tests]
        blocks = [[b] for b in base]
        names = list(BASE_COEFFICIENTS)
        prior = []
        for effect, setting in terms:
            cols, resp = self._effect_columns(effect, setting, alpha)
            if resp[0] is not None:
                ys = [r - t.payload_kg * t.a for r, t in zip(resp, self.tests)]
            if cols[0].shape[0]:
                for block, c in zip(blocks, cols):
                    block.append(c)
                names += [f"{effect.name}.{c}" for c in effect.coefficients]
                prior.append(effect.prior_sd(self.base_scale))
        Xs = [np.vstack(b) for b in blocks]
        return ys, Xs, tuple(names), (np.concatenate(prior) if prior else np.zeros(0))

    # --- scoring ----------------------------------------------------------------------------
    def fit(self, terms: Sequence[Term], alpha: float, *, spread: float | None = None) -> ModelFit:
        ys, Xs, names, effect_prior = self.design(terms, alpha)
        return _fit(ys, Xs, names, effect_prior, alpha, spread, tuple(terms))

    def profile_alpha(self, terms: Sequence[Term], grid: Sequence[float]) -> ModelFit:
        """The model at the alpha of `grid` with the highest marginal likelihood."""
        best = None
        for alpha in grid:
            fit = self.fit(terms, float(alpha))
            if best is None or fit.log_marginal > best.log_marginal:
                best = fit
        return best


def _fit(ys, Xs, names, effect_prior, alpha, spread, terms) -> ModelFit:
    p = len(names)
    y_scale = float(np.sqrt(np.mean(np.concatenate(ys) ** 2))) or 1.0
    col_scale = np.sqrt(np.mean(np.hstack(Xs) ** 2, axis=1))
    col_scale = np.where(col_scale > 0, col_scale, 1.0)
    prior_sd = np.concatenate([np.full(4, FLAT_SD), effect_prior * col_scale[4:] / y_scale])
    prior_sd = np.where(prior_sd > 0, prior_sd, FLAT_SD)

    J = len(ys)
    W = np.empty((J, p + 1, p + 1))
    n_pairs = np.empty(J)
    phi = np.empty(J)
    sigma = np.empty(J)
    for j, (y, X) in enumerate(zip(ys, Xs)):
        z = np.vstack([y / y_scale, X / col_scale[:, None]])
        coef, *_ = np.linalg.lstsq(z[1:].T, z[0], rcond=None)
        e = z[0] - coef @ z[1:]
        phi[j] = float(np.clip(np.dot(e[1:], e[:-1]) / max(np.dot(e[:-1], e[:-1]), 1e-300), 0.0, MAX_PHI))
        w = e[1:] - phi[j] * e[:-1]
        dof = max(len(w) - p - 1, 1)
        sigma[j] = math.sqrt(max(np.dot(w, w) / dof, 1e-24))
        zw = z[:, 1:] - phi[j] * z[:, :-1]
        W[j] = zw @ zw.T
        n_pairs[j] = zw.shape[1]

    # population values with no spread first: they set the spread's scale s*|mu|
    mu0 = _pieces(W, n_pairs, sigma, np.zeros(p), prior_sd)[-1]
    best = None
    for s in ([spread] if spread is not None else SPREAD_GRID):
        rho = np.concatenate([s * np.abs(mu0[:4]), np.zeros(p - 4)])
        pieces = _pieces(W, n_pairs, sigma, rho, prior_sd)
        if best is None or pieces[0] > best[1][0]:
            best = (s, pieces, rho)
    s, (log_marginal, c, h, H, Q, r, A, b, B_inv, mu), rho = best

    elpd = np.empty(J)
    Q_chol = np.linalg.cholesky(Q)
    half_logdet_Q = np.sum(np.log(np.diag(Q_chol)))
    full = 0.5 * r @ mu
    for j in range(J):
        Qj = Q - H[j]
        rj = r - h[j]
        Lj = np.linalg.cholesky(Qj)
        elpd[j] = c[j] + np.sum(np.log(np.diag(Lj))) - half_logdet_Q + full - 0.5 * rj @ np.linalg.solve(Qj, rj)
    # theta_j = mu + D B^-1 D (b_j - A_j mu)
    theta_scaled = mu[None, :] + rho[None, :] * np.einsum("jkl,jl->jk", B_inv, rho[None, :] * (b - A @ mu))
    to_si = y_scale / col_scale
    mu_cov = np.linalg.inv(Q)
    theta = theta_scaled * to_si
    residuals = tuple(y - th @ X for y, X, th in zip(ys, Xs, theta))
    return ModelFit(
        terms=terms, names=names, mu=mu * to_si, mu_sd=np.sqrt(np.diag(mu_cov)) * to_si, theta=theta,
        alpha=float(alpha), spread=float(s), phi=phi, sigma=sigma * y_scale,
        log_marginal=float(log_marginal + sum(np.log(y_scale) * -n for n in n_pairs)),
        elpd=elpd - n_pairs * np.log(y_scale), residuals=residuals,
    )


def _pieces(W, n_pairs, sigma, rho, prior_sd):
    """Collapsed log marginal and its Gaussian pieces (module docstring), scaled units."""
    J, p1, _ = W.shape
    p = p1 - 1
    var = sigma * sigma
    A = W[:, 1:, 1:] / var[:, None, None]
    b = W[:, 1:, 0] / var[:, None]
    yy = W[:, 0, 0] / var
    DA = rho[None, :, None] * A
    B = np.eye(p)[None] + DA * rho[None, None, :]
    L = np.linalg.cholesky(B)
    B_inv = np.linalg.inv(B)
    g = np.linalg.solve(L, (rho[None, :] * b)[..., None])[..., 0]
    G = np.linalg.solve(L, DA)
    H = A - np.einsum("jki,jkl->jil", G, G)
    h = b - np.einsum("jki,jk->ji", G, g)
    c = (-np.sum(np.log(np.diagonal(L, axis1=1, axis2=2)), axis=1) + 0.5 * np.sum(g * g, axis=1)
         - 0.5 * n_pairs * (LOG_2PI + np.log(var)) - 0.5 * yy)
    Q = np.diag(1.0 / prior_sd**2) + H.sum(axis=0)
    r = h.sum(axis=0)
    Qc = np.linalg.cholesky(Q)
    mu = np.linalg.solve(Q, r)
    log_marginal = (c.sum() - np.sum(np.log(prior_sd)) - np.sum(np.log(np.diag(Qc))) + 0.5 * r @ mu)
    return log_marginal, c, h, H, Q, r, A, b, B_inv, mu
