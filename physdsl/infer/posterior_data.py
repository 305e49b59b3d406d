"""The posterior container across arviz's two APIs: ``InferenceData`` (arviz 0.19-0.23) and
xarray ``DataTree`` (arviz >= 1.0: arviz_base, arviz_stats).

Every part of physdsl builds, reads, writes, summarises and scores posteriors through these
functions, so the rest of the code is written once. A group read back is an xarray
``Dataset`` under both; the file layout is the same (one netCDF group per arviz group, the
run's attributes on the root), so a posterior.nc written under one version reads under the
other. The version is looked at once, here, at import time.
"""
from __future__ import annotations

import importlib.metadata
import importlib.util
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import numpy as np

from .. import io

VERSION = importlib.metadata.version("arviz")
MODERN = int(VERSION.split(".")[0]) >= 1  # arviz >= 1.0: DataTree, from_dict({group: ...})


def _arviz():
    """arviz, imported on first use (with xarray below): together they take over a second to
    import, which a command that reads or writes no posterior should not pay."""
    import arviz

    return arviz


def from_dict(groups: dict[str, dict | None], dims=None, coords=None):
    """An arviz posterior (InferenceData or DataTree) from ``{group: {name: array}}`` (posterior-like groups: arrays
    (chain, draw, ...); ``observed_data``: no sample dimensions). Empty groups are left out."""
    groups = {g: v for g, v in groups.items() if v}
    if MODERN:
        return _arviz().from_dict(groups, dims=dims, coords=coords)
    return _arviz().from_dict(**groups, dims=dims, coords=coords)


def group_names(idata) -> list[str]:
    """Names of the groups ``idata`` holds (``posterior``, ``log_likelihood``, ...)."""
    return list(idata.children) if MODERN else list(idata.groups())


def group(idata, name: str):
    """The group ``name`` of ``idata`` as an xarray Dataset, or None where it has none."""
    if name not in group_names(idata):
        return None
    return idata[name].to_dataset() if MODERN else getattr(idata, name)


def add_group(idata, name: str, variables: dict, attrs: dict | None = None):
    """Add a posterior-like group ``name`` (arrays (chain, draw, ...)) to ``idata``, in place."""
    ds = group(from_dict({"posterior": variables}), "posterior")
    ds.attrs.update(attrs or {})
    if MODERN:
        import xarray as xr

        idata[name] = xr.DataTree(ds)
    else:
        idata.add_groups({name: ds})
    return idata


def _engine() -> str:
    """h5netcdf where it is installed, else netCDF4 (both read what the other wrote)."""
    return "h5netcdf" if importlib.util.find_spec("h5netcdf") is not None else "netcdf4"


def write(idata, path) -> Path:
    """Write ``idata`` as netCDF (groups as netCDF groups) atomically."""
    path = Path(path)
    with io.atomic_path(path) as tmp:
        idata.to_netcdf(str(tmp), engine=_engine())
    return path


def read(path):
    """Read a posterior file written by ``write`` (under either arviz version) into memory."""
    if MODERN:
        import xarray as xr

        with xr.open_datatree(str(path), engine=_engine()) as tree:
            return tree.load()
    return _arviz().from_netcdf(str(path), engine=_engine())


def posterior_draws(idata, names: Sequence[str], max_draws: int | None = None) -> dict[str, np.ndarray]:
    """Draws of the named posterior variables with the chains joined: name -> (chains * draws,
    *shape); evenly thinned to at most ``max_draws`` when given."""
    post = group(idata, "posterior")
    out = {}
    for n in names:
        arr = np.asarray(post[n].values)
        arr = arr.reshape(-1, *arr.shape[2:])
        if max_draws is not None:
            arr = arr[::max(1, arr.shape[0] // max_draws)][:max_draws]
        out[n] = arr
    return out


def ess(x, method: str = "bulk") -> float:
    """Effective sample size of the draws ``x`` (chain, draw): ``bulk``, or ``tail`` (the
    smaller of the 5% and 95% quantiles' ESS: arviz 0.x's default, explicit for 1.x)."""
    prob = {"prob": (0.05, 0.95)} if method == "tail" else {}
    return float(_arviz().ess(np.asarray(x, dtype=float), method=method, **prob))


def rhat(x) -> float:
    """Rank-normalised split r-hat of the draws ``x`` (chain, draw)."""
    return float(_arviz().rhat(np.asarray(x, dtype=float)))


@dataclass
class Loo:
    """PSIS-LOO over n points: the estimate, its standard error, the effective number of
    parameters and the pointwise values and Pareto k (length n)."""
    elpd_loo: float
    se: float
    p_loo: float
    loo_i: np.ndarray
    pareto_k: np.ndarray


def loo(ll: np.ndarray) -> Loo:
    """PSIS-LOO (arviz) of a pointwise log-likelihood ``ll`` (chain, draw, n). A point whose
    log-likelihood is the same in every draw gets its exact LOO density (that value, Pareto k
    0: leaving it out changes no weight); arviz 1.x refuses to fit a tail to it, 0.x returns
    NaN. The standard error is sqrt(n var(loo_i)) under both versions (1.x: ddof=1)."""
    ll = np.asarray(ll, dtype=float)
    flat = ll.reshape(-1, ll.shape[2])
    constant = np.ptp(flat, axis=0) == 0
    pointwise, k = flat[0].copy(), np.zeros(ll.shape[2])
    if not constant.all():
        data = from_dict({"posterior": {"_": np.zeros(ll.shape[:2])},
                          "log_likelihood": {"all": ll[..., ~constant]}})
        r = _arviz().loo(data, pointwise=True)
        pointwise[~constant] = np.asarray(r.elpd_i if MODERN else r["loo_i"], dtype=float).ravel()
        k[~constant] = np.asarray(r.pareto_k, dtype=float).ravel()
    k = np.where(np.isnan(k), np.inf, k)  # no tail could be fitted: 0.x says inf, 1.x NaN
    m = flat.max(axis=0)
    lppd = float(np.sum(m + np.log(np.mean(np.exp(flat - m), axis=0))))
    elpd = float(pointwise.sum())
    se = float(np.sqrt(pointwise.size * np.var(pointwise)))
    return Loo(elpd, se, lppd - elpd, pointwise, k)
