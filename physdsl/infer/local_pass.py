"""The posterior pass of a Laplace fit's draws from an expansion of their predictions about
each mode, where the expansion holds.

A MAP fit's draws are Gaussian about a mode: x = m + S z. Its predictions are read off
2 dim + 1 rollouts, the mode and ``STEP`` posterior sds either side along each column of S:
their differences give each direction's slope and curve, p(z) = p(0) + sum_k (D_k z_k +
C_k z_k^2), exact for a prediction that is quadratic along each direction. What they cannot
see (terms in two directions at once, a contact that starts between the points) the draws
farthest from the mode show: ``CHECKED`` of them are rolled out, and where their predictions
differ from the expansion by more than ``CHECK_TOL`` noise sds, or their log-likelihoods by
more than ``CHECK_LL_TOL`` nats, or a curve exceeds ``CURVE_TOL`` noise sds at one posterior
sd, the expansion is declined and the caller rolls out every draw (``output.posterior_pass``).
Otherwise every draw's predictions are the expansion's and its log-likelihood is read off them
by one small compiled program (no physics): 2 dim + 1 + ``CHECKED`` rollouts a mode instead of
one a draw.

Where the likelihood leaves out contact pairs the recording rules out (``left_out``: every
draw must stay out of their reach), the rolled-out points' clearances (``Model.
left_out_clearance``) stand for the draws': the expansion holds only where each is positive
and the mode's exceeds ``REACH_MARGIN`` times the most the clearance can fall at the farthest
draw by its slope and curve along the directions (|slope| |z| + max |curve| |z|^2). The
damped chain passes (its links 17.7 cm beyond reach at the mode, 26 um nearer at 2e-4 rad
more starting angle); a ball that grazes a ground left out is rolled out draw by draw.
"""
from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from ..ahead import Program
from ..compile import PRED_PREFIX
from .left_out import CLEARANCE_SITE
from .problem import drawn

STEP = 2.0  # posterior sds from the mode to the points along each direction: nonlinearity
# within about 95% of the draws along it is seen by the curve
CURVE_TOL = 0.05  # noise sds: the largest curve (the z_k^2 term) accepted, at one posterior sd
CHECKED = 4  # draws rolled out exactly per mode: those farthest from it (largest |z|)
CHECK_TOL = 0.05  # noise sds: the most a checked draw's predictions may differ from the
# expansion (at about 3.5 sds out, where a term in two directions is 12x its size at 1 sd)
CHECK_LL_TOL = 1.0  # nats: the most a checked draw's log-likelihood (all measurements) may
# differ; 12x smaller at a draw 1 sd out, the error an ELPD would carry
REACH_MARGIN = 2.0  # how many times the clearance's largest fall across the draws (by the
# expansion of the clearance itself) the mode's clearance must exceed
CHUNK = 64  # draws per call of the compiled read-off (one compile for any number of draws)


def local_pass(model, problem, flat: np.ndarray, means: np.ndarray, sqrts: np.ndarray
               ) -> tuple[dict, dict] | None:
    """(sites, pointwise log-likelihood) of each draw of ``flat`` (chains, samples, dim),
    chain c drawn as ``means[c] + sqrts[c] @ z``, as ``output.posterior_pass`` returns them
    (draws in chain order), from each mode's expansion; None where some mode's expansion does
    not hold (or, where the likelihood leaves contact pairs out, the draws may reach them)."""
    chains, samples, dim = flat.shape
    if problem.draw is None or dim == 0:
        return None
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
    """(sites, log-likelihood) of ``rows`` from the expansion about ``mean``; None where a
    curve or a checked draw says that it does not hold (every prediction is checked, those
    the likelihood masks too)."""
    dim = rows.shape[1]
    z = np.linalg.lstsq(sqrt, (rows - mean).T, rcond=None)[0].T  # (n, dim)
    far = np.argsort(-np.linalg.norm(z, axis=1))[:CHECKED]
    points = [mean] + [mean + s * STEP * sqrt[:, k] for k in range(dim) for s in (1.0, -1.0)]
    exact = drawn(problem, points + [rows[i] for i in far])
    m = 2 * dim + 1
    if model.ruled_out and not _clear_of_left_out(exact, m, z):
        return None
    preds = _preds(model, [e[0] for e in exact])
    slope, curve = {}, {}
    for name, p in preds.items():
        slope[name], curve[name] = _slope_curve(p, m)
    # every prediction in noise sds (the masked ones too: a leave-future-out fit's later
    # times are scored from them, ``diagnose.lfo``), at the mode's noise scales
    scale = _read(model, problem, _values(model, [exact[0][0]]),
                  {k: v[:1] for k, v in preds.items()})[1]
    sds = {k: np.min(v[0]) for k, v in scale.items()}
    curve_sds = max(np.max(np.abs(curve[k])) / sds[k] for k in preds)
    if not np.isfinite(curve_sds) or curve_sds > CURVE_TOL:
        return None
    expanded = {k: preds[k][0][None] + np.einsum("nk,k...->n...", z, slope[k])
                + np.einsum("nk,k...->n...", z ** 2, curve[k]) for k in preds}
    values = _values(model, [_constrained(problem, x) for x in rows])
    ll = _read(model, problem, values, expanded)[0]
    miss = max(np.max(np.abs(preds[k][m:] - expanded[k][far])) / sds[k] for k in preds)
    ll_far = np.array([sum(np.sum(e[1][k]) for k in ll) for e in exact[m:]])
    ll_rows = sum(v[far].sum(axis=-1) for v in ll.values())
    if (not np.isfinite(miss) or miss > CHECK_TOL
            or np.max(np.abs(ll_far - ll_rows), initial=0.0) > CHECK_LL_TOL):
        return None
    for j, i in enumerate(far):  # the checked draws as rolled out
        for name in ll:
            ll[name][i] = exact[m + j][1][name]
        for name in expanded:
            expanded[name][i] = preds[name][m + j]
    keep = set(model.unknown_names)
    out = {k: v for k, v in values.items() if k in keep}
    out.update({PRED_PREFIX + k: v for k, v in expanded.items()})
    return out, ll


def _slope_curve(p, m: int):
    """Each direction's slope and curve (per posterior sd, and per sd squared) of a quantity
    ``p`` stacked over the points (the mode, then + and - ``STEP`` sds along each direction;
    ``m`` of them): the central differences of the expansion."""
    plus, minus = p[1:m:2], p[2:m:2]
    return (plus - minus) / (2.0 * STEP), (plus + minus - 2.0 * p[:1]) / (2.0 * STEP ** 2)


def _clear_of_left_out(exact, m: int, z) -> bool:
    """Whether every draw ``z`` (n, dim) stays clear of the pairs the likelihood leaves out, by
    the clearances of the rolled-out points ``exact`` (the mode, the 2 dim points along the
    directions, then the checked draws): all positive, and the mode's ``REACH_MARGIN`` times
    beyond the clearance's largest fall by its slope and curve at the farthest draw."""
    c = np.array([float(e[0][CLEARANCE_SITE]) for e in exact])
    if not np.all(c > 0.0):  # (NaN: not clear)
        return False
    slope, curve = _slope_curve(c, m)
    far = float(np.max(np.linalg.norm(z, axis=1), initial=0.0))
    fall = np.linalg.norm(slope) * far + np.max(np.abs(curve), initial=0.0) * far ** 2
    return bool(c[0] > REACH_MARGIN * fall)


def _constrained(problem, x) -> dict:
    return jax.device_get(problem.draw.constrain(jnp.asarray(x)))


def _preds(model, sites: list) -> dict:
    """name -> (n, N, D) predictions stacked from draws' sites."""
    return {o.obs.name: np.stack([np.asarray(s[PRED_PREFIX + o.obs.name]) for s in sites])
            for o in model.observed}


def _values(model, sites: list) -> dict:
    """The constrained values (every unknown's, the noise scales' among them) stacked from
    draws' sites (or from ``draw.constrain``'s outputs)."""
    names = [k for k in sites[0] if not k.startswith(PRED_PREFIX) and k != CLEARANCE_SITE]
    return {k: np.stack([np.asarray(s[k]) for s in sites]) for k in names}


def _read(model, problem, values: dict, preds: dict) -> tuple[dict, dict]:
    """(pointwise log-likelihood by observable, noise scales by observable (n, K)) of stacked
    values and predictions: one compiled program, ``CHUNK`` draws a call (the last padded)."""
    fn = model.cached(("local-read", CHUNK), lambda: Program(jax.vmap(
        lambda v, p, data: (model.pointwise_log_likelihood(v, p, data),
                            {o.obs.name: model.noise_scale(o.obs, v) for o in model.observed}),
        in_axes=(0, 0, None))))
    n = len(next(iter(preds.values())))
    parts = []
    for i in range(0, n, CHUNK):
        m = min(CHUNK, n - i)
        out = fn(*jax.tree_util.tree_map(lambda a: _padded(a[i:i + m]), (values, preds)),
                 problem.data)
        parts.append(jax.tree_util.tree_map(lambda a: np.asarray(a)[:m], out))
    ll, scale = jax.tree_util.tree_map(lambda *a: np.concatenate(a), *parts)
    return {k: np.array(v) for k, v in ll.items()}, scale


def _padded(a):
    """``a`` (m, ...) with its last row repeated to ``CHUNK`` rows."""
    return np.concatenate([a, np.repeat(a[-1:], CHUNK - len(a), 0)])
