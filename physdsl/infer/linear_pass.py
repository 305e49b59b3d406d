"""The posterior pass of a Laplace fit's draws from its predictions' line, where that line holds.

A MAP fit's draws are Gaussian about a mode: x = m + S z. Its predictions are read off
2 dim + 1 rollouts, the mode and one posterior sd either side along each column of S: the
central differences give the line p(z) = p(0) + D z, and the same rollouts give each
column's second difference, the curve that the line leaves out. Where that curve stays below
``CURVE_TOL`` noise sds at every measurement, and the draws farthest out (``CHECKED`` of them,
rolled out exactly) agree with the line within ``CHECK_TOL`` noise sds, every other draw's
predictions are the line's and its log-likelihood is read off them (no physics): 2 dim + 1 +
``CHECKED`` rollouts a mode instead of one a draw. Elsewhere (a contact that starts or ends
within the posterior's spread, a wrapped angle, a likelihood that leaves out contact pairs)
the caller rolls out every draw (``output.posterior_pass``).

Measured (``benchmarks/diagnosis.py``): the sliding ball's 500 draws a fit cost 22 ms each,
the pendulum's 10 ms; here 11 to 21 rollouts a fit.
"""
from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from ..compile import PRED_PREFIX
from .left_out import REACHED_SITE
from .threads import split, thread_map, workers

CURVE_TOL = 5e-3  # noise sds: the largest second-order term at one posterior sd accepted
BIAS_TOL = 0.1  # nats: the most the line may take off a draw's expected log-likelihood
CHECK_TOL = 0.1  # noise sds: the most a far-out draw's line may differ from its rollout
# (about 3.5 posterior sds out: the curve alone may reach 12 x CURVE_TOL there)
CHECKED = 4  # draws rolled out exactly per mode, those farthest from it (largest |z|)
CHUNK = 64  # draws per call of the compiled read-off (one compile for any number of draws)


def linearised_pass(model, problem, flat: np.ndarray, means: np.ndarray, sqrts: np.ndarray
                    ) -> tuple[dict, dict] | None:
    """(sites, pointwise log-likelihood) of each draw of ``flat`` (chains, samples, dim),
    chain c drawn as ``means[c] + sqrts[c] @ z``, as ``output.posterior_pass`` returns them
    (draws in chain order), from each mode's line; None where some mode's line does not hold
    there (or the likelihood checks contact pairs that it leaves out: ``left_out``)."""
    if problem.draw is None or model.ruled_out:
        return None
    chains, samples, dim = flat.shape
    sites = [None] * chains
    for group in _same_gaussian(means, sqrts):
        rows = flat[group].reshape(-1, dim)
        out = _pass(model, problem, rows, means[group[0]], sqrts[group[0]])
        if out is None:
            return None
        for k, c in enumerate(group):
            sites[c] = jax.tree_util.tree_map(lambda a: a[k * samples:(k + 1) * samples], out)
    return jax.tree_util.tree_map(lambda *a: np.concatenate(a), *sites)


def _same_gaussian(means, sqrts) -> list[list[int]]:
    """Chains grouped by their Gaussian (equal mode and square root: the chains that took
    the best mode share it)."""
    groups: list[list[int]] = []
    for c in range(len(means)):
        for g in groups:
            if np.array_equal(means[g[0]], means[c]) and np.array_equal(sqrts[g[0]], sqrts[c]):
                g.append(c)
                break
        else:
            groups.append([c])
    return groups


def _pass(model, problem, rows, mean, sqrt):
    """(sites, log-likelihood) of ``rows`` from the line through ``mean``; None where the
    curve or a far-out draw says that the line does not hold."""
    dim = rows.shape[1]
    z = np.linalg.lstsq(sqrt, (rows - mean).T, rcond=None)[0].T  # (n, dim)
    far = np.argsort(-np.linalg.norm(z, axis=1))[:CHECKED]
    points = [mean] + [mean + s * sqrt[:, k] for k in range(dim) for s in (1.0, -1.0)]
    exact = _exact(problem, points + [rows[i] for i in far])
    preds = _preds(model, [e[0] for e in exact])
    centre = jax.tree_util.tree_map(lambda a: a[0], preds)
    plus = jax.tree_util.tree_map(lambda a: a[1:2 * dim + 1:2], preds)
    minus = jax.tree_util.tree_map(lambda a: a[2:2 * dim + 1:2], preds)
    # the curve, in noise sds at the mode's values: half the second difference of the
    # standardised residuals (affine in the predictions at fixed values)
    at_mode = _values(model, [exact[0][0]] * (2 * dim + 1))
    s = _read(model, problem, at_mode, jax.tree_util.tree_map(lambda a: a[:2 * dim + 1], preds))[1]
    curve = 0.5 * (s[1:2 * dim + 1:2] + s[2:2 * dim + 1:2] - 2.0 * s[:1])
    # what the line takes off a draw's expected log-likelihood (normal noise: -s^2 / 2, each
    # s short by curve_k z_k^2, E z_k^2 = 1), in nats: the error an ELPD would carry
    bias = abs(float(np.sum(s[0] * np.sum(curve, axis=0))))
    if (not np.all(np.isfinite(s)) or np.max(np.abs(curve), initial=0.0) > CURVE_TOL
            or bias > BIAS_TOL):
        return None
    slope = jax.tree_util.tree_map(lambda p, m: 0.5 * (p - m), plus, minus)  # (dim, N, D)
    line = jax.tree_util.tree_map(
        lambda c, d: c[None] + np.einsum("nk,k...->n...", z, d), centre, slope)
    values = _values(model, [_constrained(problem, x) for x in rows])
    ll, s_line = _read(model, problem, values, line)
    checked = _values(model, [e[0] for e in exact[2 * dim + 1:]])
    s_far = _read(model, problem, checked, jax.tree_util.tree_map(
        lambda a: a[2 * dim + 1:], preds))[1]
    if not np.all(np.isfinite(s_line)) or np.max(np.abs(s_far - s_line[far]), initial=0.0) > CHECK_TOL:
        return None
    for j, i in enumerate(far):  # the far draws as rolled out
        for name in ll:
            ll[name][i] = exact[2 * dim + 1 + j][1][name]
        for name in line:
            line[name][i] = preds[name][2 * dim + 1 + j]
    keep = set(model.unknown_names)
    out = {k: v for k, v in values.items() if k in keep}
    out.update({PRED_PREFIX + k: v for k, v in line.items()})
    return out, ll


def _exact(problem, xs) -> list:
    """(sites, log-likelihood) of each of ``xs`` through the fit's compiled rollout, from
    ``threads.workers()`` threads."""
    data = problem.data
    return [o for part in thread_map(lambda part: jax.device_get(
        [problem.draw(jnp.asarray(x), data)[:2] for x in part]), split(xs, workers()))
        for o in part]


def _constrained(problem, x) -> dict:
    return jax.device_get(problem.draw.constrain(jnp.asarray(x)))


def _preds(model, sites: list) -> dict:
    """name -> (n, N, D) predictions stacked from draws' sites."""
    return {o.obs.name: np.stack([np.asarray(s[PRED_PREFIX + o.obs.name]) for s in sites])
            for o in model.observed}


def _values(model, sites: list) -> dict:
    """The constrained values (every unknown's, the noise scales' among them) stacked from
    draws' sites (or from ``draw.constrain``'s outputs)."""
    names = [k for k in sites[0] if not k.startswith(PRED_PREFIX) and k != REACHED_SITE]
    return {k: np.stack([np.asarray(s[k]) for s in sites]) for k in names}


def _read(model, problem, values: dict, preds: dict) -> tuple[dict, np.ndarray]:
    """(pointwise log-likelihood by observable, standardised residuals (n, R)) of stacked
    values and predictions: one compiled program, ``CHUNK`` draws a call (the last padded)."""
    fn = model.cached(("linear-read", CHUNK), lambda: jax.jit(jax.vmap(
        lambda v, p, data: (model.pointwise_log_likelihood(v, p, data),
                            model.standardized_residuals(v, p, data)), in_axes=(0, 0, None))))
    n = len(next(iter(preds.values())))
    parts = []
    for i in range(0, n, CHUNK):
        m = min(CHUNK, n - i)
        pad = lambda a: np.concatenate([a[i:i + m], np.repeat(a[i + m - 1:i + m], CHUNK - m, 0)])  # noqa: E731
        out = fn(*jax.tree_util.tree_map(pad, (values, preds)), problem.data)
        parts.append(jax.tree_util.tree_map(lambda a: np.asarray(a)[:m], out))
    ll, s = jax.tree_util.tree_map(lambda *a: np.concatenate(a), *parts)
    return {k: np.array(v) for k, v in ll.items()}, s
