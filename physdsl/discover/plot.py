"""The learned force against the state (not just a number): on a body its component along the
motion against speed and its component towards ``center`` against distance; in a joint the
force against q and against qdot. The distilled law's values at the same states are drawn over
the network's."""
from __future__ import annotations

from pathlib import Path

import jax.numpy as jnp
import numpy as np

from ..diagnose.report import new_figure, save_png
from .distil import Samples
from .terms import body_law, joint_law


def _unit(x):
    return x / (np.linalg.norm(x, axis=1, keepdims=True) + 1e-300)


def panels(s: Samples, law: dict | None):
    """[(x label, x, y label, learned y, law y | None)] for ``s`` (law: term -> coefficient)."""
    if s.kind == "body":
        fl = None if law is None else np.asarray(body_law(law, jnp.asarray(s.a), jnp.asarray(s.b)))
        along, towards = _unit(s.a), -_unit(s.b)
        return [("speed |v| [m/s]", np.linalg.norm(s.a, axis=1), "F · v/|v| [N]",
                 np.sum(s.force * along, 1), None if fl is None else np.sum(fl * along, 1)),
                ("distance |x - center| [m]", np.linalg.norm(s.b, axis=1),
                 "F towards center [N]", np.sum(s.force * towards, 1),
                 None if fl is None else np.sum(fl * towards, 1))]
    fl = None if law is None else np.asarray(joint_law(law, jnp.asarray(s.a), jnp.asarray(s.b)))
    unit = "N m" if s.kind == "hinge" else "N"
    return [(f"q [{'rad' if s.kind == 'hinge' else 'm'}]", s.a, f"tau [{unit}]", s.force, fl),
            (f"qdot [{'rad/s' if s.kind == 'hinge' else 'm/s'}]", s.b, f"tau [{unit}]", s.force, fl)]


def plot_learned(s: Samples, law: dict | None, title: str, path: Path) -> Path:
    """Write the learned force (and the law) against the state as a PNG."""
    rows = panels(s, law)
    fig = new_figure(figsize=(9, 3.4), layout="constrained")
    for i, (xl, x, yl, y, yl_law) in enumerate(rows):
        ax = fig.add_subplot(1, len(rows), i + 1)
        ax.scatter(x, y, s=6, color="tab:blue", label="learned (network)")
        if yl_law is not None:
            ax.scatter(x, yl_law, s=3, color="tab:red", label="distilled law")
        ax.axhline(0.0, color="0.6", lw=0.8)
        ax.set_xlabel(xl)
        ax.set_ylabel(yl)
        ax.legend(fontsize=7)
    fig.suptitle(title, fontsize=9)
    save_png(fig, Path(path))
    return Path(path)
