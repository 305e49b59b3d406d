"""Multistart mode search: several starts, Levenberg-Marquardt from each, basins reported.

The starts are a start from the data (``data_starts``: initial-state unknowns at what the
first samples say), the prior's centre (the coordinate-wise median of prior draws in
unconstrained space) and prior draws; a given start (``Settings.start``) comes first. Each is
optimised by ``backends.map.find_mode``; the modes are grouped into basins (two modes share a
basin when they lie within ``SAME_BASIN_SD`` Laplace standard deviations of each other, by the
Gauss-Newton curvature of the better one), and each basin is reported with its log density
and residual RMS in noise units. The best mode wins (``backends.map.major_modes``: chains in a
basin far below it move there). A fit that never reaches the basin where a contact seen in
the data happens loses by log density to one that does, once any start gets there: the start
from the data puts the throw where the first samples say, so it does.
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import jax
import jax.numpy as jnp
import numpy as np
from numpyro.infer.util import constrain_fn, potential_energy

from . import levenberg_marquardt as lm
from .backends.map import MINOR_MODE, find_mode, major_modes, remember_modes
from .base import cached, gauss_newton_fn, value_and_grad_fn, value_fn
from .data_starts import data_start
from .problem import prior_draws_unconstrained, unconstrained_layout, unraveler
from .spectral_starts import screened_starts
from .threads import thread_map

SAME_BASIN_SD = 3.0  # modes closer than this many Laplace sd (Mahalanobis) share a basin
CENTRE_DRAWS = 256  # prior draws whose coordinate-wise median is the prior's centre


@dataclass
class Search:
    """Modes (one per chain, minor ones moved to the best), the basins found, the best's index."""

    modes: np.ndarray  # (chains, dim)
    basins: list[dict] = field(default_factory=list)
    best: int = 0


def prior_centre(problem, key) -> np.ndarray:
    """The prior's centre in unconstrained space: the coordinate-wise median of prior draws."""
    return np.median(prior_draws_unconstrained(problem, key, CENTRE_DRAWS), axis=0)


def start_points(problem, positions, key, given: bool = False) -> tuple[np.ndarray, list[str]]:
    """(starts (chains, dim), their labels): row 0 kept where ``given`` (a start the user gave),
    then the start from the data, the prior's centre, and the rows of ``positions`` (finite
    prior draws) in the remaining places, every other one with its initial-state unknowns
    from the data (``_with_data_start``: draws 2, 4, ...; draws 1, 3, ... stay as drawn).
    With the default 4 chains: data, centre, a prior draw, a prior draw thrown as the data
    say. (Draws at the data's frequency come later, in ``search``, where they are needed.)"""
    positions = np.asarray(positions, dtype=float)
    chains = positions.shape[0]
    rows, labels = [], []
    if given:
        rows.append(positions[0])
        labels.append("given")
    centre = prior_centre(problem, key)
    draws = list(positions[1:] if given else positions)
    try:
        from_data = data_start(problem, draws[0] if draws else positions[0], others=(centre,))
    except Exception as err:  # noqa: BLE001 - a helper start: the run goes on without it
        warnings.warn(f"no start from the data ({type(err).__name__}: {err}); starting from "
                      "the prior's centre and draws", stacklevel=2)
        from_data = None
    if from_data is not None:
        rows.append(from_data)
        labels.append("data")
    rows.append(centre)
    labels.append("prior centre")
    for i, d in enumerate(draws):
        mixed = (_with_data_start(problem, d, from_data)
                 if from_data is not None and i % 2 == 1 else None)
        rows.append(d if mixed is None else mixed)
        labels.append(f"prior draw {i + 1}" + ("" if mixed is None else " + data"))
        if len(rows) >= chains:
            break
    return np.stack(rows[:chains]), labels[:chains]


def _screened(problem, key, from_data, n: int) -> list:
    """``spectral_starts.screened_starts`` ([] where it fails: a helper start)."""
    try:
        return screened_starts(problem, jax.random.fold_in(key, 1), from_data, n)
    except Exception as err:  # noqa: BLE001 - the run goes on with prior draws
        warnings.warn(f"no start at the data's frequency ({type(err).__name__}: {err})",
                      stacklevel=2)
        return []


def _with_data_start(problem, draw, from_data):
    """``draw`` with its initial-state unknowns fitted to the first samples (starting that
    small fit at ``from_data``), its other unknowns as drawn; None where that fails.

    In contact scenes the basin is mostly decided by where the bodies start (a throw that
    meets the chain or misses it) and then by the physical unknowns (restitution, friction,
    a mass: a block that sticks or slides). Every start from a plain prior draw throws
    somewhere at random and most end in a basin that misses the contacts seen; the data
    start alone tries one value of the physical unknowns. These starts put the bodies where
    the data say and spread the physical unknowns over their prior."""
    try:
        return data_start(problem, draw, others=(from_data,))
    except Exception:  # noqa: BLE001 - a helper start: the plain draw is used instead
        return None


def search(problem, starts, labels, steps: int, on_start=None, key=None) -> Search:
    """Optimise from every start, group the modes into basins, move minor ones to the best.
    ``on_start(i, label)``: called before start ``i``'s optimisation (progress).

    Where the best mode's residuals stay far above the noise (``RESCREEN_RMS``) and the data
    oscillate, prior draws at the data's frequency (``spectral_starts``, ``key``) are
    optimised too; each that ends better than the worst chain's mode takes that chain. Fits
    that already match the data pay nothing for it (a screen simulates 64 draws)."""
    modes, stopped = _optimised_all(problem, np.asarray(starts), steps, on_start, labels, 0)
    lps, rms, curv = _assess(problem, modes)
    all_modes, all_labels = modes, list(labels)
    extra = _frequency_round(problem, starts, labels, lps, rms, steps, key, on_start)
    if extra is not None:
        extra, extra_stopped = extra
        xl, xr, xc = _assess(problem, extra)
        all_modes = np.concatenate([modes, extra])
        all_labels += [SCREENED] * len(extra)
        stopped = np.concatenate([stopped, extra_stopped])
        lps, rms, curv = np.concatenate([lps, xl]), np.concatenate([rms, xr]), curv + xc
        chains = np.argsort(-lps, kind="stable")[:len(modes)]
        modes, chain_lps = all_modes[chains], lps[chains]
    basins = _cluster(problem, all_modes, lps, rms, curv, all_labels, stopped)
    kept, kept_lps, best = major_modes(problem, modes,
                                       lps=lps if extra is None else chain_lps)
    remember_modes(problem, kept, kept_lps)  # MAP keeps them as its modes (no second search)
    return Search(kept, basins, best)


SCREENED = "prior draw at the data's frequency"
RESCREEN_RMS = 1.5  # best residual RMS (noise units) above which oscillating data are screened
SCREENED_STARTS = 2  # draws at the data's frequency optimised then


ROUND_STEPS = 10  # Levenberg-Marquardt steps each unfinished start takes between two looks


def _optimised_all(problem, xs, steps, on_start, labels, first: int
                   ) -> tuple[np.ndarray, np.ndarray]:
    """(the points reached from starts ``xs`` (numbered from ``first``), which of them were
    stopped short), the starts optimised side by side (``threads``) once the fit's programs
    are compiled (by a value and a curvature at the first start: two threads would each
    compile them).

    Levenberg-Marquardt searches advance in rounds of ``ROUND_STEPS`` steps. Once one has
    converged to a mode that fits the data (residual RMS at most ``RESCREEN_RMS``), every
    search still more than ``MINOR_MODE`` below it stops (the basins list it so): a basin
    above one at the noise level would gain little, and a search below would end as a minor
    mode (which ``major_modes`` replaces by the best) or in the same basin. Where no mode
    fits, every search runs to its end: a better basin is what the other starts are for.
    (The pendulum on a cart: a start from the data crawled its whole step budget, 54 s, to a
    basin at 152 sigma after another start had reached the mode at 1.00 sigma in 5 s.) The
    rounds make the decisions the same whatever the threads' timing. L-BFGS searches (no
    Gauss-Newton curvature, no residual RMS) run whole."""
    xs = np.asarray(xs, dtype=float)
    gn = gauss_newton_fn(problem)
    if len(xs) > 1:
        x0 = jnp.asarray(xs[0])
        if gn is not None:
            value_fn(problem)(x0)
            gn(x0)
        else:
            value_and_grad_fn(problem)(x0)
    if gn is None:
        return np.stack(thread_map(lambda j: _announced(
            on_start, first + j, labels[j], find_mode, problem, xs[j], steps),
            range(len(xs)))), np.zeros(len(xs), bool)
    value = value_fn(problem)
    states = thread_map(lambda j: _announced(on_start, first + j, labels[j], lm.init, gn, xs[j]),
                        range(len(xs)))
    stopped: set[int] = set()
    fitting = -np.inf  # the log density of the best converged mode that fits the data
    while live := [j for j, s in enumerate(states)
                   if not (s.done or s.steps >= steps or j in stopped)]:
        for j, state in zip(live, thread_map(lambda j: _advanced(gn, states[j], value, steps),
                                             live)):
            states[j] = state
            if state.done and state.value > fitting and \
                    residual_rms(problem, state.x, state.value) <= RESCREEN_RMS:
                fitting = state.value
        stopped |= {j for j in live if not states[j].done
                    and states[j].value < fitting - MINOR_MODE}
    return np.stack([s.x for s in states]), np.isin(np.arange(len(xs)), list(stopped))


STOPPED = "stopped far below a mode that fits the data"


def _announced(on_start, i, label, fn, *args):
    """``fn(*args)`` after ``on_start(i, label)`` (progress)."""
    if on_start is not None:
        on_start(i, label)
    return fn(*args)


def _advanced(gn, state, value, steps: int):
    """``state`` after up to ``ROUND_STEPS`` more steps (within ``steps`` in all)."""
    end = min(state.steps + ROUND_STEPS, steps)
    while not state.done and state.steps < end:
        state = lm.step(gn, state, value)
    return state


def _assess(problem, modes):
    """(log densities, residual RMS, Gauss-Newton curvatures or Nones) of ``modes``."""
    gn = gauss_newton_fn(problem)
    if gn is not None:
        evals = [gn(jnp.asarray(m)) for m in modes]
        lps = np.array([float(v) for v, _, _ in evals])
        curv = [np.asarray(H, dtype=float) for _, _, H in evals]
    else:
        vg = value_and_grad_fn(problem)
        lps = np.array([float(vg(jnp.asarray(m))[0]) for m in modes])
        curv = [None] * len(modes)
    lps = np.where(np.isfinite(lps), lps, -np.inf)
    rms = np.array([residual_rms(problem, m, lp) for m, lp in zip(modes, lps)])
    return lps, rms, curv


def _frequency_round(problem, starts, labels, lps, rms, steps, key, on_start):
    """Modes from draws at the data's frequency (``spectral_starts``), or None where the best
    mode fits (RMS at most ``RESCREEN_RMS``, or unknown) or no draw matches. Their initial
    state is the start from the data's, where there is one."""
    if not np.any(np.isfinite(lps)) or not rms[int(np.argmax(lps))] > RESCREEN_RMS:
        return None
    from_data = np.asarray(starts)[labels.index("data")] if "data" in labels else None
    key = jax.random.PRNGKey(0) if key is None else key
    xs = _screened(problem, key, from_data, SCREENED_STARTS)
    if not xs:
        return None
    return _optimised_all(problem, np.asarray(xs), steps, on_start, [SCREENED] * len(xs),
                          len(labels))


def _cluster(problem, modes, lps, rms, curv, labels, stopped) -> list[dict]:
    """Basins, best first: each mode joins the first better basin within ``SAME_BASIN_SD``;
    then the starts with no finite log density, and those stopped short (no mode)."""
    order = [i for i in np.argsort(-lps) if np.isfinite(lps[i]) and not stopped[i]]
    heads: list[int] = []
    members: dict[int, list[int]] = {}
    for i in order:
        home = next((h for h in heads if _same(modes[h], modes[i], curv[h], lps[h], lps[i],
                                               rms[h], rms[i])), None)
        if home is None:
            heads.append(i)
            members[i] = [i]
        else:
            members[home].append(i)
    out = []
    for h in heads:
        out.append({"log_density": float(lps[h]),
                    "rms_sigma": None if not np.isfinite(rms[h]) else float(rms[h]),
                    "starts": [labels[i] for i in members[h]],
                    "values": _scalar_values(problem, modes[h])})
    failed = [labels[i] for i in range(len(modes)) if not np.isfinite(lps[i])]
    if failed:
        out.append({"log_density": None, "rms_sigma": None, "starts": failed, "values": {},
                    "note": "with no finite log density"})
    short = [labels[i] for i in range(len(modes)) if stopped[i] and np.isfinite(lps[i])]
    if short:
        out.append({"log_density": None, "rms_sigma": None, "starts": short, "values": {},
                    "note": STOPPED})
    return out


def _same(a, b, H, lp_a, lp_b, rms_a, rms_b) -> bool:
    d = b - a
    if H is not None and np.all(np.isfinite(H)):
        return float(d @ H @ d) <= SAME_BASIN_SD**2
    # no curvature: the same log density and residual to rounding
    return abs(lp_a - lp_b) <= 1e-6 * max(1.0, abs(lp_a)) and (
        not np.isfinite(rms_a) or abs(rms_a - rms_b) <= 1e-6)


def residual_rms(problem, x, lp=None) -> float:
    """RMS of the standardised residuals at ``x`` (noise units), read off the log density
    where the likelihood is least squares (no rollout beyond the log density's); NaN else."""
    model = problem.model
    if not model.least_squares:
        return float("nan")
    if lp is None:
        lp = float(value_and_grad_fn(problem)(jnp.asarray(x))[0])
    if not np.isfinite(lp):
        return float("nan")
    prior_neg, norm, count = _likelihood_constants(problem)(jnp.asarray(x))
    loglik = lp + float(prior_neg)
    chi2 = -2.0 * (loglik + float(norm))
    return float(np.sqrt(max(chi2, 0.0) / max(float(count), 1.0)))


def _likelihood_constants(problem):
    """Jitted x -> (-log prior, sum of log(sigma sqrt(2 pi)) over measured residuals, their
    number): with them, -2 (log likelihood + the sum) is the residuals' square sum."""
    model = problem.model

    def build():
        unravel, _ = unraveler(unconstrained_layout(model))

        def fn(x, data):
            u = unravel(x)
            values = constrain_fn(model.prior_values, (), {}, u)
            norm, count = 0.0, 0.0
            for o in model.observed:
                m = jnp.asarray(data[o.obs.name]["mask"], dtype=float)
                scale = model.noise_scale(o.obs, values)
                norm = norm + jnp.sum(m * jnp.log(scale * jnp.sqrt(2 * jnp.pi)))
                count = count + jnp.sum(m)
            return potential_energy(model.prior_values, (), {}, u), norm, count

        return jax.jit(fn)

    f = cached(problem, "likelihood-constants", build)
    return lambda x: f(x, problem.data)


def _scalar_values(problem, x) -> dict:
    """Constrained values of the unknowns at ``x`` (scalars as floats, vectors as lists)."""
    model = problem.model

    def build():
        unravel, _ = unraveler(unconstrained_layout(model))
        return jax.jit(lambda x: constrain_fn(model.prior_values, (), {}, unravel(x)))

    values = cached(problem, "constrain-prior", build)(jnp.asarray(x))
    return {k: np.asarray(v).tolist() for k, v in values.items()}


def describe(basins: list[dict]) -> list[str]:
    """The basins as lines for the terminal, best first."""
    lines = [f"basins found: {sum(1 for b in basins if b['log_density'] is not None)} "
             f"(from {sum(len(b['starts']) for b in basins)} starts)"]
    for k, b in enumerate(basins):
        if b["log_density"] is None:
            lines.append(f"  starts {b['note']}: {', '.join(b['starts'])}")
            continue
        rms = "n/a" if b["rms_sigma"] is None else f"{b['rms_sigma']:.2f}σ"
        tag = "best" if k == 0 else f"{basins[0]['log_density'] - b['log_density']:.1f} below"
        lines.append(f"  {k + 1}. log density {b['log_density']:.1f} ({tag}), residual RMS {rms}, "
                     f"from {', '.join(b['starts'])}")
    return lines


__all__ = ["Search", "describe", "prior_centre", "residual_rms", "search",
           "start_points"]
