"""Collapsed likelihood of the hierarchical AR(1) force model, in pure JAX.

Model, per test j (scaled units, see _statistics.py):

    y_j = X_j(alpha) theta_j + e_j,     e_jt = phi_j e_j(t-1) + w_jt,   w ~ N(0, sigma_j^2)
    theta_j ~ N(mu, T),  T = diag(rho^2)             (test-to-test variation)
    mu ~ N(m0, S0),      S0 = diag(s0^2)             (population values)

theta_j and mu enter linearly and with Gaussian priors, so both are integrated out exactly
(a Rao-Blackwellised, "collapsed" model): the sampler explores only alpha, rho, phi_j,
sigma_j, and theta_j, mu are drawn afterwards from their exact Gaussian conditionals.

Per test, with A = X'X/sigma^2, b = X'y/sigma^2 (AR-whitened moments), D = diag(rho) and
B = I + D A D (well conditioned for any rho >= 0):

    log p(y_j | mu) = c_j + h_j' mu - 1/2 mu' H_j mu
    c_j = -1/2 log|B| + 1/2 (Db)' B^-1 (Db) - n_j/2 log(2 pi sigma^2) - y'y/(2 sigma^2)
    H_j = A - A D B^-1 D A          (= (A^-1 + T)^-1)
    h_j = b - A D B^-1 D b          (= (I + A T)^-1 b)

and with Q = S0^-1 + sum H_j, r = S0^-1 m0 + sum h_j:

    log p(y | alpha, rho, phi, sigma) = sum c_j - 1/2 log|S0| - 1/2 log|Q|
                                        + 1/2 r' Q^-1 r - 1/2 m0' S0^-1 m0
    mu | rest ~ N(Q^-1 r, Q^-1),   theta_j | mu, rest ~ N(mu + P_j^-1 (b_j - A_j mu), P_j^-1),
    P_j^-1 = D B_j^-1 D.

test_terms evaluates H_j and h_j in forms without the subtractions above (see there), and the
noise sd entering A, b, c is sqrt(sigma^2 + floor^2) (RELATIVE_NOISE_FLOOR). The sampler
differentiates the likelihood through marginal_gradient's closed form (Fisher's identity), not
by tracing the factorisations back.
"""

from __future__ import annotations

from functools import partial
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

import bayes_sst._jaxconfig  # noqa: F401  (float64 before any array)
from bayes_sst.inference import _smalllinalg as sl

LOG_2PI = 1.8378770664093453


DAMPING = 3  # index of the damping column in z = (y, a, u, |v|^alpha sign v, sign v)


class MomentTable(NamedTuple):
    """The lagged moments in the form the likelihood reads them, tests on the last axis.

    Whitening needs only the symmetric lag sums S = (M0, M1 + M1', M2), and only row and
    column DAMPING of them depend on alpha (see _statistics.py for the interpolation):

    constant : (3, 5, 5, J) S with row and column DAMPING zeroed;
    cross : (G-1, 3, 4, 4, J) S of the damping column's four Hermite basis columns with
        (y, a, u, sign), per grid interval;
    gram : (G-1, 3, 4, 4, J) S of the basis columns with each other.
    """

    constant: jax.Array
    cross: jax.Array
    gram: jax.Array
    n_pairs: jax.Array  # (J,)
    alpha_start: float
    alpha_step: float
    noise_floor: float = 0.0  # see RELATIVE_NOISE_FLOOR
    # (J,) (L_j - 1)/L_j of each test's friction load L_j (signals.friction_load); None: all 0
    load_share: jax.Array | None = None


# The payload's friction. The Coulomb column of test j is L_j*filter(sign v), with L_j the
# bearing-load ratio the table description gives (signals.friction_load); the model lets the
# data scale the description's payload increase by a gain kappa (the sampled site
# payload_friction_gain), so that test j's Coulomb column becomes
#
#     (1 + kappa (L_j - 1)) filter(sign v) = s_j L_j filter(sign v),   s_j = 1 + (kappa - 1) w_j,
#     w_j = (L_j - 1)/L_j,
#
# and every lag sum's row and column SIGN is multiplied by s_j: S_j -> E_j S_j E_j with
# E_j = diag(1, 1, 1, 1, s_j). kappa = 1 is the description's physics (Fmu = mu_e (F_hd + m g));
# a simulator or table whose friction ignores the hold-down force has kappa = (F_hd + m g)/(m g),
# one whose friction ignores the payload has kappa = 0.
SIGN = 4  # index of the Coulomb column in z


def load_share(friction_load):
    """w_j = (L_j - 1)/L_j of bearing-load ratios L_j (signals.friction_load)."""
    return 1.0 - 1.0 / np.asarray(friction_load, dtype=float)


def payload_friction_factor(gain, share):
    """s = 1 + (kappa - 1) w: the factor on a Coulomb column L filter(sign v) that makes it
    (1 + kappa (L - 1)) filter(sign v), w = load_share(L)."""
    return 1.0 + (gain - 1.0) * share


def friction_factors(table: MomentTable, gain, xp=jnp):
    """s_j = 1 + (kappa - 1) w_j, (J,) (or (draws, J) for a gain per draw (draws,))."""
    if table.load_share is None:
        return None
    return payload_friction_factor(xp.asarray(gain)[..., None], table.load_share)


def _sign_column(factors, size: int = 5):
    """The diagonal of E, (size, [draws,] J): 1 in every row but SIGN, which holds the factors."""
    unit = np.zeros(size)
    unit[SIGN] = 1.0
    return 1.0 + _trailing(unit, 1 + factors.ndim) * (factors - 1.0)


def _scaled_sign(S, factors, xp):
    """S (..., 5, 5, [draws,] J) with its row and column SIGN multiplied by the factors
    ([draws,] J): E S E."""
    if factors is None:
        return S
    column = _sign_column(factors, S.shape[-2 - factors.ndim])
    return S * column[:, None] * column[None, :]


# The likelihood's noise sd is sqrt(sigma^2 + floor^2), floor = this share of the RMS force.
# Why: the collapsed terms subtract moment sums of order (force/noise)^2 * n, so their
# precision falls with the square of the signal-to-noise ratio; measured on the virtual table
# with 10 N of white force noise (1.6 N after the low-pass, 3e-5 of the RMS force) the
# population draws came out 100-4700 % off while 30 N (8e-5) was still right. A floor of 1e-4
# of the RMS force keeps every fit on the right side of that and widens no realistic one:
# at the twin's default noise (about 3e-3 of the RMS force after the low-pass) it changes the
# noise variance by 0.1 %.
RELATIVE_NOISE_FLOOR = 1e-4


def compact_table(moments, damping_cross, damping_gram, n_pairs, alpha_grid, xp=jnp,
                  noise_floor: float = 0.0, friction_load=None) -> MomentTable:
    """MomentTable from lagged moments (J, G, 3, 5, 5) and the damping cells (J, G-1, 3, 4, 4)
    of a LaggedMoments; friction_load (J,) the tests' L_j (None: no payload's friction)."""
    from bayes_sst.inference._statistics import symmetric_lag_sums

    alpha_grid = np.asarray(alpha_grid, dtype=float)
    constant = symmetric_lag_sums(np.asarray(moments, dtype=float)[:, 0])
    constant[..., DAMPING, :] = 0.0
    constant[..., :, DAMPING] = 0.0
    return MomentTable(
        constant=xp.asarray(np.moveaxis(constant, 0, -1)),
        cross=xp.asarray(np.moveaxis(np.asarray(damping_cross, dtype=float), 0, -1)),
        gram=xp.asarray(np.moveaxis(np.asarray(damping_gram, dtype=float), 0, -1)),
        n_pairs=xp.asarray(np.asarray(n_pairs, dtype=float)),
        alpha_start=float(alpha_grid[0]),
        alpha_step=float(alpha_grid[1] - alpha_grid[0]),
        noise_floor=float(noise_floor),
        load_share=None if friction_load is None else xp.asarray(load_share(friction_load)),
    )


def moment_table(lagged, xp=jnp) -> MomentTable:
    """MomentTable from a LaggedMoments (whose response is scaled by the RMS force, so that the
    noise floor is RELATIVE_NOISE_FLOOR in its units)."""
    return compact_table(lagged.moments, lagged.damping_cross, lagged.damping_gram, lagged.n_pairs,
                         lagged.alpha_grid, xp, noise_floor=RELATIVE_NOISE_FLOOR,
                         friction_load=getattr(lagged, "friction_load", None))


class TestTerms(NamedTuple):
    """Per-test Gaussian pieces of the collapsed likelihood (see module docstring); tests last."""

    __test__ = False  # not a pytest class

    c: jax.Array  # (J,)
    h: jax.Array  # (4, J)
    H: jax.Array  # (4, 4, J)
    A: jax.Array  # (4, 4, J)
    b: jax.Array  # (4, J)
    B_chol: jax.Array  # (4, 4, J)
    B_inverse: jax.Array  # (4, 4, J)


def _hermite_position(table: MomentTable, alpha, xp):
    """Grid interval g of alpha and s = (alpha - alpha_g)/step, its place in it."""
    position = (alpha - table.alpha_start) / table.alpha_step
    g = xp.clip(xp.floor(position).astype(xp.int32), 0, table.cross.shape[0] - 1)
    return g, position - g


def hermite_weights(table: MomentTable, alpha, xp=jnp):
    """Grid interval g, the cubic-Hermite weights at alpha and their alpha-derivatives: with
    s = (alpha - alpha_g)/step, M(alpha) = h00 M_g + h10 step M'_g + h01 M_(g+1) + h11 step M'_(g+1)."""
    g, s = _hermite_position(table, alpha, xp)
    s2, s3 = s * s, s * s * s
    weights = xp.stack([2 * s3 - 3 * s2 + 1, s3 - 2 * s2 + s, -2 * s3 + 3 * s2, s3 - s2])
    slopes = xp.stack([6 * s2 - 6 * s, 3 * s2 - 4 * s + 1, 6 * s - 6 * s2, 3 * s2 - 2 * s]) / table.alpha_step
    return g, weights, slopes


def whitened_moments(moments, phi, xp=jnp):
    """W_j = M0 - phi (M1 + M1') + phi^2 M2: moments of z_t - phi z_(t-1), (5, 5, J)."""
    m0, m1, m2 = moments[0], moments[1], moments[2]
    return m0 - phi * (m1 + xp.swapaxes(m1, 0, 1)) + phi * phi * m2


def _trailing(x, ndim: int):
    """x with unit axes appended up to ndim axes: a per-draw or per-coefficient array made to
    broadcast against arrays with the tests (and draws) last."""
    return x.reshape(x.shape + (1,) * (ndim - x.ndim))


def _cell_contractions(table: MomentTable, g, many: bool, xp):
    """The contractions of the basis columns' lag sums in alpha's grid cells g with a vector w of
    Hermite weights (4,), or (4, draws) where many: cross(w) = sum_k w_k S(K_k, o), (3, 4, *batch)
    for o = (y, a, u, sign); gram(w) = S(K, K) w, (3, 4, *batch); quadratic(v, gram(w)) = v'S(K, K) w,
    (3, *batch)."""
    cell_cross, cell_gram = table.cross[g], table.gram[g]  # (3, 4, 4, J), or (draws, 3, 4, 4, J)
    if many:  # one alpha per draw (the posterior's draws, in numpy): einsum is 3x faster
        return (lambda w: xp.einsum("kd,dlkmj->lmdj", w, cell_cross, optimize=True),
                lambda w: xp.einsum("dlkmj,md->lkdj", cell_gram, w, optimize=True),
                lambda v, gram_w: xp.einsum("lkdj,kd->ldj", gram_w, v, optimize=True))
    # contractions as broadcast sums: XLA fuses these into loops over the tests, where its
    # batched dot products of 4x4 blocks cost several times more on CPU
    return (lambda w: xp.sum(w[None, :, None, None] * cell_cross, axis=1),
            lambda w: xp.sum(cell_gram * w[None, None, :, None], axis=2),
            lambda v, gram_w: xp.sum(gram_w * v[None, :, None], axis=1))


def damping_rows(table: MomentTable, alpha, xp=jnp):
    """Row DAMPING of the lag sums S_l(alpha) and its alpha-derivative, each (3, 5, J), or
    (3, 5, draws, J) for alpha (draws,): the damping column is interpolated as
    d = sum_k w_k K_k, so its row is sum_k w_k S(K_k, .) and its diagonal w' S(K, K) w (see
    MomentTable)."""
    g, weights, slopes = hermite_weights(table, alpha, xp)
    cross, gram, quadratic = _cell_contractions(table, g, bool(xp.ndim(alpha)), xp)
    gram_weights = gram(weights)
    others, d_others = cross(weights), cross(slopes)  # (y, a, u, sign)
    diagonal, d_diagonal = quadratic(weights, gram_weights), 2.0 * quadratic(slopes, gram_weights)

    def row(o, diag):
        return xp.stack([o[:, 0], o[:, 1], o[:, 2], diag, o[:, 3]], axis=1)

    return row(others, diagonal), row(d_others, d_diagonal)


def lag_sums_at(table: MomentTable, alpha, xp=jnp, gain=1.0):
    """S_l(alpha), l = 0, 1, 2, as (3, 5, 5, J): W = S0 - phi S1 + phi^2 S2, with the payload's
    friction gain `gain` (friction_factors)."""
    S = _with_rows(table.constant, [(DAMPING, damping_rows(table, alpha, xp)[0])])
    return _scaled_sign(S, friction_factors(table, gain, xp), xp)


def _lagged(S, phi):
    """S0 - phi S1 + phi^2 S2 of a (3, ..., J) stack."""
    return S[0] - phi * (S[1] - phi * S[2])


def whitened_at(table: MomentTable, alpha, phi, xp=jnp, gain=1.0):
    """W_j(alpha, phi_j) = S0 - phi_j S1 + phi_j^2 S2 at alpha, (5, 5, J)."""
    return _lagged(lag_sums_at(table, alpha, xp, gain), phi)


# A test's own damping exponent. The population's alpha is shared, but the damping law of a real
# table is a power law only approximately, and tests that sweep different speed ranges read
# different exponents from it. To first order in a test's deviation delta_j,
#
#     Ce_j |v|^(alpha + delta_j) sign v  ~  Ce_j d(alpha) + c_j d'(alpha),   c_j = Ce_j delta_j,
#
# with d' = d(|v|^alpha sign v)/d alpha = |v|^alpha log|v| sign v, which the Hermite interpolation
# gives exactly as the slope-weighted sum of the same basis columns (d' = sum_k w'_k K_k). With
# c_j ~ N(0, rho_d^2) (rho_d = tau |Ce|, tau the between-test sd of the exponent) the extended
# moments z = (y, a, u, d, sign, d') are reduced to those of (y, a, u, d, sign) by integrating c_j
# out (absorb_deviation), and the rest of the likelihood is as before.
DEVIATION = 5  # index of d' in the extended z


def hermite_curvatures(table: MomentTable, alpha, xp=jnp):
    """The second alpha-derivatives of hermite_weights' weights, (4, *alpha.shape)."""
    _, s = _hermite_position(table, alpha, xp)
    return xp.stack([12 * s - 6, 6 * s - 4, 6 - 12 * s, 6 * s - 2]) / (table.alpha_step * table.alpha_step)


def deviation_rows(table: MomentTable, alpha, xp=jnp):
    """Rows DAMPING and DEVIATION of the extended lag sums (3, 6, *batch) and their
    alpha-derivatives, batch = (J,) or (draws, J) for alpha (draws,).

    With w, w', w'' the Hermite weights and their alpha-derivatives, C = S(K, o) the basis
    columns' lag sums with o = (y, a, u, sign) and G = S(K, K):

        row d  = (C w, w'Gw, C w (sign), w'G w'),    row d' = (C w', 0, C w' (sign), w''G w'),
        d/dalpha row d  = (C w', 2 w'G w', C w' (sign), w''G w' + w'G w''),
        d/dalpha row d' = (C w'', 0, C w'' (sign), 2 w''G w'')

    (the (d, d') entry is carried by row d only, the zero in row d' keeps it from counting twice).
    """
    g, weights, slopes = hermite_weights(table, alpha, xp)
    curvatures = hermite_curvatures(table, alpha, xp)
    cross, gram, quadratic = _cell_contractions(table, g, bool(xp.ndim(alpha)), xp)
    c_w, c_s, c_c = cross(weights), cross(slopes), cross(curvatures)
    g_s, g_c = gram(slopes), gram(curvatures)
    wGs, sGs, wGc, sGc = quadratic(weights, g_s), quadratic(slopes, g_s), quadratic(weights, g_c), quadratic(slopes, g_c)
    wGw = quadratic(weights, gram(weights))
    zero = xp.zeros_like(wGw)

    def row(o, d_entry, deviation_entry):
        return xp.stack([o[:, 0], o[:, 1], o[:, 2], d_entry, o[:, 3], deviation_entry], axis=1)

    return (row(c_w, wGw, wGs), row(c_s, zero, sGs),
            row(c_s, 2.0 * wGs, sGs + wGc), row(c_c, zero, 2.0 * sGc))


def _with_rows(base, rows):
    """base (3, n, n, J) (zero in the rows set) with each (index, row) of rows set as a row and
    column, row (3, n, *batch), batch = (J,) or (draws, J)."""
    n, n_batch = base.shape[1], rows[0][1].ndim - 2
    out = base.reshape(base.shape[:3] + (1,) * (n_batch - 1) + base.shape[3:])
    for index, row in rows:
        unit = np.zeros(n)
        unit[index] = 1.0
        e_row, e_col = _trailing(unit, 2 + n_batch), _trailing(unit[None], 2 + n_batch)
        out = out + e_row * row[:, None] + e_col * row[:, :, None] - e_row * e_col * row[:, index][:, None, None]
    return out


def extended_lag_sums(table: MomentTable, alpha, xp=jnp, gain=1.0, with_slope: bool = False):
    """The lag sums of z = (y, a, u, d, sign, d') at alpha, (3, 6, 6, *batch), and with_slope
    the alpha-derivatives of their rows DAMPING and DEVIATION too, (3, 6, *batch) each (the
    payload's friction gain scaling all, friction_factors; the derivative of the (d, d') entry
    is in the first only, see deviation_rows)."""
    row_d, row_deviation, slope_d, slope_deviation = deviation_rows(table, alpha, xp)
    base = xp.pad(table.constant, ((0, 0), (0, 1), (0, 1), (0, 0)))
    factors = friction_factors(table, gain, xp)
    S = _scaled_sign(_with_rows(base, [(DAMPING, row_d), (DEVIATION, row_deviation)]), factors, xp)
    if not with_slope:
        return S
    if factors is not None:
        column = _sign_column(factors, 6)
        slope_d, slope_deviation = slope_d * column, slope_deviation * column
    return S, (slope_d, slope_deviation)


def absorb_deviation(extended, noise, deviation_spread, xp=jnp):
    """Integrate each test's deviation coefficient c_j ~ N(0, rho_d^2) out of its whitened
    extended moments W (6, 6, *batch): with P = W[:5, :5], q = W[:5, d'], w = W[d', d'],
    s the noise sd,

        p(y | theta) = integral N(y - X theta - c d') N(c; 0, rho_d^2) dc
        -> W_reduced = P - q q' / r,   r = w + s^2 / rho_d^2,
           log-likelihood + extra,     extra = -1/2 log(1 + rho_d^2 w / s^2)

    (completing the square in c). Returns W_reduced (5, 5, *batch), extra (*batch) and
    (q, r, w) for absorb_deviation_gradient."""
    var = noise * noise
    spread = xp.maximum(deviation_spread, SPREAD_FLOOR)
    P, q, w = extended[:5, :5], extended[:5, DEVIATION], extended[DEVIATION, DEVIATION]
    r = w + var / (spread * spread)
    reduced = P - q[:, None] * q[None, :] / r
    extra = -0.5 * xp.log1p(spread * spread * w / var)
    return reduced, extra, (q, r, w)


def absorb_deviation_gradient(d_reduced, parts, noise, deviation_spread, xp=jnp):
    """Given G = dl/dW_reduced (5, 5, J), the derivative of l + sum extra (absorb_deviation) with
    respect to the extended W (6, 6, J), the noise sd (J,) and rho_d:

        dl/dP = G,   dl/dq = -2 G q / r,   dl/dr = q'Gq / r^2,
        d extra/dw = -1/(2r),   d extra/ds^2 = w / (2 s^2 r),   d extra/drho_d = -w / (rho_d r),
        dr/dw = 1,   dr/ds^2 = 1/rho_d^2,   dr/drho_d = -2 s^2 / rho_d^3

    (q enters W twice, as row and as column, so each of its two entries in W gets -G q / r)."""
    q, r, w = parts
    var = noise * noise
    spread = xp.maximum(deviation_spread, SPREAD_FLOOR)
    Gq = xp.sum(d_reduced * q[None, :], axis=1)  # (5, J)
    qGq = xp.sum(q * Gq, axis=0)
    d_r = qGq / (r * r)
    column = -Gq / r
    corner = d_r - 0.5 / r
    d_extended = xp.concatenate([
        xp.concatenate([d_reduced, column[:, None]], axis=1),
        xp.concatenate([column[None], corner[None, None]], axis=1),
    ], axis=0)
    d_var = d_r / (spread * spread) + 0.5 * w / (var * r)
    d_spread = xp.sum(-2.0 * var * d_r / (spread * spread * spread) - w / (spread * r))
    d_spread = xp.where(deviation_spread >= SPREAD_FLOOR, d_spread, 0.0)
    return d_extended, 2.0 * noise * d_var, d_spread


# spreads below this (scaled units, i.e. relative to the prior centre) are raised to it inside
# test_terms, so that D is invertible; a coefficient shared by all tests (spread 0) then varies
# by 1e-4 % between tests, far below any posterior sd
SPREAD_FLOOR = 1e-6


def test_terms(whitened, n_pairs, sigma, rho, xp=jnp) -> TestTerms:
    """c_j, h_j, H_j of the module docstring, for all tests at once (tests last; whitened may
    carry a draws axis before the tests, (5, 5, draws, J), with rho (4, draws)).

    With L the Cholesky factor of B, Y = L^-1 (so B^-1 = Y'Y) and g = L^-1 D b:

        H = D^-1 (I - B^-1) D^-1,   h = D^-1 B^-1 D b,   (Db)' B^-1 (Db) = g'g.

    Algebraically H = A - A D B^-1 D A and h = b - A D B^-1 D b, but those differences cancel
    two numbers of order A ~ (force/noise)^2 n where the data pin a test's coefficients far
    beyond the between-test spread (D A D >> I), and a force recorded ~1e4 times above its
    noise gave population draws off by a factor of ten; in the forms used here B^-1 is small
    in those directions, and the cancellation moves to the directions the data hardly inform,
    where it costs nothing.
    """
    var = sigma * sigma
    yy = whitened[0, 0]
    A = whitened[1:, 1:] / var
    b = whitened[1:, 0] / var
    rho = _trailing(xp.maximum(rho, SPREAD_FLOOR), A.ndim - 1)  # (4, [draws,] 1)
    eye = _trailing(xp.eye(4), A.ndim)
    DA = rho[:, None] * A
    B = eye + DA * rho[None, :]
    B_chol = sl.cholesky(B, xp)
    Db = rho * b
    identity = xp.broadcast_to(eye, B.shape)
    Yg = sl.solve_lower(B_chol, xp.concatenate([identity, Db[:, None]], axis=1), xp)
    Y, g = Yg[:, :4], Yg[:, 4]
    B_inverse = xp.sum(Y[:, :, None] * Y[:, None, :], axis=0)
    inverse_rho = 1.0 / rho
    H = (eye - B_inverse) * (inverse_rho[:, None] * inverse_rho[None, :])
    h = xp.sum(B_inverse * Db[None], axis=1) * inverse_rho
    c = (
        -0.5 * sl.log_det_from_cholesky(B_chol, xp)
        + 0.5 * xp.sum(g * g, axis=0)
        - 0.5 * n_pairs * (LOG_2PI + 2.0 * xp.log(sigma))
        - 0.5 * yy / var
    )
    return TestTerms(c=c, h=h, H=H, A=A, b=b, B_chol=B_chol, B_inverse=B_inverse)


def population_posterior(terms: TestTerms, prior_mean, prior_sd, xp=jnp):
    """Q and r of the Gaussian conditional mu | rest ~ N(Q^-1 r, Q^-1); (4, 4, [draws]) and
    (4, [draws])."""
    prior_precision = 1.0 / (prior_sd * prior_sd)
    n_batch = terms.h.ndim - 2  # 1 with a draws axis
    Q = _trailing(xp.diag(prior_precision), 2 + n_batch) + xp.sum(terms.H, axis=-1)
    r = _trailing(prior_precision * prior_mean, 1 + n_batch) + xp.sum(terms.h, axis=-1)
    return Q, r


def _noise_sd(table: MomentTable, sigma, xp):
    """The likelihood's noise sd sqrt(sigma^2 + floor^2) (RELATIVE_NOISE_FLOOR)."""
    return xp.sqrt(sigma * sigma + table.noise_floor * table.noise_floor)


def _reduced_whitened(table, alpha, phi, sigma, xp, gain, deviation):
    """The whitened moments the test terms read (5, 5, *batch), the noise sd, the extra
    log-likelihood per test and absorb_deviation's (q, r, w): plain (0 and None), or with each
    test's deviation coefficient integrated out."""
    noise = _noise_sd(table, sigma, xp)
    if deviation is None:
        return whitened_at(table, alpha, phi, xp, gain), noise, 0.0, None
    extended = _lagged(extended_lag_sums(table, alpha, xp, gain), phi)
    spread = xp.asarray(deviation)
    spread = spread[..., None] if spread.ndim else spread  # one per draw: broadcast over the tests
    reduced, extra, parts = absorb_deviation(extended, noise, spread, xp)
    return reduced, noise, extra, parts


def _exponents(parts, noise, alpha, coefficients, normal, xp):
    """Each test's own exponent alpha + delta_j given its coefficients (4, [draws,] J), from
    standard normal deviates normal ([draws,] J) (draw_deviations gives the conditional)."""
    q, r, _ = parts
    c = (q[0] - xp.sum(q[1:] * coefficients, axis=0)) / r + noise / xp.sqrt(r) * normal
    return xp.asarray(alpha)[..., None] + c / coefficients[2]


def _symmetric(whitened, xp):
    # the formulas read v'Wv, which only sees W's symmetric part; reading that part explicitly
    # makes marginal_gradient the exact derivative for any W, not only for symmetric ones
    return 0.5 * (whitened + xp.swapaxes(whitened, 0, 1))


def _marginal(whitened, n_pairs, noise, rho, prior_mean, prior_sd, xp):
    """The value, and what marginal_gradient reads: the test terms, the population step's
    Cholesky factor and r, and W's symmetric part."""
    W = _symmetric(whitened, xp)
    terms = test_terms(W, n_pairs, noise, rho, xp)
    Q, r = population_posterior(terms, prior_mean, prior_sd, xp)
    Q_chol = sl.cholesky_by_columns(Q, xp)
    # r' Q^-1 r = |L^-1 r|^2: one triangular solve instead of two
    whitened_r = sl.solve_lower(Q_chol, r, xp)
    prior_precision = 1.0 / (prior_sd * prior_sd)
    value = (
        xp.sum(terms.c)
        - xp.sum(xp.log(prior_sd))
        - 0.5 * sl.log_det_from_cholesky(Q_chol, xp)
        + 0.5 * xp.sum(whitened_r * whitened_r)
        - 0.5 * xp.sum(prior_precision * prior_mean * prior_mean)
    )
    return value, terms, Q_chol, r, W


def marginal_log_likelihood(whitened, n_pairs, noise, rho, prior_mean, prior_sd, xp=jnp):
    """log p(y | W, noise, rho) of the module docstring from the whitened moments W (5, 5, J),
    the likelihood's noise sd (J,) and the between-test sds rho (4,), every theta_j and mu
    integrated out."""
    return _marginal(whitened, n_pairs, noise, rho, prior_mean, prior_sd, xp)[0]


def marginal_gradient(whitened, n_pairs, noise, rho, prior_mean, prior_sd, xp=jnp):
    """marginal_log_likelihood and its gradient with respect to W, the noise sd, the spreads and
    the population prior, in closed form (n_pairs is data).

    Fisher's identity: the gradient of log p(y | psi) is the posterior expectation of the
    gradient of the complete-data log density log p(y, theta, mu | psi), and with every piece
    Gaussian those expectations are exact. With the posterior moments of the coefficients

        mu | y ~ N(mu_bar, Q^-1),                mu_bar = Q^-1 r,
        E[theta_j] = m_j = mu_bar + D u_j,       u_j = B^-1 D (b_j - A_j mu_bar),
        Cov[theta_j] = D (B^-1 + B^-1 D^-1 Q^-1 D^-1 B^-1) D,
        v_j = (1, -theta_j),  E[v v'] = [[1, -m'], [-m, m m' + Cov]],

    and log p(y_j | theta_j) = -n_j/2 log(2 pi s_j^2) - v_j' W_j v_j / (2 s_j^2) (s_j the noise sd):

        dl/dW_j   = -E[v_j v_j'] / (2 s_j^2)
        dl/ds_j   = -n_j / s_j + tr(W_j E[v_j v_j']) / s_j^3
        dl/drho_k = (1/rho_k) sum_j (E[(theta_jk - mu_k)^2] / rho_k^2 - 1),
            E[(theta_j - mu)(theta_j - mu)'] / (rho rho') = B^-1 + u u' + M Q^-1 M' on the
            diagonal, M = B^-1 D A  (theta_j - mu = -D M mu + D B^-1 D b + noise given y)
        dl/dm0    = (mu_bar - m0) / s0^2
        dl/ds0    = -1/s0 + ((mu_bar - m0)^2 + diag Q^-1) / s0^3

    Why: reverse-mode differentiation of the unrolled 4x4 Cholesky factorisations and solves
    is a long chain of small operations per test; measured at 200 tests it cost 280 us per
    gradient against 58 us for the value, and most of NUTS's time. A spread below SPREAD_FLOOR
    (a shared coefficient) gets a zero gradient, as the floor's maximum gives it.

    Returns (value, (dW, ds, drho, dm0, ds0)).
    """
    var = noise * noise
    value, terms, Q_chol, r, W = _marginal(whitened, n_pairs, noise, rho, prior_mean, prior_sd, xp)
    scale = xp.maximum(rho, SPREAD_FLOOR)
    Q_root_inverse = sl.solve_lower(Q_chol, xp.eye(4), xp)  # L^-1, Q^-1 = L^-T L^-1
    Q_inverse = xp.sum(Q_root_inverse[:, :, None] * Q_root_inverse[:, None, :], axis=0)
    mu_bar = xp.sum(Q_inverse * r[None, :], axis=1)

    B_inverse = terms.B_inverse
    residual = terms.b - xp.sum(terms.A * mu_bar[None, :, None], axis=1)  # b - A mu_bar, (4, J)
    u = xp.sum(B_inverse * (scale[:, None] * residual)[None], axis=1)
    mean = mu_bar[:, None] + scale[:, None] * u
    scaled_Q_inverse = Q_inverse / (scale[:, None] * scale[None, :])
    # products of (4, 4, J) stacks as broadcast sums: XLA fuses these into one loop over the
    # tests, where einsum's batched 4x4 dot products cost several times more on CPU
    BS = xp.sum(B_inverse[:, :, None, :] * scaled_Q_inverse[None, :, :, None], axis=1)
    BSB = xp.sum(BS[:, :, None, :] * B_inverse[None, :, :, :], axis=1)
    covariance = (B_inverse + BSB) * (scale[:, None] * scale[None, :])[:, :, None]
    second = mean[:, None, :] * mean[None, :, :] + covariance
    n_tests = W.shape[-1]
    outer = xp.concatenate([
        xp.concatenate([xp.ones((1, 1, n_tests)), -mean[None]], axis=1),
        xp.concatenate([-mean[:, None], second], axis=1),
    ], axis=0)  # E[v v'], (5, 5, J)
    d_whitened = -outer / (2.0 * var)
    expected_square = xp.sum(W * outer, axis=(0, 1))
    d_noise = -n_pairs / noise + expected_square / (var * noise)

    M = xp.sum(B_inverse[:, :, None, :] * (scale[:, None, None] * terms.A)[None], axis=1)
    MQ = xp.sum(M[:, :, None, :] * Q_inverse[None, :, :, None], axis=1)
    spread_term = xp.sum(MQ * M, axis=1)
    diagonal = xp.stack([B_inverse[k, k] for k in range(4)])
    d_scale = xp.sum(diagonal + u * u + spread_term - 1.0, axis=-1) / scale
    d_rho = xp.where(rho >= SPREAD_FLOOR, d_scale, 0.0)

    offset = mu_bar - prior_mean
    prior_var = prior_sd * prior_sd
    d_prior_mean = offset / prior_var
    d_prior_sd = -1.0 / prior_sd + (offset * offset + xp.stack([Q_inverse[k, k] for k in range(4)])) / (prior_var * prior_sd)
    return value, (d_whitened, d_noise, d_rho, d_prior_mean, d_prior_sd)


def _collapsed_value(table: MomentTable, alpha, rho, phi, sigma, prior_mean, prior_sd, xp, gain=1.0, deviation=None):
    whitened, noise, extra, _ = _reduced_whitened(table, alpha, phi, sigma, xp, gain, deviation)
    return marginal_log_likelihood(whitened, table.n_pairs, noise, rho, prior_mean, prior_sd, xp) + xp.sum(extra)


def collapsed_gradient(table: MomentTable, alpha, rho, phi, sigma, prior_mean, prior_sd, xp=jnp, gain=1.0,
                       deviation=None):
    """collapsed_log_likelihood and its gradient with respect to (alpha, rho, phi, sigma,
    prior_mean, prior_sd, gain, deviation). With G_j = dl/dW_j (marginal_gradient) and the lag sums
    S_l(alpha) (their row and column SIGN scaled by s_j, friction_factors):

        dl/dphi_j   = sum_ab G_j,ab (2 phi_j S2 - S1)_ab
        dl/dalpha   = sum_j sum_ab G_j,ab dW_j,ab/dalpha    (only row and column DAMPING move)
        dl/dsigma_j = dl/ds_j * sigma_j / s_j,   s_j = sqrt(sigma_j^2 + floor^2)
        dl/dkappa   = sum_j w_j (2/s_j) sum_b G_j,SIGN b W_j,SIGN b

    (W_j = E_j W0_j E_j, so dW_j/ds_j is row and column SIGN of W_j divided by s_j, the corner
    counted twice.)

    With a deviation spread rho_d the same formulas run on the extended moments (DEVIATION),
    G_j coming through absorb_deviation_gradient; deviation None gives a zero derivative for it.
    """
    if deviation is not None:
        return _extended_gradient(table, alpha, rho, phi, sigma, prior_mean, prior_sd, xp, gain, deviation)
    rows, d_rows = damping_rows(table, alpha, xp)
    factors = friction_factors(table, gain, xp)
    S = _scaled_sign(_with_rows(table.constant, [(DAMPING, rows)]), factors, xp)
    noise = _noise_sd(table, sigma, xp)
    W = _lagged(S, phi)
    value, (d_W, d_noise, d_rho, d_prior_mean, d_prior_sd) = marginal_gradient(
        W, table.n_pairs, noise, rho, prior_mean, prior_sd, xp)
    d_phi = xp.sum(d_W * (2.0 * phi * S[2] - S[1]), axis=(0, 1))
    d_row = _lagged(d_rows, phi)  # row DAMPING of dW/dalpha, (5, J); d_W is symmetric
    if factors is not None:
        d_row = d_row * _sign_column(factors)
    d_alpha = xp.sum(_row_gradient(d_W, d_row, DAMPING, xp))
    return value, (d_alpha, d_rho, d_phi, d_noise * sigma / noise, d_prior_mean, d_prior_sd,
                   _gain_gradient(table, factors, d_W, W, xp), xp.zeros(()))


def _row_gradient(d_W, row, index, xp):
    """sum_ab G_ab dW_ab per test, G = d_W symmetric, for a dW whose only nonzero entries are its
    row and column `index`, both `row` (n, J): the row once, the column once, the diagonal once."""
    return 2.0 * xp.sum(d_W[index] * row, axis=0) - d_W[index, index] * row[index]


def _gain_gradient(table: MomentTable, factors, d_W, W, xp):
    """dl/dkappa = sum_j w_j (2/s_j) sum_b G_j,SIGN b W_j,SIGN b (collapsed_gradient); 0 without loads."""
    if factors is None:
        return xp.zeros(())
    return xp.sum(table.load_share * 2.0 / factors * xp.sum(d_W[SIGN] * W[SIGN], axis=0))


def _extended_gradient(table: MomentTable, alpha, rho, phi, sigma, prior_mean, prior_sd, xp, gain, deviation):
    """collapsed_gradient with each test's deviation coefficient integrated out."""
    S, (slope_d, slope_deviation) = extended_lag_sums(table, alpha, xp, gain, with_slope=True)
    noise = _noise_sd(table, sigma, xp)
    W = _lagged(S, phi)
    reduced, extra, parts = absorb_deviation(W, noise, deviation, xp)
    value, (d_reduced, d_noise, d_rho, d_prior_mean, d_prior_sd) = marginal_gradient(
        reduced, table.n_pairs, noise, rho, prior_mean, prior_sd, xp)
    d_W, d_noise_extra, d_deviation = absorb_deviation_gradient(d_reduced, parts, noise, deviation, xp)
    d_noise = d_noise + d_noise_extra
    d_phi = xp.sum(d_W * (2.0 * phi * S[2] - S[1]), axis=(0, 1))
    # rows DAMPING and DEVIATION move with alpha; the (d, d') pair sits in row d only
    d_alpha = xp.sum(_row_gradient(d_W, _lagged(slope_d, phi), DAMPING, xp)
                     + _row_gradient(d_W, _lagged(slope_deviation, phi), DEVIATION, xp))
    d_gain = _gain_gradient(table, friction_factors(table, gain, xp), d_W, W, xp)
    return value + xp.sum(extra), (d_alpha, d_rho, d_phi, d_noise * sigma / noise, d_prior_mean, d_prior_sd, d_gain,
                                   d_deviation)


def collapsed_log_likelihood(table: MomentTable, alpha, rho, phi, sigma, prior_mean, prior_sd, xp=jnp, gain=1.0,
                             deviation=None):
    """log p(y | alpha, rho, phi, sigma, kappa, rho_d) with every theta_j and mu integrated out
    (scaled units); gain is the payload's friction gain kappa (friction_factors), deviation the
    spread rho_d of each test's deviation coefficient (DEVIATION; None: every test has alpha).

    Under JAX its derivative is collapsed_gradient's closed form rather than reverse-mode
    differentiation of the factorisations (see marginal_gradient for why); the moment table
    itself is data and gets no derivative."""
    if xp is jnp:
        # without loads the gain's scaling is left out of the compiled program altogether
        with_loads = table.load_share is not None
        with_deviation = deviation is not None
        static = (table.alpha_start, table.alpha_step, table.noise_floor, with_loads, with_deviation)
        load_share = table.load_share if with_loads else jnp.zeros_like(table.n_pairs)
        return _collapsed_jax(static, (table.constant, table.cross, table.gram, table.n_pairs, load_share),
                              alpha, rho, phi, sigma, prior_mean, prior_sd, jnp.asarray(gain, dtype=float),
                              jnp.asarray(deviation if with_deviation else 0.0, dtype=float))
    return _collapsed_value(table, alpha, rho, phi, sigma, prior_mean, prior_sd, xp, gain, deviation)


def _table(static, arrays):
    constant, cross, gram, n_pairs, load_share = arrays
    *numbers, with_loads, _ = static
    return MomentTable(constant, cross, gram, n_pairs, *numbers, load_share if with_loads else None)


def _deviation(static, deviation):
    return deviation if static[-1] else None


@partial(jax.custom_vjp, nondiff_argnums=(0,))
def _collapsed_jax(static, arrays, alpha, rho, phi, sigma, prior_mean, prior_sd, gain, deviation):
    return _collapsed_value(_table(static, arrays), alpha, rho, phi, sigma, prior_mean, prior_sd, jnp, gain,
                            _deviation(static, deviation))


def _collapsed_jax_forward(static, arrays, alpha, rho, phi, sigma, prior_mean, prior_sd, gain, deviation):
    value, gradient = collapsed_gradient(_table(static, arrays), alpha, rho, phi, sigma, prior_mean, prior_sd,
                                         jnp, gain, _deviation(static, deviation))
    return value, (gradient, arrays)


def _collapsed_jax_backward(static, saved, cotangent):
    gradient, arrays = saved
    no_derivative = jax.tree.map(jnp.zeros_like, arrays)
    return (no_derivative, *(cotangent * part for part in gradient))


_collapsed_jax.defvjp(_collapsed_jax_forward, _collapsed_jax_backward)


class CoefficientDraws(NamedTuple):
    """What draw_coefficients draws (scaled units): the population values mu ([draws,] 4), each
    test's coefficients theta ([draws,] J, 4), each test's log-likelihood given mu ([draws,] J),
    and, where each test's own exponent was asked for, those exponents ([draws,] J; else None)."""

    mu: np.ndarray
    theta: np.ndarray
    log_likelihood: np.ndarray
    exponents: np.ndarray | None = None


def draw_coefficients(normal_mu, normal_theta, table: MomentTable, alpha, rho, phi, sigma,
                      prior_mean, prior_sd, xp=jnp, gain=1.0, ignored_spread=None, normal_ignored=None,
                      deviation=None, normal_deviation=None):
    """An exact draw of mu (4,) and every theta_j (J, 4) given the sampled parameters, from
    standard normal deviates normal_mu (4,) and normal_theta (J, 4); also the per-test
    log-likelihood log p(y_j | mu, alpha, rho, phi_j, sigma_j), (J,) (scaled units); returned
    as CoefficientDraws.

    Many draws at once: alpha and gain (draws,), rho (4, draws), phi and sigma (draws, J),
    normal_mu (4, draws) and normal_theta (draws, J, 4) give mu (draws, 4), theta
    (draws, J, 4) and the log-likelihood (draws, J).

    theta_j's Coulomb coefficient is that of test j's column s_j L_j filter(sign v)
    (friction_factors): the empty table's friction as the test saw it. With deviation (rho_d,
    one per draw) each test's deviation coefficient is integrated out (absorb_deviation): the
    draws of theta and the log-likelihood are those marginal over it; with normal_deviation
    ([draws,] J) as well, each test's own exponent is drawn given its theta (draw_deviations)
    (CoefficientDraws.exponents).

    ignored_spread (4,) (floats, zeros for none) and normal_ignored (4, [draws,] J): a shared
    coefficient k (rho_k = 0) whose tests may in truth differ by d_jk ~ N(0, (s_k mu_k)^2).
    Such a d_jk moves b_j by A_j e_k d_jk and so mu's mean by Q^-1 H_j e_k d_jk (h_j = (I + A T)^-1 b_j,
    H_j = (I + A T)^-1 A_j), so mu gains sum_j Q^-1 H_j e_k s_k |mu_k| z_jk: the shared fit's
    population value with the spread it left out. Tests that pin coefficient k dominate both
    its value and this term."""
    whitened, noise, extra, parts = _reduced_whitened(table, alpha, phi, sigma, xp, gain, deviation)
    terms = test_terms(whitened, table.n_pairs, noise, rho, xp)
    terms = terms._replace(c=terms.c + extra)
    Q, r = population_posterior(terms, prior_mean, prior_sd, xp)
    Q_chol = sl.cholesky(Q, xp)
    # mu = Q^-1 r + L^-T z has covariance Q^-1
    mu = sl.cho_solve(Q_chol, r, xp) + sl.solve_upper_transposed(Q_chol, normal_mu, xp)
    if ignored_spread is not None:
        for k, relative_sd in enumerate(ignored_spread):
            if relative_sd > 0.0:
                # (4, [draws,] J): how test j's coefficient k moves mu
                response = sl.cho_solve(Q_chol[..., None], terms.H[:, k], xp)
                shift = relative_sd * xp.abs(mu[k])[..., None] * normal_ignored[k]
                mu = mu + xp.sum(response * shift[None], axis=-1)
    per_test_mu = mu[..., None]  # (4, [draws,] 1)
    residual = terms.b - xp.sum(terms.A * per_test_mu[None], axis=1)
    # theta_j = mu + D B^-1 D (b - A mu) + D L^-T z has covariance D B^-1 D
    D = _trailing(rho, per_test_mu.ndim)
    theta = (
        per_test_mu
        + D * sl.cho_solve(terms.B_chol, D * residual, xp)
        + D * sl.solve_upper_transposed(terms.B_chol, xp.moveaxis(normal_theta, -1, 0), xp)
    )
    quadratic = xp.sum(per_test_mu[:, None] * terms.H * per_test_mu[None, :], axis=(0, 1))
    per_test = terms.c + xp.sum(terms.h * per_test_mu, axis=0) - 0.5 * quadratic
    exponents = (None if parts is None or normal_deviation is None
                 else _exponents(parts, noise, alpha, theta, normal_deviation, xp))
    return CoefficientDraws(xp.moveaxis(mu, 0, -1), xp.moveaxis(theta, 0, -1), per_test, exponents)


def draw_deviations(normal, table: MomentTable, alpha, theta, phi, sigma, deviation, xp=np, gain=1.0):
    """Each test's own exponent alpha + delta_j for draws of theta (draws, J, 4) from
    draw_coefficients(..., deviation=deviation), from standard normal deviates normal
    (draws, J); alpha and deviation (draws,), phi and sigma (draws, J). Returns (draws, J).

    Given theta_j, the deviation coefficient c_j = Ce_j delta_j has the Gaussian conditional
    (absorb_deviation's q, r, w of the whitened extended moments, s the noise sd)

        c_j | theta_j, y ~ N((q_y - q_x' theta_j) / r, s^2 / r),

    q_y and q_x the entries of q for y and the four coefficients, so (theta_j, c_j) is a draw
    of their joint posterior; delta_j = c_j / Ce_j. (draw_coefficients draws them in the same
    pass with normal_deviation.)"""
    _, noise, _, parts = _reduced_whitened(table, alpha, phi, sigma, xp, gain, xp.asarray(deviation))
    return _exponents(parts, noise, alpha, xp.moveaxis(theta, -1, 0), normal, xp)
