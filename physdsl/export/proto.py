"""The whole export: a scene and its posterior -> fitted distributions -> proto-program text."""
from __future__ import annotations

import warnings
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from .. import syntax
from ..errors import PhysError, UsageError
from ..infer import posterior_data
from ..scene import Scene
from ..syntax.loops import unroll_module
from ..syntax.printer import format_module
from ..version import __version__
from .drop import drop_parts
from .fit_distributions import ProtoFit, as_block, fit_draws
from .fit_text import block_texts, marginal_text
from .program import add_params, rebase_paths, set_unknown, snippet
from .support import prior_support


def export(scene_path: str | Path, idata, *, free: Sequence[str] = (), drop: Sequence[str] = (),
           widen: float = 1.0, observe: bool = True, out_path: str | Path | None = None,
           run: Mapping | None = None) -> str:
    """A .phys program whose priors are the posterior ``idata`` fitted, as text.

    ``free``: unknowns that keep their original prior; ``drop``: bodies, effects
    (``effect@target``) or observations (``target.quantity``) removed with what depends on
    them; ``widen``: factor on every unconstrained scale; ``observe=False``: no observe
    blocks (a pure generator). ``out_path``: where the text will be written (relative file
    names are rewritten to work from there; default: beside the scene). ``run``: the run's
    run.json contents, for the header. The text parses, resolves and is ``fmt``-stable.
    """
    scene_path = Path(scene_path)
    source = scene_path.read_text(encoding="utf-8")
    scene = syntax.loads(source, filename=str(scene_path), base_dir=scene_path.parent)
    run = dict(run or {})
    run.setdefault("scene", str(scene_path))
    posterior_vars = set(idata.posterior.data_vars)
    names = {u.name for u in scene.unknowns}
    bad = [f for f in free if f not in names]
    if bad:
        raise UsageError(f"--free {bad[0]}: no unknown of that name in {scene_path}",
                         hint="unknowns: " + ", ".join(sorted(names)))
    module = unroll_module(syntax.parse(source, str(scene_path)))  # loops written out
    module = drop_parts(module, drop, observe, duration=scene.duration, source=source)
    reduced = syntax.loads(format_module(module, source), filename=str(scene_path),
                           base_dir=scene_path.parent)
    targets = [u for u in reduced.unknowns if u.name in posterior_vars and u.name not in free]
    draws = _target_draws(idata, targets)
    fit = _fit(draws, targets, widen)
    z_names = [f"{_z_prefix(scene, source)}{k + 1}" for k in range(sum(len(b.mean) for b in fit.blocks))]
    module = _write_fit(module, fit, z_names, {u.name: u.unit for u in targets})
    header = _header(scene_path, run, fit, fit_quality(idata, [u.name for u in targets]),
                     len(next(iter(draws.values()))) if draws else 0, free, drop, widen,
                     observe, z_names)
    # the program must resolve (checked where its files are now, before they are rebased)
    syntax.loads(format_module(module, source), filename=str(scene_path), base_dir=scene_path.parent)
    out_dir = Path(out_path).parent if out_path is not None else scene_path.parent
    module = rebase_paths(module, scene_path.parent, out_dir)
    return syntax.format_source("\n".join(header) + "\n\n" + format_module(module, source))


def _target_draws(idata, targets) -> dict[str, np.ndarray]:
    """Posterior draws of the exported unknowns; an error where a shape is not the scene's."""
    draws = posterior_data.posterior_draws(idata, [u.name for u in targets])
    for u in targets:
        if tuple(draws[u.name].shape[1:]) != tuple(u.shape):
            raise PhysError(f"posterior of '{u.name}' has shape {draws[u.name].shape[1:]}, the "
                            f"scene says {tuple(u.shape)}", span=u.span,
                            hint="export with the scene the posterior was fitted to")
    return draws


def _fit(draws: Mapping[str, np.ndarray], targets, widen: float) -> ProtoFit:
    """The fit of ``draws`` within each prior's support; unit-bearing params whose fit would be
    log-normal or beta (arguments without unit) become one-unknown blocks."""
    means = {n: d.mean(axis=0) for n, d in draws.items()}
    supports = {u.name: prior_support(u, means) for u in targets}
    fit = fit_draws(draws, supports, widen=widen)
    units = {u.name: u.unit for u in targets}
    for m in fit.marginals:
        if "." not in m.name and units[m.name] not in ("", "1") and m.dist in ("log_normal", "beta"):
            fit = as_block(fit, m.name, draws[m.name], widen)
    return fit


def _write_fit(module, fit: ProtoFit, z_names: Sequence[str], units: Mapping[str, str]):
    """``module`` with every fitted unknown written: block members as expressions of the
    standard-normal params ``z_names`` (declared first in the scene), marginals as priors."""
    k = 0
    for b in fit.blocks:
        texts = block_texts(b, z_names[k:k + len(b.mean)], fit, units)
        k += len(b.mean)
        for name, text in texts.items():
            module = set_unknown(module, name, snippet(f"x: {text}"))
    for m in fit.marginals:
        module = set_unknown(module, m.name, snippet(f"x ~ {marginal_text(m, units[m.name])}"))
    if z_names:
        module = add_params(module, [(z, "normal(0, 1)") for z in z_names])
    return module


def fit_quality(idata, names: Sequence[str]) -> tuple[float, float]:
    """(max r-hat, min bulk ESS) over the named unknowns' components (nan when undefined)."""
    if not names:
        return float("nan"), float("nan")
    post = posterior_data.group(idata, "posterior")
    r, e = [], []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for n in names:
            arr = np.asarray(post[n].values, dtype=float)
            for x in np.moveaxis(arr.reshape(*arr.shape[:2], -1), 2, 0):  # (chain, draw) each
                r.append(posterior_data.rhat(x))
                e.append(posterior_data.ess(x, method="bulk"))
    r_max = float(np.nanmax(r)) if np.any(np.isfinite(r)) else float("nan")
    e_min = float(np.nanmin(e)) if np.any(np.isfinite(e)) else float("nan")
    return r_max, e_min


def _z_prefix(scene: Scene, source: str) -> str:
    """``proto_z`` (or ``proto_proto_z``, ...): a prefix no name of the scene starts with."""
    prefix = "proto_z"
    while prefix in source or any(u.name.startswith(prefix) for u in scene.unknowns):
        prefix = "proto_" + prefix
    return prefix


def _header(scene_path: Path, run: Mapping, fit: ProtoFit, quality, n_draws: int,
            free, drop, widen, observe, z_names) -> list[str]:
    """The comment lines heading a proto-program: its source, the run, the fit's quality and form."""
    lines = [f"proto-program exported by physdsl {__version__} from {run.get('scene') or scene_path}"]
    if run.get("scene_sha256"):
        lines.append(f"scene sha256 {run['scene_sha256']}")
    for f, h in (run.get("data_sha256") or {}).items():
        lines.append(f"data {Path(f).name} sha256 {h}")
    chains = f"backend {run.get('backend', '?')}, seed {run.get('seed', '?')}, {n_draws} draws"
    r_max, e_min = quality
    lines.append(f"posterior: {chains}; r-hat max {r_max:.3f}, ESS min {e_min:.0f}")
    if fit.blocks:
        names = list(dict.fromkeys(n for b in fit.blocks for n, _ in b.components))
        lines.append(f"correlated (multivariate normal, unconstrained space, {z_names[0]}.."
                     f"{z_names[-1]}): {', '.join(names)}")
    if fit.marginals:
        lines.append("independent: " + ", ".join(f"{m.name} {m.dist}" for m in fit.marginals))
    opts = []
    if free:
        opts.append("free " + ", ".join(free))
    if drop:
        opts.append("dropped " + ", ".join(drop))
    if widen != 1.0:
        opts.append(f"widened x{widen:g}")
    if not observe:
        opts.append("no observations (a pure generator)")
    if opts:
        lines.append("; ".join(opts))
    return ["# " + line for line in lines]
