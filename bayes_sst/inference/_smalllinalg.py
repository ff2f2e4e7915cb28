"""Cholesky factorisation and triangular solves of small SPD matrices, unrolled.

LAPACK on CPU handles a batch of 4x4 matrices one call at a time, which costs far more
than the arithmetic; written out entry by entry, XLA fuses the whole batch into a few
vector kernels. The batch axes come LAST: matrices are (n, n, *batch), vectors (n, *batch),
so that every entry A[i, j] is one contiguous batch vector. Every function takes the array
namespace `xp` (jax.numpy inside the sampler, numpy for post-processing, where compiling
would cost more than it saves).
"""

from __future__ import annotations

import jax.numpy as jnp


def cholesky(A, xp=jnp):
    """Lower-triangular L with L L' = A (A symmetric positive definite), (n, n, *batch)."""
    n = A.shape[0]
    L = [[None] * n for _ in range(n)]
    zero = xp.zeros_like(A[0, 0])
    for j in range(n):
        s = A[j, j]
        for k in range(j):
            s = s - L[j][k] * L[j][k]
        L[j][j] = xp.sqrt(s)
        for i in range(j + 1, n):
            s = A[i, j]
            for k in range(j):
                s = s - L[i][k] * L[j][k]
            L[i][j] = s / L[j][j]
    return xp.stack([xp.stack([L[i][j] if j <= i else zero for j in range(n)]) for i in range(n)])


def cholesky_by_columns(A, xp=jnp):
    """Lower-triangular L with L L' = A for ONE small SPD matrix (n, n), column by column:

        v_j = A[:, j] - sum_{k<j} L[j, k] L[:, k],   L[:, j] = v_j / sqrt(v_j[j]) below the diagonal.

    For a single matrix there is no batch to vectorise, and the entry-by-entry form of
    `cholesky` becomes dozens of scalar operations (and as many again in the gradient) that XLA
    compiles one by one; as n-vector operations the same factorisation compiles in about a
    third of the time. (LAPACK compiles faster still, but made JAX crash while writing the
    persistent compilation cache.)
    """
    n = A.shape[0]
    below = xp.arange(n)
    columns = []
    for j in range(n):
        v = A[:, j]
        for k in range(j):
            v = v - columns[k][j] * columns[k]
        columns.append(xp.where(below >= j, v, 0.0) / xp.sqrt(v[j]))
    return xp.stack(columns, axis=1)


def solve_lower(L, b, xp=jnp):
    """x with L x = b (forward substitution); b (n, *batch) or, several columns, (n, m, *batch)."""
    n = L.shape[0]
    many = b.ndim == L.ndim
    x = []
    for i in range(n):
        s = b[i]
        for k in range(i):
            s = s - (L[i, k][None] if many else L[i, k]) * x[k]
        x.append(s / (L[i, i][None] if many else L[i, i]))
    return xp.stack(x)


def solve_upper_transposed(L, b, xp=jnp):
    """x with L' x = b (back substitution on the transpose of a lower factor); b (n, *batch)."""
    n = L.shape[0]
    x = [None] * n
    for i in reversed(range(n)):
        s = b[i]
        for k in range(i + 1, n):
            s = s - L[k, i] * x[k]
        x[i] = s / L[i, i]
    return xp.stack(x)


def cho_solve(L, b, xp=jnp):
    """x with (L L') x = b, b (n, *batch)."""
    return solve_upper_transposed(L, solve_lower(L, b, xp), xp)


def log_det_from_cholesky(L, xp=jnp):
    """log|A| = 2 sum log diag(L), (*batch)."""
    return 2.0 * sum(xp.log(L[i, i]) for i in range(L.shape[0]))
