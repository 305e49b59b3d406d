"""Intervals that stay honest when the model misses the data: a sandwich covariance with the
residuals' own covariance as its "meat", applied to the posterior draws.

The posterior's intervals assume the residuals are white noise at the stated level. A scene
fitted to data from another simulator (MuJoCo's soft contacts, a friction law that is not
quite the textbook one) leaves residuals above the noise and in runs, and the plain
posterior is then too narrow. Each residual component (an observable's axis) is taken for
what it looks like: white noise of a fitted level plus, where the data clearly ask for it, a
smooth stationary discrepancy (exponential or Matern 3/2 kernel), fitted to the residuals at
the posterior mean by restricted maximum likelihood (REML: the directions the fit absorbed
are projected out). The unknowns' uncertainty then follows from the sandwich

    V = H^-1 (J^T Gamma J) H^-1   (J = d standardised residuals / d theta, H^-1 = posterior cov)

which is the posterior's covariance when Gamma = I. J and H are never formed:
Cov_post(theta, r_t) = H^-1 J_t^T to first order (statistical linearisation over the draws),
so V = C Gamma C^T with C = Cov_post(theta, r) read off the draws and their predictions, for
every backend, with no extra compile. The draws are widened by an affine map about their
mean in unconstrained space (supports hold): along each direction where V exceeds the
posterior covariance (generalised eigenvalues above 1) the spread grows to V's, elsewhere it
is kept, so intervals only widen. Noise-scale unknowns keep their posterior.

An impact informs the unknowns through the contact law, an idealisation whose error the
residuals need not show: ``contact_law`` adds the covariance that each impacting pair's
restitution, free within a few percent instead of fixed, gives the unknowns (the Laplace
approximation marginalised over it), along with the rest.

A misfit confined to part of the record (an impact) is averaged away by those stationary
residual models; the scores' own long-run covariance (Newey-West over psi_t = C_t r_t, all
components on one time grid) counts it where it is, and replaces the REML sandwich along the
directions where it exceeds it by more than its chance excess under the model.

A mismatch the residuals cannot show (white at the stated level, the error absorbed by the
unknowns) is caught by ``block_check``: refits with one time block left out that scatter more
than the noise explains widen each unknown to the spread of what the blocks say, beyond the
sandwich's widening (not on top of it). Run for the shown robust intervals only
(``--intervals model`` skips its refits).
"""
from __future__ import annotations

import functools
import json

import jax
import jax.numpy as jnp
import numpy as np
from numpyro.infer.util import constrain_fn
from scipy.stats import chi2

from ..ahead import Program
from ..compile import PRED_PREFIX
from ..expr import references
from . import posterior_data
from . import contact_law
from .base import cached
from .block_check import block_factors, full_mode
from .problem import unconstrained_layout, unraveler

SHOWN = ("robust", "model")  # what summary.csv shows: ``--intervals``
GROUP = "posterior_robust"
METHOD = "sandwich, REML residual covariance"
BLOCK_METHOD = "block refits"
HAC_METHOD = "score HAC"  # where the scores' long-run covariance widened some direction


# -- the residuals' covariance: white noise plus a smooth discrepancy, fitted by REML ------
KERNELS = ("exponential", "matern32")
MAX_ROWS = 600  # longer series are averaged in consecutive bins first (dense algebra)
PENALTY = 3.0  # per fitted parameter of the residual model (noise level; discrepancy scale
# and length): a noise level other than the stated one needs a likelihood-ratio statistic
# above 3 (chi-square 1 dof: 92%), a discrepancy above a further 6 (chi-square 2 dof: 95%)
LEVERAGE = 0.05  # a fitted direction counts for a series where it absorbs this much of it
MIN_DOF = 20  # a discrepancy is fitted only to a series with this many residual degrees of
# freedom (rows less fitted directions): fewer cannot tell one from white noise


def kernel(kind: str, dt: np.ndarray, ell: float) -> np.ndarray:
    """Unit-variance stationary correlation at time lags ``dt`` and length scale ``ell``:
    exponential (an AR(1)/Ornstein-Uhlenbeck discrepancy) or Matern 3/2 (a smooth one)."""
    a = np.abs(dt) / ell
    if kind == "exponential":
        return np.exp(-a)
    s = np.sqrt(3.0) * a
    return (1.0 + s) * np.exp(-s)


def _reml(yq, Bq, lam, phis):
    """-2 log restricted likelihood (up to a constant) and the profiled s^2 of residuals with
    covariance s^2 (I + phi K), for every ``phi``, given K = Q diag(lam) Q^T and the
    residuals ``yq`` = Q^T y and fitted directions ``Bq`` = Q^T B (orthonormal B) rotated."""
    n, p = Bq.shape
    w = 1.0 / (1.0 + phis[:, None] * np.maximum(lam, 0.0)[None, :])  # (F, N)
    G = np.einsum("np,fn,nq->fpq", Bq, w, Bq)
    b = np.einsum("np,fn,n->fp", Bq, w, yq)
    sign, logdet_g = np.linalg.slogdet(G)
    q = np.einsum("fn,n->f", w, yq ** 2) - np.einsum("fp,fp->f", b, np.linalg.solve(G, b[..., None])[..., 0])
    ok = (sign > 0) & (q > 0)
    s2 = np.where(ok, q, 1.0) / (n - p)
    v = (n - p) * (np.log(s2) + 1.0) - np.sum(np.log(w), axis=1) + logdet_g
    return np.where(ok, v, np.inf), s2


@functools.lru_cache(maxsize=64)
def _eigh(times: bytes, kind: str, ell: float):
    """Eigendecomposition of the kernel matrix at ``times`` (float64 bytes): the components of
    one observable share their times, so each is decomposed once."""
    t = np.frombuffer(times)
    return np.linalg.eigh(kernel(kind, t[:, None] - t[None, :], ell))


def residual_covariance(t: np.ndarray, y: np.ndarray, W: np.ndarray):
    """The covariance of one residual series ``y`` (standardised) at times ``t``: white
    noise at the stated level (I), at a fitted level (s^2 I), or s^2 (I + phi K_ell) with K
    an exponential or Matern 3/2 kernel (a smooth discrepancy), whichever has the lowest
    restricted likelihood (REML) penalised by ``PENALTY`` per parameter. REML projects out
    the directions the fit absorbed, which plain likelihood would take for less noise: those
    of ``W`` (N, d) = Cov_post(theta, y)^T in whitened unknowns (its squared singular values
    are the fitted unknowns' leverage on this series) with at least ``LEVERAGE``. Returns
    (covariance (N, N), {kind, s2, phi, ell})."""
    U, sv, _ = np.linalg.svd(W, full_matrices=False)
    B = U[:, sv ** 2 >= LEVERAGE]
    n, p = B.shape
    step = float(np.median(np.diff(np.sort(t)))) if n > 1 else 1.0
    r = y - B @ (B.T @ y)
    stated = float(r @ r)  # -2 log REML of I, the same constant dropped
    v, s2 = _reml(y, B, np.zeros(n), np.zeros(1))
    best = (stated, "stated", 1.0, 0.0, step)
    if float(v[0]) + PENALTY < best[0]:
        best = (float(v[0]) + PENALTY, "white", float(s2[0]), 0.0, step)
    span = float(t.max() - t.min()) if n > 1 else 1.0
    phis = np.geomspace(1e-3, 1e4, 36)
    for kind in KERNELS if n - p >= MIN_DOF else ():
        for ell in np.geomspace(max(step, 1e-12), span, 14):
            lam, Q = _eigh(t.tobytes(), kind, float(ell))
            v, s2 = _reml(Q.T @ y, Q.T @ B, lam, phis)
            i = int(np.argmin(v))
            if v[i] + 3 * PENALTY < best[0]:
                best = (float(v[i]) + 3 * PENALTY, kind, float(s2[i]), float(phis[i]), float(ell))
    _, kind, s2, phi, ell = best
    corr = np.eye(n) + (phi * kernel(kind, t[:, None] - t[None, :], ell) if phi > 0 else 0.0)
    return s2 * corr, {"kind": kind, "s2": s2, "phi": phi, "ell": ell}


def _binned(t, y, C, rows: int):
    """Consecutive rows averaged (times, residuals) and summed (C) in bins, at most ``rows``."""
    m = int(np.ceil(t.size / rows))
    if m <= 1:
        return t, y, C
    edges = np.arange(0, t.size, m)
    mean = lambda a: np.add.reduceat(a, edges, axis=-1) / np.diff(np.append(edges, t.size))  # noqa: E731
    return mean(t), mean(y), np.add.reduceat(C, edges, axis=-1)


def widening(sigma: np.ndarray, V: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(A, factors): the linear map with Cov(A delta) = V along the directions where V exceeds
    ``sigma`` (the posterior covariance) and = ``sigma`` elsewhere, by the generalised
    eigenvalues of (V, sigma) clipped below at 1; ``factors`` are their square roots (>= 1)."""
    L = np.linalg.cholesky(sigma)
    Li = np.linalg.inv(L)
    lam, U = np.linalg.eigh(Li @ V @ Li.T)
    f = np.sqrt(np.maximum(lam, 1.0))
    return L @ (U * f) @ U.T @ Li, f


# -- the scores' own covariance over time: heteroscedasticity and autocorrelation consistent --
HAC_BLOCKS = 8  # the bandwidth is at most the record / this (``block_check``'s blocks): the
# scores of a fit sum to zero over the record, so a window near its length sees nothing
HAC_LEVEL = 0.05  # a direction widens by the HAC estimate only where it exceeds the REML
# sandwich by more than the estimate's own sampling error would under the model, at this
# level, Bonferroni over the d directions


def andrews_bandwidth(psi: np.ndarray) -> float:
    """Bartlett-kernel bandwidth (lags) of Andrews (1991) from AR(1) fits to each column of the
    score series ``psi`` (M, d): long where the scores run, about 1 where they are white."""
    a, b = psi[1:], psi[:-1]
    rho = np.clip(np.sum(a * b, axis=0) / np.maximum(np.sum(b * b, axis=0), 1e-300), -0.97, 0.97)
    s2 = np.mean(psi ** 2, axis=0) * (1.0 - rho ** 2)
    num = np.sum(4.0 * rho ** 2 * s2 ** 2 / ((1.0 - rho) ** 6 * (1.0 + rho) ** 2))
    den = np.sum(s2 ** 2 / (1.0 - rho) ** 4)
    return 1.1447 * (num / max(den, 1e-300) * psi.shape[0]) ** (1.0 / 3.0)


def hac_covariance(psi: np.ndarray) -> tuple[np.ndarray, float]:
    """(Omega (d, d), bandwidth): the Newey-West (Bartlett) long-run covariance of the score
    series ``psi`` (M, d), sum_t sum_s w(|t - s|) psi_t psi_s^T, with ``andrews_bandwidth``
    at most M / ``HAC_BLOCKS``. Non-parametric: a misfit confined to part of the record (an
    impact a soft contact makes differently) counts where it is, not averaged over it."""
    m = psi.shape[0]
    L = float(np.clip(andrews_bandwidth(psi), 1.0, max(m / HAC_BLOCKS, 1.0)))
    omega = psi.T @ psi
    for j in range(1, int(np.floor(L)) + 1):
        g = psi[j:].T @ psi[:-j]
        omega += (1.0 - j / (L + 1.0)) * (g + g.T)
    return 0.5 * (omega + omega.T), L


def hac_excess(a: np.ndarray, lags: float, level: float) -> float:
    """How far above its mean ``hac_covariance``'s variance along a unit direction u comes by
    chance, at ``level``, if the model were right (psi_t = c_t e_t, e white at the stated
    noise): the estimate is a quadratic form in Gaussians, of mean sum_t a_t and variance
    2 sum_ts w_ts^2 a_t a_s (``a`` (M,): a_t = E (u . psi_t)^2, the bin's sum of (u . c)^2),
    taken as a scaled chi-square with those two moments (Satterthwaite). Few informative rows
    (the end of a record, an impact) make it large."""
    mean, total = float(a.sum()), float(a @ a)
    for j in range(1, int(np.floor(lags)) + 1):
        total += 2.0 * (1.0 - j / (lags + 1.0)) ** 2 * float(a[j:] @ a[:-j])
    if mean <= 0 or total <= 0:
        return 0.0
    nu = mean ** 2 / total  # 2 mean^2 / variance, variance = 2 total
    return mean * (float(chi2.isf(level, nu)) / nu - 1.0)


def _score_series(parts, rows: int):
    """(psi (M, d), a) on one time grid of at most ``rows`` bins over the span of ``parts``
    [(times (N,), c (N, d), residuals (N,))], every residual component's: per bin, the sum of
    the scores psi_t = c_t r_t (components measured at the same time together: their misfits
    are correlated, e.g. at an impact); ``a(u)`` -> (M,): per bin, the sum of (u . c_t)^2, what
    E (u . psi_t)^2 would be with white residuals at the stated noise."""
    t = np.concatenate([p[0] for p in parts])
    c = np.concatenate([p[1] for p in parts])
    r = np.concatenate([p[2] for p in parts])
    lo, hi = float(t.min()), float(t.max())
    steps = [np.diff(np.unique(p[0])) for p in parts]
    step = min((float(np.median(d)) for d in steps if d.size), default=max(hi - lo, 1.0))
    m = int(min(rows, max(1, np.ceil((hi - lo) / max(step, 1e-12)) + 1)))
    idx = np.minimum(((t - lo) / max(hi - lo, 1e-300) * m).astype(int), m - 1)
    psi = np.zeros((m, c.shape[1]))
    np.add.at(psi, idx, c * r[:, None])
    return psi, lambda u: np.bincount(idx, weights=(c @ u) ** 2, minlength=m)


def _combine(M1: np.ndarray, M2: np.ndarray, a, lags: float):
    """(M1 plus the part of (M2 - M1) that its sampling error under the model cannot explain,
    how many directions took it) (whitened: the posterior is I): at least the REML sandwich
    everywhere, and the HAC estimate along the directions where it is clearly larger.
    ``a``: ``_score_series``'s per-bin expected squares along a direction."""
    lam, U = np.linalg.eigh(0.5 * ((M2 - M1) + (M2 - M1).T))
    level = HAC_LEVEL / max(len(lam), 1)
    big = np.array([lam[i] > 0 and lam[i] > hac_excess(a(U[:, i]), lags, level)
                    for i in range(len(lam))], dtype=bool)
    return M1 + (U[:, big] * lam[big]) @ U[:, big].T, int(big.sum())


def robust_covariance(draws: np.ndarray, streams: list[tuple[np.ndarray, np.ndarray, np.ndarray]]):
    """Sandwich covariance (d, d) from flat draws (n, d) and, per residual stream, (times (N,),
    standardised residual draws (n, N, K), mask (N, K)); and the fitted residual model of
    every component. V = sum over components of C Gamma C^T with C = Cov_post(theta, r) (from
    the draws: H^-1 J^T to first order) and Gamma the component's ``residual_covariance``
    (the components are taken as independent of each other); then, along the directions
    where the scores' non-parametric long-run covariance (``hac_covariance`` of
    psi_t = sum_k C_tk r_tk over all components) is clearly larger, that one instead."""
    delta = draws - draws.mean(axis=0)
    V = np.zeros((draws.shape[1],) * 2)
    L = np.linalg.cholesky(np.cov(draws, rowvar=False).reshape(V.shape))
    Li = np.linalg.inv(L)
    fits, parts = [], []
    for times, res, mask in streams:
        rbar = res.mean(axis=0)
        C = np.einsum("nd,ntk->dtk", delta, res - rbar) / (draws.shape[0] - 1)
        for k in range(res.shape[2]):
            rows = mask[:, k]
            if rows.sum() < 8:
                continue
            tk = np.asarray(times, float)[rows]
            parts.append((tk, (Li @ C[:, rows, k]).T, rbar[rows, k]))
            t, y, Ck = _binned(tk, rbar[rows, k], C[:, rows, k], MAX_ROWS)
            gamma, fit = residual_covariance(t, y, (Li @ Ck).T)
            V += Ck @ gamma @ Ck.T
            fits.append(fit)
    V = 0.5 * (V + V.T)
    if parts:
        psi, a = _score_series(parts, MAX_ROWS)
        omega, lags = hac_covariance(psi)
        M, used = _combine(Li @ V @ Li.T, omega, a, lags)
        V = L @ (0.5 * (M + M.T)) @ L.T
        fits.append({"kind": "hac", "bandwidth_lags": lags, "rows": int(psi.shape[0]),
                     "largest": float(np.linalg.eigvalsh(omega).max()), "directions": used})
    return V, fits


# -- the run's draws ------------------------------------------------------------------------
def add_robust(idata, model, problem, flat: np.ndarray, constrained: dict, shown: str = "robust",
               on_block=None):
    """Add the group ``posterior_robust`` (the widened draws) to ``idata`` and name the shown
    intervals in ``idata.attrs["intervals"]``. ``flat`` (chains, samples, dim): the
    unconstrained draws; ``constrained``: the posterior pass's sites, (chains * samples, ...)
    each (unknowns and ``pred:`` predictions). Where no sandwich can be made (no trajectory
    observation, too few draws) the model's intervals are shown and ``intervals_note`` says why."""
    chains, samples, dim = flat.shape
    X = np.asarray(flat, dtype=float).reshape(chains * samples, dim)
    why = _unavailable(model, X)
    if why:
        idata.attrs["intervals"] = "model"
        idata.attrs["intervals_note"] = f"robust intervals unavailable: {why}"
        return idata
    res = _residual_draws(model, problem, constrained)
    streams = [(np.asarray(o.obs.times, float), res[o.obs.name],
                np.asarray(problem.data[o.obs.name]["mask"], bool)) for o in model.observed]
    keep = _physical_dims(model, dim)
    m = X.mean(axis=0)
    try:
        V, fits = robust_covariance(X, streams)
        sigma = np.cov(X[:, keep], rowvar=False).reshape(keep.size, keep.size)
        A, f = widening(sigma, V[np.ix_(keep, keep)])
    except np.linalg.LinAlgError:  # draws on a lower-dimensional set: no covariance to widen
        idata.attrs["intervals"] = "model"
        idata.attrs["intervals_note"] = "robust intervals unavailable: a singular posterior covariance"
        return idata
    Xr = X.copy()
    Xr[:, keep] = m[keep] + (X[:, keep] - m[keep]) @ A.T
    mode = _mode(problem, X) if shown == "robust" else None
    block = _block_check(problem, X, keep, Xr, m, mode, on_block) if shown == "robust" else None
    contact = _contact_term(model, problem, mode, keep, Xr, m) if shown == "robust" else None
    widest = Xr[:, keep].std(axis=0) / X[:, keep].std(axis=0)
    values = _constrain(model, problem)(jnp.asarray(Xr))
    post = {u: np.asarray(values[u]).reshape(chains, samples, *np.shape(values[u])[1:])
            for u in model.unknown_names}
    hac = [fit for fit in fits if fit["kind"] == "hac"]
    fits = [fit for fit in fits if fit["kind"] != "hac"]
    found = [fit for fit in fits if fit["kind"] in KERNELS]
    posterior_data.add_group(idata, GROUP, post, {
        "method": METHOD + (" + " + HAC_METHOD if hac and hac[0]["directions"] else "")
        + (" + " + contact_law.METHOD if contact and contact.get("widened") else "")
        + (" + " + BLOCK_METHOD if block and "p_value" in block else ""),
        "max_widening": float(max(f.max(initial=1.0), widest.max(initial=1.0))),
        "block_check": json.dumps(block if block is not None else {"note": "not run"}),
        "residual_models": json.dumps(fits),
        "score_hac": json.dumps(hac[0] if hac else {}),
        "contact_law": json.dumps(contact if contact is not None else {"note": "not run"}),
        "discrepancies": f"{len(found)} of {len(fits)} residual components"})
    idata.attrs["intervals"] = shown
    return idata


def _mode(problem, X):
    """The full data's mode (``block_check.full_mode``), once for the block check and the
    contact law; None where it cannot be found (each then says why it did not run)."""
    try:
        return full_mode(problem, X)
    except (np.linalg.LinAlgError, ValueError, FloatingPointError):
        return None


def _contact_term(model, problem, mode, keep, Xr, m) -> dict | None:
    """``contact_law.marginal_covariance`` added to the covariance of the draws ``Xr`` as the
    sandwich and the block check left them (in place: a common error of every block, it is
    no scatter between blocks, so the block check's scale does not include it). None where the
    scene has no pair with a fixed restitution (nothing computed), else its figures and
    whether it widened."""
    if not contact_law.fitted_pairs(model):
        return None
    try:
        found = None if mode is None else contact_law.marginal_covariance(model, problem, mode)
        if found is None:
            return {"note": "not possible: no mode, or no least-squares curvature"}
        if not found["pairs"]:  # no pair impacts in the record: the draws stay as they are
            return {"pairs": [], "eta_sd": [], "width": found["width"], "widened": False,
                    "largest": 1.0}
        sigma = np.cov(Xr[:, keep], rowvar=False).reshape(keep.size, keep.size)
        A, f = widening(sigma, sigma + found["cov"][np.ix_(keep, keep)])
    except (np.linalg.LinAlgError, ValueError, FloatingPointError) as err:  # a widening only
        return {"note": f"not possible: {type(err).__name__}: {err}"}
    widened = bool(np.any(f > 1.0 + contact_law.NEGLIGIBLE))
    if widened:
        Xr[:, keep] = m[keep] + (Xr[:, keep] - m[keep]) @ A.T
    return {"pairs": found["pairs"], "eta_sd": found["eta_sd"], "width": found["width"],
            "widened": widened, "largest": float(f.max(initial=1.0))}


def _block_check(problem, X, keep, Xr, m, mode, on_block=None) -> dict | None:
    """``block_check``: where its refits on time blocks scatter more than the sandwich's
    intervals explain, widen the draws ``Xr`` (in place) per coordinate by the measured
    excess over them (no double count). Its figures, or a note saying why there are none."""
    have = Xr[:, keep].std(axis=0) / X[:, keep].std(axis=0)
    if mode is None:
        return {"note": "not possible: no mode found"}
    try:
        found = block_factors(problem, mode, keep, scale=have, on_block=on_block)
    except (np.linalg.LinAlgError, ValueError, FloatingPointError) as err:  # a check only
        return {"note": f"not possible: {type(err).__name__}: {err}"}
    if found is None:
        return {"note": "not possible: no least-squares curvature, or fewer than two blocks "
                        "refitted with a positive definite curvature"}
    Xr[:, keep] = m[keep] + (Xr[:, keep] - m[keep]) * found["factors"]
    return {"p_value": found["p_value"], "statistic": found["statistic"], "dof": found["dof"],
            "blocks": found["blocks"], "factors": np.asarray(found["factors"]).tolist()}


def _unavailable(model, X) -> str:
    if not model.observed:
        return "no trajectory observation"
    if X.shape[1] == 0 or _physical_dims(model, X.shape[1]).size == 0:
        return "no unknown but noise scales"
    if not np.all(np.isfinite(X)):
        return "non-finite draws"
    if X.shape[0] < 4 * X.shape[1] + 4:
        return f"{X.shape[0]} draws for {X.shape[1]} dimensions (need {4 * X.shape[1] + 4})"
    sd = X.std(axis=0)
    if np.any(sd <= 1e-12 * np.maximum(1.0, np.abs(X.mean(axis=0)))):
        return "a posterior with no spread along some unknown"
    return ""


def _residual_draws(model, problem, constrained) -> dict[str, np.ndarray]:
    """Standardised residuals of every draw: name -> (n, N, K), 0 where not measured."""
    names = model.unknown_names

    def one(c, data):
        values = {k: c[k] for k in names}
        return {o.obs.name: model._residual(o.obs, c[PRED_PREFIX + o.obs.name], data[o.obs.name])
                / model.noise_scale(o.obs, values) for o in model.observed}

    fn = cached(problem, "intervals-residuals", lambda: Program(jax.vmap(one, in_axes=(0, None))))
    sites = {k: v for k, v in constrained.items()
             if k in names or k.startswith(PRED_PREFIX)}
    return {k: np.asarray(v) for k, v in fn(sites, problem.data).items()}


def _physical_dims(model, dim: int) -> np.ndarray:
    """Flat indices of every unknown but the noise scales (ravel order: sorted names)."""
    noise = set()
    for o in model.observed:
        noise |= references(o.obs.noise.scale)
    keep, at = [], 0
    for name, leaf in sorted(unconstrained_layout(model).items()):
        size = int(np.prod(leaf.shape))
        if name not in noise:
            keep.extend(range(at, at + size))
        at += size
    assert at == dim, (at, dim)
    return np.asarray(keep, dtype=int)


def _constrain(model, problem):
    def build():
        unravel, _ = unraveler(unconstrained_layout(model))
        return jax.jit(jax.vmap(lambda x: constrain_fn(model.prior_values, (), {}, unravel(x))))

    return cached(problem, "intervals-constrain", build)


# -- what is shown --------------------------------------------------------------------------
def shown_posterior(idata):
    """(posterior dataset, label) that summaries show: the widened draws where the run chose
    them (``--intervals robust``, the default) and has them, else the model's posterior."""
    if idata.attrs.get("intervals", "model") == "robust" and GROUP in \
            posterior_data.group_names(idata):
        return posterior_data.group(idata, GROUP), "robust"
    return posterior_data.group(idata, "posterior"), "model"


def describe(idata) -> str:
    """One line for the terminal: which intervals the summary shows and how much they widened."""
    post, label = shown_posterior(idata)
    if label == "robust":
        block = json.loads(post.attrs.get("block_check", "{}"))
        check = ("" if "p_value" not in block else
                 f"; block check p = {block['p_value']:.2g}: "
                 + ("the parts of the record disagree, widened" if max(block["factors"]) > 1
                    else "the parts of the record agree"))
        return (f"intervals: robust ({post.attrs.get('method', METHOD)}; widest "
                f"{post.attrs.get('max_widening', 1.0):.2g}x the model posterior's{check}; "
                f"`--intervals model` for the plain posterior)")
    note = idata.attrs.get("intervals_note")
    return "intervals: model (the plain posterior)" + (f"; {note}" if note else "")


__all__ = ["SHOWN", "GROUP", "add_robust", "shown_posterior", "describe", "robust_covariance",
           "residual_covariance", "widening"]
