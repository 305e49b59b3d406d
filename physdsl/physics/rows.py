"""Row selection and placement by static indices without gather/scatter.

XLA on CPU runs gathers and scatters (and their transposes in gradients) element by element;
for the few static rows a physics step selects, slices and concatenations fuse instead.
"""
from __future__ import annotations

from typing import Sequence

import jax.numpy as jnp


def take(x, idx: Sequence[int]):
    """x[idx] along axis 0 for a static index sequence (a slice when it is a contiguous run)."""
    idx = tuple(int(i) for i in idx)
    if not idx:
        return x[:0]
    if idx == tuple(range(idx[0], idx[0] + len(idx))):
        return x[idx[0]:idx[0] + len(idx)]
    return jnp.stack([x[i] for i in idx])


def place(base, idx: Sequence[int], rows):
    """``base`` with rows idx replaced by ``rows`` (static idx, distinct)."""
    idx = tuple(int(i) for i in idx)
    if idx == tuple(range(base.shape[0])):
        return rows
    where = {b: k for k, b in enumerate(idx)}
    return jnp.stack([rows[where[b]] if b in where else base[b] for b in range(base.shape[0])])


def spread(n: int, idx: Sequence[int], rows):
    """An (n, ...) array with rows[k] added at row idx[k] and zeros elsewhere (static idx)."""
    idx = tuple(int(i) for i in idx)
    if idx == tuple(range(n)):
        return rows
    out = [None] * n
    for k, b in enumerate(idx):
        out[b] = rows[k] if out[b] is None else out[b] + rows[k]
    zero = jnp.zeros(rows.shape[1:], rows.dtype)
    return jnp.stack([zero if r is None else r for r in out])
