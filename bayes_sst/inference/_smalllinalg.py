"""Cholesky factorisation and triangular solves of small SPD matrices, unrolled.

LAPACK on CPU handles a batch of 4x4 matrices one call at a time, which costs far more
than the arithmetic; written out entry by entry, XLA fuses the whole batch into a few
vector kernels. Shapes: matrices (..., n, n), vectors (..., n), with n small and static.
Every function takes the array namespace `xp` (jax.numpy inside the sampler, numpy for
post-processing, where compiling would cost more than it saves).
"""

from __future__ import annotations

import jax.numpy as jnp


def cholesky(A, xp=jnp):
    """Lower-triangular L with L L' = A (A symmetric positive definite)."""
    n = A.shape[-1]
    L = [[None] * n for _ in range(n)]
    zero = xp.zeros_like(A[..., 0, 0])
    for j in range(n):
        s = A[..., j, j]
        for k in range(j):
            s = s - L[j][k] * L[j][k]
        L[j][j] = xp.sqrt(s)
        for i in range(j + 1, n):
            s = A[..., i, j]
            for k in range(j):
                s = s - L[i][k] * L[j][k]
            L[i][j] = s / L[j][j]
    rows = [xp.stack([L[i][j] if j <= i else zero for j in range(n)], axis=-1) for i in range(n)]
    return xp.stack(rows, axis=-2)


def solve_lower(L, b, xp=jnp):
    """x with L x = b (forward substitution); b (..., n) or, several columns, (..., n, m)."""
    n = L.shape[-1]
    many = b.ndim == L.ndim
    x = []
    for i in range(n):
        s = b[..., i, :] if many else b[..., i]
        for k in range(i):
            coefficient = L[..., i, k][..., None] if many else L[..., i, k]
            s = s - coefficient * x[k]
        diagonal = L[..., i, i][..., None] if many else L[..., i, i]
        x.append(s / diagonal)
    return xp.stack(x, axis=-2 if many else -1)


def solve_upper_transposed(L, b, xp=jnp):
    """x with L' x = b (back substitution on the transpose of a lower factor)."""
    n = L.shape[-1]
    x = [None] * n
    for i in reversed(range(n)):
        s = b[..., i]
        for k in range(i + 1, n):
            s = s - L[..., k, i] * x[k]
        x[i] = s / L[..., i, i]
    return xp.stack(x, axis=-1)


def cho_solve(L, b, xp=jnp):
    """x with (L L') x = b, b (..., n)."""
    return solve_upper_transposed(L, solve_lower(L, b, xp), xp)


def log_det_from_cholesky(L, xp=jnp):
    """log|A| = 2 sum log diag(L)."""
    return 2.0 * xp.sum(xp.log(xp.diagonal(L, axis1=-2, axis2=-1)), axis=-1)
