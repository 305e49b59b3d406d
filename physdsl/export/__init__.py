"""Proto-programs: a posterior written back as a .phys program whose priors are the fit.

``export`` turns a scene and its posterior draws into a new scene program: every inferred
unknown's prior becomes a fitted distribution that respects the prior's support. Unknowns
whose unconstrained draws are correlated (|r| >= 0.1) are written jointly as a multivariate
normal in the unconstrained space (numpyro's ``biject_to``): standard-normal params
``proto_zK ~ normal(0, 1)`` and each field an expression ``transform(mean + L_i . z)`` with
the Cholesky factor ``L``. Others get one readable distribution each.

The rooms: ``support`` (a prior's support and its bijection), ``fit_distributions`` (draws ->
marginals and correlated blocks), ``literals`` and ``fit_text`` (a fit as .phys text),
``program`` and ``drop`` (edits of the parsed program), ``proto`` (the whole export),
``mjcf`` (``--format mjcf``: the scene at its posterior medians).
"""
from __future__ import annotations

from .drop import drop_parts
from .fit_distributions import Block, Marginal, ProtoFit, as_block, draw_from_fit, fit_draws
from .fit_text import block_texts, marginal_text, transform_text
from .literals import literal, number, with_unit
from .program import add_params, rebase_paths, set_unknown, snippet
from .proto import export, fit_quality
from .support import Support, classify_constraint, prior_support

__all__ = ["export", "fit_quality", "Support", "classify_constraint", "prior_support", "Marginal",
           "Block", "ProtoFit", "fit_draws", "as_block", "draw_from_fit", "marginal_text",
           "block_texts", "transform_text", "number", "with_unit", "literal", "drop_parts",
           "set_unknown", "add_params", "rebase_paths", "snippet"]
