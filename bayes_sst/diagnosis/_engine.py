"""Scoring a force model (base plus effects) on a series: collapsed hierarchical AR(1) GLS.

Model, for test j with design X_j = [a, u, filter(|v|^alpha sign v), filter(sign v), effect
columns] and response y_j = F_j (or an effect's re-read force) - m_payload*a_j:

    y_j = X_j theta_j + e_j,   e_jt = phi_j e_j(t-1) + w_jt,  w ~ N(0, sigma_j^2)
    theta_jk ~ N(mu_k, (s_k*mu_k)^2) for the four base coefficients, with one test-to-test
    spread s_1 for Me and Ke (the deck's mass and the struts' stiffness) and one s_2 for Ce and
    Fmu (damping and friction, which vary with the oil's temperature and the bearings' state),
    theta_jk = mu_k for effect coefficients (one value for the campaign),
    mu ~ N(0, S0),  S0 flat for the base coefficients, the effect's prior for its own.

theta_j and mu are integrated out exactly (as in bayes_sst.inference._collapsed); phi_j and
sigma_j are plugged in from the test's own least-squares residual, s_1, s_2 and alpha are profiled.
With Scorer.consistent_noise (the reversal and stroke views' scorers), the plug-ins come instead from the
residual of the model being scored (a first fit's y_j - X_j theta_j, effect coefficients at
their one shared value), and the model is fitted again with them. Why: the least-squares
residual lets an effect's coefficient take any value in each test. A column that is non-zero
on a few samples per reversal (a narrow Stribeck bump) then fits each test's own reversal
misfit with its own absurd coefficient (static ratios of 4-300 on the sixth simulator's seed
100, per-test sigma 186 -> 100 N), while the scored model, with one shared value, leaves that
residual where it was (192.8 -> 188.1 N): the likelihood was evaluated with a sigma far under
the model's residual, and the log marginal fell by up to 229 nats for a column with a 1.23
stiction in it. With the model's own residual the profile over the Stribeck velocity is
smooth, peaks at 6.4-7.7 mm/s (true 6.8) with a ratio of 1.18-1.27 (true 1.23), +9.8 nats.
A hinge column in the stroke view does the same with each test's Coulomb column
(diagnosis._diagnose.CONSISTENT_NOISE_VIEWS). The default view keeps the least-squares
plug-ins, with which its gates were set.

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
from bayes_sst.signals._noise import NOISE_KEEP

BASE_COEFFICIENTS = ("Me", "Ke", "Ce", "Fmu")
SPREAD_GRID = (0.001, 0.0025, 0.005, 0.01, 0.02, 0.035, 0.06, 0.1, 0.18)
# Me's and Ke's spread stops at 6 %: a deck's mass does not change between the tests of a
# campaign (a payload is modelled) and the struts' stiffness moves with their gas temperature
# only. Why a bound: within a sine test a = -omega^2*u, so the per-test Me and Ke are told
# apart by a's small harmonics alone; when the accelerometer's noise drowns them, a free spread
# ran to 18 % and let the per-test values, still pulled low by the noise, carry the population
# (twin with 0.12 m/s^2 of accelerometer noise: Me -26 %; with the bound, 0.0 and -1.2 %, as
# with one spread for all four coefficients)
INERTIA_STIFFNESS_SPREAD_GRID = tuple(g for g in SPREAD_GRID if g <= 0.06)
FLAT_SD = 1e4          # prior sd of base coefficients, scaled units: flat in practice
LOG_2PI = math.log(2.0 * math.pi)
MAX_PHI = 0.98
# a test whose residual keeps fewer degrees of freedom than this cannot tell its own noise: it
# takes the other tests' pooled sigma. Why: a 0.1 Hz triangle of 6.6 mm (the seventh simulator's
# seed 207) kept 3 samples in the default view once the reversal band and the pre-sliding turn
# were out; its least-squares residual was zero, sigma fell to its floor of 1e-12 and the
# collapsed precision stopped being positive definite (an internal error, nothing diagnosed)
MIN_NOISE_DOF = 3

Term = tuple[Effect, Mapping[str, float]]


@dataclass(frozen=True)
class ModelFit:
    """One model scored on a series (SI coefficients).

    names : coefficient names; mu, mu_sd : population coefficients and their sd (given the
    profiled alpha, spread, noise); mu_sandwich_sd : their cluster-robust sd over tests,
    sqrt(diag(Q^-1 S Q^-1)) with S = J/(J-1)*sum_j psi_j psi_j', psi_j = h_j - H_j mu (test j's
    score at mu), which also holds what the tests disagree on beyond the model's noise (a
    column whose shape is not the data's shows so); theta : (J, p) per-test coefficients
    (posterior means);
    alpha; spread : (s_1, s_2), the relative test-to-test spreads of (Me, Ke) and of (Ce, Fmu);
    phi, sigma : (J,) noise; log_marginal; elpd : (J,) leave-one-test-out log predictive
    densities; residuals : per-test y - X theta_j at the kept samples, N.
    """

    terms: tuple
    names: tuple[str, ...]
    mu: np.ndarray
    mu_sd: np.ndarray
    mu_sandwich_sd: np.ndarray
    theta: np.ndarray
    alpha: float
    spread: tuple[float, float]
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

    def __init__(self, tests: Sequence[EffectData], base_scale: Mapping[str, float] | None = None,
                 consistent_noise: bool = False):
        self.tests = list(tests)
        self._base_cache: dict[float, list[np.ndarray]] = {}
        self._effect_cache: dict = {}
        self.sign = [t.sign() for t in self.tests]
        self.base_scale = dict(base_scale or {})
        # what the accelerometer's noise draws become in the acceleration column (K, n_kept)
        self.a_noise = [None if t.a_noise_full is None else t.filtered(t.a_noise_full) for t in self.tests]
        self._noise_cache: dict = {}
        # the plug-in noise from the scored model's own residual (module docstring)
        self.consistent_noise = consistent_noise

    # --- design -----------------------------------------------------------------------------
    def base_columns(self, alpha: float) -> list[np.ndarray]:
        key = round(float(alpha), 6)
        if key not in self._base_cache:
            self._base_cache[key] = [np.vstack([t.model_a, t.model_u, t.damping(alpha), s])
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

    def _effect_noise(self, effect: Effect, setting):
        """Per test, the accelerometer noise draws through the effect's columns (K, k, n), or None."""
        key = (effect.name, tuple(sorted(setting.items())))
        if key not in self._noise_cache:
            self._noise_cache[key] = [
                None if t.a_noise_full is None else effect.acceleration_columns(t, setting, t.a_noise_full)
                for t in self.tests]
            if len(self._noise_cache) > 256:
                self._noise_cache.pop(next(iter(self._noise_cache)))
        return self._noise_cache[key]

    def noise(self, terms: Sequence[Term]):
        """Per test: (payload kg, {column index: (K, n) noise draws}) for the errors-in-variables
        correction, or None for a test without a known accelerometer noise. The acceleration
        column is index 0; an effect's columns that read the acceleration carry the same draws
        through their own transform (Effect.acceleration_columns)."""
        out = []
        for j, t in enumerate(self.tests):
            if self.a_noise[j] is None:
                out.append(None)
                continue
            columns = {0: self.a_noise[j]}
            index = len(BASE_COEFFICIENTS)
            for effect, setting in terms:
                k = len(effect.coefficients)
                if k:
                    drawn = self._effect_noise(effect, setting)[j]
                    if drawn is not None:
                        for i in range(k):
                            columns[index + i] = drawn[:, i, :]
                index += k
            out.append((t.payload_kg, columns))
        return out

    def design(self, terms: Sequence[Term], alpha: float):
        """Per-test y (n,), X (p, n), coefficient names and effect prior sds (SI)."""
        base = self.base_columns(alpha)
        ys = [t.F - t.payload_kg * t.model_a for t in self.tests]
        blocks = [[b] for b in base]
        names = list(BASE_COEFFICIENTS)
        prior = []
        for effect, setting in terms:
            cols, resp = self._effect_columns(effect, setting, alpha)
            if resp[0] is not None:
                ys = [r - t.payload_kg * t.model_a for r, t in zip(resp, self.tests)]
            if cols[0].shape[0]:
                for block, c in zip(blocks, cols):
                    block.append(c)
                names += [f"{effect.name}.{c}" for c in effect.coefficients]
                prior.append(effect.prior_sd(self.base_scale))
        Xs = [np.vstack(b) for b in blocks]
        return ys, Xs, tuple(names), (np.concatenate(prior) if prior else np.zeros(0))

    # --- scoring ----------------------------------------------------------------------------
    def fit(self, terms: Sequence[Term], alpha: float, *, spread=None) -> ModelFit:
        """The model with `terms` at this alpha; spread: (s_1, s_2) (or one value for both) to
        hold, None to profile. With consistent_noise, fitted twice: the second time with each
        test's phi and sigma read from the first fit's residual (module docstring)."""
        ys, Xs, names, effect_prior = self.design(terms, alpha)
        noise = self.noise(terms)
        fit = _fit(ys, Xs, names, effect_prior, alpha, spread, tuple(terms), noise)
        if self.consistent_noise:
            fit = _fit(ys, Xs, names, effect_prior, alpha, spread, tuple(terms), noise, fit.residuals)
        return fit

    def profile_alpha(self, terms: Sequence[Term], grid: Sequence[float]) -> ModelFit:
        """The model at the alpha of `grid` with the highest marginal likelihood."""
        return most_probable(self.alpha_fits(terms, grid))

    def alpha_fits(self, terms: Sequence[Term], grid: Sequence[float],
                   known: Sequence[ModelFit] = ()) -> list[ModelFit]:
        """The model at every alpha of `grid`; known: fits of the same terms already made, reused
        at their alphas (a fine grid around a coarse one's best shares its nodes)."""
        made = {round(fit.alpha, 6): fit for fit in known}
        return [made.get(round(float(alpha), 6)) or self.fit(terms, float(alpha)) for alpha in grid]


def most_probable(fits: Sequence[ModelFit]) -> ModelFit:
    """The fit of highest log marginal likelihood (the first of equals)."""
    return max(fits, key=lambda fit: fit.log_marginal)


def _noise_moments(payload: float, columns: Mapping[int, np.ndarray], p: int, phi: float,
                   y_scale: float, col_scale: np.ndarray) -> np.ndarray:
    """C (p+1, p+1): E[zw_n zw_n'], what the accelerometer's noise adds to the whitened moments
    W of z = (y, X) in the scaled units, from its Monte Carlo draws through each column that reads
    the acceleration (Scorer.noise); y = F - m_payload*a carries -m_payload times the a column's."""
    rows = [0] + [index + 1 for index in columns]  # y, then the columns the noise reaches
    zn = np.stack([-payload * columns[0] / y_scale] + [draws / col_scale[index] for index, draws in columns.items()],
                  axis=1)
    whitened = zn[:, :, 1:] - phi * zn[:, :, :-1]
    C = np.zeros((p + 1, p + 1))
    C[np.ix_(rows, rows)] = np.einsum("kit,kjt->ij", whitened, whitened) / len(zn)
    return C


def _scaled(ys, Xs):
    """(y_scale, col_scale, empty, Xs): the RMS of the response and of each column over all
    tests, and the columns that are zero everywhere in this view (a Stribeck bump for |v| well
    below the reversal band, weighted out). Those carry no information: they are set to exactly
    zero, with scale 1, so that their coefficient keeps its prior and the score is the base
    model's, instead of dividing by ~1e-170."""
    y_scale = float(np.sqrt(np.mean(np.concatenate(ys) ** 2))) or 1.0
    col_scale = np.sqrt(np.mean(np.hstack(Xs) ** 2, axis=1))
    empty = col_scale < 1e-100
    if np.any(empty):
        Xs = [np.where(empty[:, None], 0.0, X) for X in Xs]
    return y_scale, np.where(empty, 1.0, col_scale), empty, Xs


def _test_moments(y, X, y_scale: float, col_scale: np.ndarray, noise_j, empty: np.ndarray, noise_residual=None):
    """One test's whitened moments W = zw zw' of z = (y, X) in scaled units, its number of pairs,
    the plug-in AR(1) phi and innovation sd sigma of its own least-squares residual (of
    noise_residual, N, where given: a model's residual, whose degrees of freedom leave out only
    the base coefficients, the test's own), C, what
    the accelerometer's noise adds to W (None without a known noise; zero in the rows of empty
    columns, which hold no data for the noise to add to), and the residual's degrees of freedom
    (below MIN_NOISE_DOF _fit replaces sigma by the other tests' pooled value)."""
    p = X.shape[0]
    z = np.vstack([y / y_scale, X / col_scale[:, None]])
    if noise_residual is None:
        coef, _, rank, _ = np.linalg.lstsq(z[1:].T, z[0], rcond=None)
        e = z[0] - coef @ z[1:]
    else:
        # the scored model's own residual: only the base coefficients are the test's own
        e = noise_residual / y_scale
        rank = int(np.linalg.matrix_rank(z[1:1 + len(BASE_COEFFICIENTS)].T))
    phi = float(np.clip(np.dot(e[1:], e[:-1]) / max(np.dot(e[:-1], e[:-1]), 1e-300), 0.0, MAX_PHI))
    w = e[1:] - phi * e[:-1]
    # the columns' rank, not their number: a column that repeats the others within a test (drift's
    # -s_j*(Fmu*sign + Ce*damping)) takes no degree of freedom, and counting it raised sigma 1.5 %
    # and the log marginal, which the plug-in sigma sits below the optimum of, by 0.4 nats a test
    dof = len(w) - rank - 1
    sigma = math.sqrt(max(np.dot(w, w) / max(dof, 1), 1e-24))
    zw = z[:, 1:] - phi * z[:, :-1]
    C = None
    if noise_j is not None:
        C = _noise_moments(noise_j[0], noise_j[1], p, phi, y_scale, col_scale)
        rows = np.concatenate([[False], empty])
        C[rows, :] = 0.0
        C[:, rows] = 0.0
    return zw @ zw.T, zw.shape[1], phi, sigma, C, dof


def noise_scale_limit(W: np.ndarray, C: np.ndarray) -> float:
    """The largest t with W_x - t*C_x positive semi-definite, x the design's rows of W and C
    (both positive semi-definite): 1/lambda_max(C_x^(1/2) W_x^+ C_x^(1/2)), taken over the rows
    the noise reaches; infinite where it reaches none. With only the acceleration column
    reached this is what the other columns leave unexplained in a over the noise's energy there.

    Why an eigenvalue and not a search: halving a trial scale until the matrix was definite
    jumped by factors of 2 between neighbouring damping exponents and between models (the scale
    that stops at the limit is singular up to rounding, which failed the check about as often as
    not). On a clean series of the fifth independent simulator (seed 24, 512 Hz, 22 tests) the
    base model's log marginal then moved 20-40 nats between alpha nodes 0.025 apart and its Me by
    11 %, and a drift of -0.003 +- 0.026, whose columns within a test are the base's own, scored
    166 +- 80 nats: a solve on its singular moments had turned the correction off."""
    x = np.flatnonzero(np.any(C[1:, 1:] != 0.0, axis=1))
    if x.size == 0:
        return math.inf
    values, vectors = np.linalg.eigh(C[1:, 1:][np.ix_(x, x)])
    half = (vectors * np.sqrt(np.clip(values, 0.0, None))) @ vectors.T
    inverse = np.linalg.pinv(W[1:, 1:], rcond=1e-12, hermitian=True)[np.ix_(x, x)]
    largest = float(np.linalg.eigvalsh(half @ inverse @ half).max())
    return 1.0 / largest if largest > 0.0 else math.inf


def noise_factor(W: np.ndarray, C: np.ndarray) -> float:
    """The share of C that may be taken from W: at most what leaves NOISE_KEEP of the noise's
    energy in the part of a that the other columns do not explain, (u_a - NOISE_KEEP*C_aa)/C_aa
    with u_a = W_aa - W_ar W_rr^+ W_ra, and at most what leaves at least NOISE_KEEP*C in every
    direction of the design's moments (noise_scale_limit less NOISE_KEEP); within [0, 1].

    With the noise in a alone the two are one bound. With an effect column that reads a (a
    specimen's base shear, in a slow sine a near copy of a) the first is the smaller: little of
    a is left unexplained, and the correction all but stops. The second alone kept 60-100 % of
    it there, and the fifth simulator's 3.26 t specimen at 8.08 Hz (seed 214, the slow test
    test_a_sharp_resonance_behind_a_broad_coarse_peak_is_found_where_the_residual_is_well_above_its_floor)
    was no longer found: its coarse profile's nodes near 8 Hz fell below the base model."""
    a_row = W[1, 2:]
    unexplained = float(W[1, 1] - a_row @ np.linalg.pinv(W[2:, 2:], rcond=1e-12, hermitian=True) @ a_row)
    first = (unexplained - NOISE_KEEP * C[1, 1]) / C[1, 1] if C[1, 1] > 0.0 else math.inf
    return float(np.clip(min(first, noise_scale_limit(W, C) - NOISE_KEEP), 0.0, 1.0))


def _fit(ys, Xs, names, effect_prior, alpha, spread, terms, noise=None, noise_residuals=None) -> ModelFit:
    p = len(names)
    y_scale, col_scale, empty, Xs = _scaled(ys, Xs)
    prior_sd = np.concatenate([np.full(4, FLAT_SD), effect_prior * col_scale[4:] / y_scale])
    prior_sd = np.where(prior_sd > 0, prior_sd, FLAT_SD)

    J = len(ys)
    W = np.empty((J, p + 1, p + 1))
    n_pairs = np.empty(J)
    phi = np.empty(J)
    sigma = np.empty(J)
    moments: list[np.ndarray | None] = [None] * J
    dof = np.empty(J)
    for j, (y, X) in enumerate(zip(ys, Xs)):
        W[j], n_pairs[j], phi[j], sigma[j], moments[j], dof[j] = _test_moments(
            y, X, y_scale, col_scale, None if noise is None else noise[j], empty,
            None if noise_residuals is None else noise_residuals[j])
    few = dof < MIN_NOISE_DOF
    if few.all():
        raise ValueError(f"every test keeps too few samples in this view to tell its noise (residual degrees of "
                         f"freedom {', '.join(str(int(d)) for d in dof)}; at least {MIN_NOISE_DOF} are needed): "
                         f"longer tests, or more cycles per test, are needed")
    if few.any():
        sigma[few] = math.sqrt(np.sum(dof[~few] * sigma[~few] ** 2) / np.sum(dof[~few]))

    # Errors in variables: the recorded a = a_true + n carries noise the force does not, and within
    # a sine test Me is told from Ke only by a's small harmonics, where that noise weighs most, so
    # least squares pulls Me toward zero. E[W] gains C = E[zw_n zw_n'] (_noise_moments: the noise
    # through the a column, through y = F - m_payload*a, and through the effect columns that read
    # a, such as the specimen's base shear). C is subtracted, scaled down where it would take more
    # than 1 - NOISE_KEEP of what the other columns leave unexplained in a (noise_factor); the
    # residual's own share of the noise, v'Cv with v = (1, -mu0) at the pooled coefficients, is put back into
    # the (y, y) cell, so that the plug-in sigma_j stays that of the real residual. (The fit does
    # the same: inference._statistics.acceleration_noise_correction.) Measured on an independent
    # generator's series (0.05 m/s^2 accelerometer noise at 200 Hz): without it the per-test Me
    # of its slow sines came out at 30-65 % of the truth, and with separate spreads for (Me, Ke)
    # the population Me 20 % low.
    corrections: list[np.ndarray | None] = [None] * J
    for j in range(J):
        C = moments[j]
        if C is None or C[1, 1] <= 0.0:
            continue
        factor = noise_factor(W[j], C)
        if factor <= 1e-3:
            continue
        corrections[j] = factor * C
        W[j] -= corrections[j]
    # population values with no spread first: they set the spread's scale s*|mu|
    mu0 = _pieces(W, n_pairs, sigma, np.zeros(p), prior_sd)[-1]
    v = np.concatenate([[1.0], -mu0])
    for j, C in enumerate(corrections):
        if C is not None:
            W[j][0, 0] += v @ C @ v
    cache = {}

    def evaluate(pair):
        if pair not in cache:
            group = np.array([pair[0], pair[0], pair[1], pair[1]])
            rho = np.concatenate([group * np.abs(mu0[:4]), np.zeros(p - 4)])
            cache[pair] = (_pieces(W, n_pairs, sigma, rho, prior_sd), rho)
        return cache[pair][0][0]

    if spread is not None:
        pair = (float(spread), float(spread)) if np.isscalar(spread) else tuple(float(x) for x in spread)
    else:
        # one spread for all four first, then each group in turn (coordinate ascent on the grid)
        pair = max(((g, g) for g in SPREAD_GRID), key=evaluate)
        pair = (min(pair[0], INERTIA_STIFFNESS_SPREAD_GRID[-1]), pair[1])
        for _ in range(2):
            pair = max(((pair[0], g) for g in SPREAD_GRID), key=evaluate)
            pair = max(((g, pair[1]) for g in INERTIA_STIFFNESS_SPREAD_GRID), key=evaluate)
    evaluate(pair)
    (log_marginal, c, h, H, Q, r, A, b, B_inv, mu), rho = cache[pair]
    s = pair

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
    # the tests' own scatter of the score (cluster-robust "sandwich"): psi_j = h_j - H_j mu is
    # test j's gradient at the pooled mu, and sum_j psi_j psi_j' replaces the model's sum_j H_j,
    # J/(J-1) for the few tests there are
    psi = h - np.einsum("jkl,l->jk", H, mu)
    meat = np.einsum("ji,jk->ik", psi, psi) * J / max(J - 1, 1)
    theta = theta_scaled * to_si
    residuals = tuple(y - th @ X for y, X, th in zip(ys, Xs, theta))
    return ModelFit(
        terms=terms, names=names, mu=mu * to_si, mu_sd=np.sqrt(np.diag(mu_cov)) * to_si,
        mu_sandwich_sd=np.sqrt(np.maximum(np.diag(mu_cov @ meat @ mu_cov), 0.0)) * to_si,
        theta=theta,
        alpha=float(alpha), spread=s, phi=phi, sigma=sigma * y_scale,
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
