"""The check of a fit whose likelihood left out the contact pairs the recording rules out
(``physics.ruled_out``): every draw of its posterior pass must stay out of their reach
(``Model.left_out_clearance`` positive: ``idle.clear``'s exact rule), else ``ContactReached`` makes
``infer`` fit again with every pair (``Model.with_every_contact``)."""
from __future__ import annotations

import numpy as np

from ..errors import InferenceError

CLEARANCE_SITE = "contact_clearance:"  # the posterior pass's per-draw clearance of the pairs
# left out (m; not a site of the model): reached where not positive


class ContactReached(InferenceError):
    """A draw of a fit without the pairs the recording rules out came within their reach
    (``infer`` fits again; anywhere else it is an inference failure, with a hint)."""


def check(model, flags) -> None:
    """Raise ContactReached where any of ``flags`` (one per draw) is set."""
    reached = np.concatenate([np.atleast_1d(np.asarray(f, bool)) for f in flags]) if flags \
        else np.zeros(0, bool)
    if reached.any():
        names, pairs = model.simulator.body_names, model.simulator.model.pairs
        which = ", ".join(f"({names[pairs[k].a]}, {names[pairs[k].b]})" for k in model.ruled_out)
        raise ContactReached(
            f"{int(reached.sum())} of {len(reached)} draws come within reach of contact {which}, "
            "which the recording seemed to rule out: fitting again with every contact",
            hint="fit Model.with_every_contact() (physdsl.infer does so by itself)")
