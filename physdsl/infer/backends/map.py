"""MAP in unconstrained space, with a Laplace approximation for uncertainty.

The optimiser drives one jitted function of the log density, so the physics is compiled once
however many iterations and chains run: Levenberg-Marquardt on the Gauss-Newton program where
the likelihood is least squares (``infer/levenberg_marquardt.py``), else L-BFGS (here, with a
backtracking line search that treats a non-finite log density as a too-long step) on the
value and gradient. The Hessian at the mode comes from central differences of that same
gradient (no second compile). 'Draws' are independent samples of the Gaussian centred at each
chain's mode with the inverse Hessian as covariance, in unconstrained space, so constrained
draws respect supports.
"""
from __future__ import annotations

from functools import partial

import jax
import jax.numpy as jnp
import numpy as np

from ...errors import InferenceError
from ..base import (Backend, gauss_newton_fn, register_backend,  # noqa: F401 - re-exported
                    value_and_grad_fn, value_fn)
from .. import levenberg_marquardt
from ..problem import unconstrained_layout
from ..threads import thread_map


def find_mode(problem, x0, steps: int = 300) -> np.ndarray:
    """Maximise the log density from ``x0``; returns the best point found. By Levenberg-Marquardt
    where the likelihood is least squares (``Problem.gauss_newton``), else by L-BFGS."""
    gn = gauss_newton_fn(problem)
    if gn is not None:
        return levenberg_marquardt.run(gn, x0, steps, value_fn(problem))
    return lbfgs(value_and_grad_fn(problem), x0, steps)


def lbfgs(vg, x0, steps: int = 300, memory: int = 10) -> np.ndarray:
    """Maximise the log density ``vg`` (x -> value, gradient) from ``x0`` by L-BFGS; returns
    the best point found.

    The line search backtracks (halving) until the step lands where the log density is
    finite and rises enough (Armijo): a rollout that turns NaN past some edge of the
    parameter space (``sqrt`` of a negative drag) only shortens the step. (scipy's L-BFGS-B
    stops at once there, reporting convergence at its starting point.) The first step has
    unit length; later steps use the curvature pairs, so no scale needs to be known. A step
    along which the log density is not concave clears the pairs (they came from elsewhere:
    kept, they let the search crawl through such a region with steps of millimetres).
    """
    def neg(x):
        v, g = vg(jnp.asarray(x))
        v = float(v)
        return (-v, -np.asarray(g, dtype=float)) if np.isfinite(v) else (np.inf, None)

    x = np.asarray(x0, dtype=float)
    fx, gx = neg(x)
    if not np.isfinite(fx):
        return x
    pairs: list[tuple[np.ndarray, np.ndarray]] = []
    for _ in range(steps):
        d = -_two_loop(gx, pairs)
        slope = float(gx @ d)
        if slope >= 0:  # not a descent direction: forget the curvature, go downhill
            pairs.clear()
            d = -gx / max(np.linalg.norm(gx), 1e-300)
            slope = float(gx @ d)
        t = 1.0
        for _ in range(60):
            xn = x + t * d
            fn, gn = neg(xn)
            if np.isfinite(fn) and fn <= fx + 1e-4 * t * slope:
                break
            t *= 0.5
        else:
            break  # no step improves: at a mode (to rounding) or against an edge
        s, y = xn - x, gn - gx
        if s @ y > 1e-12 * np.linalg.norm(s) * np.linalg.norm(y):
            pairs = (pairs + [(s, y)])[-memory:]
        else:  # no positive curvature along the step (a non-concave region): the stored
            pairs.clear()  # pairs describe another region; kept, they shrink every later step
        # converged when a step gains less than 1e-10 of the log density (relative; 1e-6 on a
        # fit of a thousand points: far below any statistical meaning) or the slope vanishes.
        # Tighter, a contact rollout's rounding noise keeps the search stepping to its budget.
        done = fx - fn <= 1e-10 * max(1.0, abs(fx)) or np.max(np.abs(gn)) < 1e-7
        x, fx, gx = xn, fn, gn
        if done:
            break
    return x


def _two_loop(g, pairs):
    """L-BFGS inverse-Hessian times ``g`` from curvature pairs (unit-length step without any)."""
    if not pairs:
        return g / max(np.linalg.norm(g), 1e-300)
    q = g.copy()
    alphas = []
    for s, y in reversed(pairs):
        rho = 1.0 / (y @ s)
        a = rho * (s @ q)
        alphas.append((rho, a, s, y))
        q = q - a * y
    s, y = pairs[-1]
    q = q * (s @ y) / (y @ y)
    for rho, a, s, y in reversed(alphas):
        q = q + s * (a - rho * (y @ q))
    return q


def find_modes(problem, positions, steps: int = 300, on_mode=None) -> jnp.ndarray:
    """``find_mode`` from each row of ``positions``, except rows that are modes already found
    on this Problem's data (``remember_modes``: the multistart's), kept as they are
    (optimising them again cost a Gauss-Newton evaluation or more per chain: a minute on a
    contact scene). ``on_mode(1)`` after each (progress)."""
    modes = []
    for x in np.asarray(positions, dtype=float):
        modes.append(x if known_mode(problem, x) is not None else find_mode(problem, x, steps))
        if on_mode is not None:
            on_mode(1)
    return jnp.asarray(np.stack(modes))


def remember_modes(problem, modes, lps) -> None:
    """Mark ``modes`` (with log densities ``lps``) as optimised on ``problem``'s data, so a
    later ``find_modes`` there keeps them. Kept in the Problem's cache, tied to its data
    object: the cache is shared by every Model of one structure, and another dataset's modes
    are not modes here. A record per dataset, the ``REMEMBERED_DATASETS`` latest, so a fit
    to other data between (refine's leave-future-out fit) does not erase this one's."""
    record = {np.asarray(m, dtype=float).tobytes(): float(lp) for m, lp in zip(modes, lps)}
    others = [(d, r) for d, r in problem.cache.get(FOUND_MODES, []) if d is not problem.data]
    problem.cache[FOUND_MODES] = (others + [(problem.data, record)])[-REMEMBERED_DATASETS:]


def known_mode(problem, x) -> float | None:
    """The log density of ``x`` where it is a mode remembered on this Problem's data, else None."""
    return _remembered(problem).get(np.asarray(x, dtype=float).tobytes())


def best_known_mode(problem) -> np.ndarray | None:
    """The remembered mode (``remember_modes``) with the highest log density on this
    Problem's data, or None where none is remembered there."""
    finite = {k: lp for k, lp in _remembered(problem).items() if np.isfinite(lp)}
    if not finite:
        return None
    return np.frombuffer(max(finite, key=finite.get), dtype=float).copy()


def _remembered(problem) -> dict:
    """The remembered modes (flat bytes -> log density) of this Problem's data; empty where
    none were remembered on it (or its record has aged out)."""
    for data, record in problem.cache.get(FOUND_MODES, []):
        if data is problem.data:
            return record
    return {}


FOUND_MODES = "modes-found"  # problem.cache key of ``remember_modes``: [(data, record)]
REMEMBERED_DATASETS = 4  # datasets whose modes a structure's cache keeps (the latest)


MINOR_MODE = 10.0  # log-density units below the best mode: a basin with a negligible share


def major_modes(problem, modes, lps=None) -> tuple[np.ndarray, np.ndarray, int]:
    """(modes, log densities, index of the best) where every mode more than ``MINOR_MODE``
    below the best (or non-finite) is replaced by the best. ``lps``: the modes' log
    densities where the caller has them already (each costs a rollout).

    Such a basin holds a negligible share of the posterior (e^-10 at its peak), yet a chain
    started there stays: on contact scenes an optimisation from a prior draw can settle on a
    kink (a block whose friction makes it stick cannot feel a change of mu). Shared by MAP's
    Laplace mixture and by the starts of every sampler (``infer.run``)."""
    modes = np.array(modes, dtype=float)  # a writable copy
    if lps is None:
        vg = value_and_grad_fn(problem)
        lps = [float(vg(jnp.asarray(m))[0]) for m in modes]
    lps = np.array(lps, dtype=float)
    lps = np.where(np.isfinite(lps), lps, -np.inf)
    best = int(np.argmax(lps))
    minor = lps < lps[best] - MINOR_MODE
    modes[minor], lps[minor] = modes[best], lps[best]
    return modes, lps, best


class LaplaceError(InferenceError):
    """The log density is not strictly concave at the mode: no Laplace approximation there.

    ``directions``: each flat or non-concave eigen-direction of the Hessian as (curvature,
    [(coordinate name, weight), ...] largest first); ``mode`` and ``log_density``: the point
    (flat, unconstrained) where it failed, set by the backend, so a caller can keep it."""

    def __init__(self, message, span=None, hint=None, source=None, directions=()):
        super().__init__(message, span, hint, source)
        self.directions = list(directions)
        self.mode = None
        self.log_density = None


MAIN_COMPONENT = 0.3  # |weight| of a coordinate in a unit eigen-direction worth naming


def laplace_sqrt(problem, mode) -> np.ndarray:
    """A square root S of the Laplace covariance at ``mode`` (S S^T = inverse negative Hessian).

    The Hessian is taken by central differences of the gradient. Where those find a direction
    flat or curving upwards, a least-squares scene takes the Gauss-Newton curvature instead
    (``gauss_newton_sqrt``): differences across a kink of the rollout (Coulomb friction
    reversing, a contact switching) give no curvature, while the data's Fisher information
    J^T J does. A direction flat in that too (an unknown the data do not determine) has no
    Laplace approximation: LaplaceError names each such direction by the unknowns that make
    it up, with its curvature.
    """
    vg = value_and_grad_fn(problem)
    mode = np.asarray(mode, dtype=float)
    d = mode.size
    h = 1e-5 * np.maximum(1.0, np.abs(mode))
    H = np.zeros((d, d))
    steps = [sign * h[i] * np.eye(d)[i] for i in range(d) for sign in (1.0, -1.0)]

    def grad(e):
        return np.asarray(vg(jnp.asarray(mode + e))[1])

    # the first compiles where the fit did not; the rest side by side (``threads``)
    g = [grad(steps[0])] + thread_map(grad, steps[1:])
    for i in range(d):
        H[:, i] = -(g[2 * i] - g[2 * i + 1]) / (2 * h[i])
    H = 0.5 * (H + H.T)
    if not np.all(np.isfinite(H)):
        raise LaplaceError(f"the log density's curvature at the mode is not finite in "
                           f"{int((~np.isfinite(H)).any(axis=0).sum())} of {d} coordinates: "
                           "no Laplace approximation", hint=LAPLACE_HINT)
    S, w, v, bad = _inverse_sqrt(H)
    if S is None:
        fisher = gauss_newton_sqrt(problem, mode)
        if fisher is not None:
            return fisher
        names = coordinate_names(problem)
        directions = [(float(w[k]), _components(v[:, k], names)) for k in np.flatnonzero(bad)]
        words = "; ".join(f"{_direction_words(c)} (curvature {cw:.3g})"
                          for cw, c in directions)
        raise LaplaceError(f"the log density is not strictly concave at the mode along "
                           f"{int(bad.sum())} of {d} directions: no Laplace approximation. "
                           f"Flat or not concave along: {words}", hint=LAPLACE_HINT,
                           directions=directions)
    return S


def _inverse_sqrt(H):
    """(S with S S^T = H^-1, or None where the symmetric H is not positive enough to invert;
    its eigenvalues w and vectors v; the mask of eigenvalues flat within 1e-10 of the largest,
    curving up, or not finite)."""
    w, v = np.linalg.eigh(H)
    bad = ~np.isfinite(w) | (w <= 1e-10 * max(float(np.max(np.abs(w), initial=0.0)), 1e-300))
    ok = not bad.any() and np.all(np.isfinite(v))
    return (v / np.sqrt(w) if ok else None), w, v, bad


def gauss_newton_sqrt(problem, mode) -> np.ndarray | None:
    """S with S S^T the inverse Gauss-Newton curvature (J^T J plus the prior's Hessian) at
    ``mode``; None where the likelihood is not least squares or that curvature is flat too."""
    gn = gauss_newton_fn(problem)
    if gn is None:
        return None
    H = np.asarray(gn(jnp.asarray(mode))[2], dtype=float)
    H = 0.5 * (H + H.T)
    if not np.all(np.isfinite(H)):
        return None
    return _inverse_sqrt(H)[0]


LAPLACE_HINT = ("to sample the posterior from this mode instead, add `--fallback rmh` to "
                "`infer --backend map` (random-walk Metropolis, as `refine` does; in Python "
                "physdsl.infer(model, 'map', fallback='rmh')), or sample with --backend nuts; or "
                "give the unknowns named above a value or a tighter prior")


def coordinate_names(problem) -> list[str]:
    """The unknown (and component) each flat unconstrained coordinate belongs to."""
    if problem.model is None:  # a bare log density (tests)
        return [f"x[{i}]" for i in range(problem.dim)]
    names = []
    for path, leaf in jax.tree_util.tree_flatten_with_path(unconstrained_layout(problem.model))[0]:
        name = getattr(path[0], "key", str(path[0]))  # the flat vector's order
        size = int(np.prod(leaf.shape))
        names += [name] if leaf.shape == () else [
            f"{name}[{', '.join(map(str, np.unravel_index(i, leaf.shape)))}]" for i in range(size)]
    return names


def _components(vec, names) -> list[tuple[str, float]]:
    """(name, weight) of a unit direction's main components, largest first (at least one)."""
    order = np.argsort(-np.abs(vec))
    keep = [i for i in order if abs(vec[i]) >= MAIN_COMPONENT] or [int(order[0])]
    return [(names[i] if i < len(names) else f"x[{i}]", float(vec[i])) for i in keep]


def _direction_words(components) -> str:
    if len(components) == 1:
        return components[0][0]
    return " + ".join(f"{w:+.2f}·{n}" for n, w in components).replace("+ -", "- ")


@register_backend
class MAP(Backend):
    name = "map"

    def warmup(self, problem, positions, key, settings, on_block=None, on_laplace=None):
        """One optimisation per chain, then (``on_laplace()`` called as it begins) a Laplace
        approximation at each mode.

        A chain that ended far below the best mode (more than ``MINOR_MODE`` in log density:
        a basin with a negligible share of the posterior, e.g. a start that settled on a
        contact's kink) or at a point with no Laplace approximation takes the best mode
        instead; only a best mode without one is an error."""
        steps = max(settings.warmup, 50)  # one optimisation per start: on_block(1) after each
        modes = np.asarray(find_modes(problem, positions, steps, on_block))
        known = [known_mode(problem, m) for m in modes]  # the multistart's: values known
        value = value_fn(problem)
        lps = [float(value(jnp.asarray(m))) if lp is None else lp for m, lp in zip(modes, known)]
        modes, lps, best = major_modes(problem, modes, lps=lps)
        if on_laplace is not None:
            on_laplace()
        try:
            chol_best = laplace_sqrt(problem, modes[best])  # even the best has none: an error
        except LaplaceError as err:  # the caller may keep the mode
            err.mode, err.log_density = np.asarray(modes[best]), float(lps[best])
            raise
        chols = []
        for i, m in enumerate(modes):
            chol = chol_best
            if not np.array_equal(m, modes[best]):
                try:
                    chol = laplace_sqrt(problem, m)
                except LaplaceError:
                    modes[i], lps[i] = modes[best], lps[best]
            chols.append(chol)
        return (jnp.asarray(modes), {"chol": jnp.asarray(np.stack(chols))},
                {"log_density_at_mode": lps})

    paced = False  # independent draws in one cheap call: no need to cut them by time
    default_samples = 250  # independent draws: 4 x 250 give the effective sample size that
    # MCMC needs 2000 correlated draws for (5-95% quantiles to ~0.07 sd), and each costs a
    # rollout in the posterior pass (chain_hit: 65 of its 176 s with 4 x 500)

    def gaussian(self, states, params):
        return np.asarray(states), np.asarray(params["chol"])

    def sample(self, problem, states, params, key, n, settings, start=0):
        states = jnp.asarray(states)
        z = _normals(key, start, states.shape[0], n, states.shape[1])
        draws = states[:, None, :] + jnp.einsum("cij,cnj->cni", jnp.asarray(params["chol"]), z)
        return states, draws, {}


NORMALS_BLOCK = 256  # draws per call of the compiled normals: its shape depends on dim alone


def _normals(key, start, chains: int, n: int, dim: int):
    """Standard normals (chains, n, dim): draw j of chain c from fold_in(split(key)[c], j).

    Each draw's numbers depend on its chain and number alone, so they are made in blocks of
    ``NORMALS_BLOCK`` (chain key, number) pairs, the last padded: one compiled program per
    ``dim`` serves every number of chains and draws (threefry compiles in about a second)."""
    chain_keys = np.asarray(jax.random.split(key, chains))
    c = np.repeat(np.arange(chains), n)
    j = int(start) + np.tile(np.arange(n), chains)
    total = c.size
    pad = -total % NORMALS_BLOCK
    c, j = np.concatenate([c, np.zeros(pad, int)]), np.concatenate([j, np.zeros(pad, int)])
    blocks = [np.asarray(_normal_block(chain_keys[c[i:i + NORMALS_BLOCK]],
                                       j[i:i + NORMALS_BLOCK], dim))
              for i in range(0, c.size, NORMALS_BLOCK)]  # (numpy: no op-by-op compiles)
    return np.concatenate(blocks)[:total].reshape(chains, n, dim)


@partial(jax.jit, static_argnums=2)
def _normal_block(keys, index, dim: int):
    """Standard normals (len(index), dim): row i from fold_in(keys[i], index[i])."""
    return jax.vmap(lambda k, i: jax.random.normal(jax.random.fold_in(k, i), (dim,)))(
        keys, index.astype(jnp.uint32))
