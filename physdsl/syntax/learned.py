"""The weights of a learned residual force (``residual_force``, ``residual_joint_force``): one
vector unknown whose size follows from ``hidden``, where the grammar's parameters are scalars
or 3-vectors. The sizes match ``physics/effects/residual_force.SIZES`` (a test checks)."""
from __future__ import annotations

import numpy as np

from .. import expr as E
from ..errors import PhysTypeError

# (features in, generalized force out) of each learned effect's network
LEARNED = {"residual_force": (8, 3), "residual_joint_force": (2, 1)}


def param_shapes(res, decl, fields: dict, span) -> dict[str, tuple[int, ...]]:
    """Shapes that replace the declared ones for effect ``decl``: the weights of a learned
    effect, n_in h + h + h n_out + n_out for ``hidden`` h (written or the declared default)."""
    if decl.name not in LEARNED:
        return {}
    n_in, n_out = LEARNED[decl.name]
    if "hidden" in fields:
        node, span = fields["hidden"].value, fields["hidden"].span
        e = res.expr(node).expr
        value = np.atleast_1d(e.array()) if isinstance(e, E.Const) else np.array([np.nan])
    else:
        default = next(p.default for p in decl.params if p.name == "hidden")
        value = np.atleast_1d(default.array())
    h = float(value[0])
    if value.size != 1 or h != int(h) or not 1 <= h <= 256:
        raise res.err(PhysTypeError, f"'hidden' of {decl.name} must be a whole number of "
                      f"units from 1 to 256, not {value.tolist()}", span)
    h = int(h)
    if "weights" in fields:
        raise res.err(PhysTypeError, f"the weights of {decl.name} are learned, not written",
                      fields["weights"].span, "leave 'weights' out: they are an unknown")
    return {"weights": (n_in * h + h + h * n_out + n_out,)}
