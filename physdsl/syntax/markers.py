"""Markers (MJCF's sites): ``marker tip on pole { position: (0, 0, -0.25) m }``.

A marker is a massless point fixed in a body's frame; it adds nothing to the dynamics and is
observed as ``tip.position`` / ``tip.velocity`` (``physics.markers`` computes both; the
observation kinds a marker has are those with a ``marker_source``, ``observe.kinds``).
"""
from __future__ import annotations

from .. import expr as E
from ..errors import PhysNameError
from ..scene import Marker
from . import ast
from .words import close


def build_marker(r, item: ast.MarkerItem) -> Marker:
    """The Marker of ``item`` (its fields already registered on resolver ``r``)."""
    n, body = item.name, item.body
    if body not in r.body_index:
        kind = r.items_by_name.get(body)
        msg = (f"marker '{n}' is on '{body}', a {kind}, not a body" if kind else
               f"marker '{n}': unknown body '{body}'"
               + close(body, r.body_index))
        raise r.err(PhysNameError, msg, item.span, "a marker sits on a body: "
                    f"marker {n} on BODY {{ position: (0, 0, 0) m }}")
    position = r.opt(f"{n}.position") or E.Const((0.0, 0.0, 0.0))
    return Marker(n, body, position, r.opt(f"{n}.color"), r.opt(f"{n}.radius"), item.span)
