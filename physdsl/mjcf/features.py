"""The parts of a MuJoCo model a .phys scene cannot hold, found by walking the MjSpec."""
from __future__ import annotations

import numpy as np


class Notes:
    """Ordered, de-duplicated lines saying what was left out or approximated."""

    def __init__(self):
        self.items: list[str] = []

    def add(self, text: str) -> None:
        if text not in self.items:
            self.items.append(text)


def _names(items, what: str) -> str:
    names = [i.name or f"#{k}" for k, i in enumerate(items)]
    shown = ", ".join(f"'{n}'" for n in names[:6]) + (", ..." if len(names) > 6 else "")
    return f"{len(names)} {what} ({shown})"


def scan_spec(spec, m, notes: Notes) -> None:
    """Add a note for every element kind of ``spec`` that the importer does not translate
    (sites are markers, see ``read``)."""
    groups = [
        (spec.tendons, "tendons", "not expressed (a spatial tendon between two points is a "
                                  "physdsl spring/damper; add one by hand)"),
        (spec.equalities, "equality constraints", "not expressed (physdsl has no loop closures)"),
        (spec.sensors, "sensors", "not imported (physdsl observes bodies and joints with "
                                  "`observe`)"),
        (spec.cameras, "cameras", "not imported"),
        (spec.lights, "lights", "not imported"),
        (spec.flexes, "flexes", "not expressible (deformable bodies)"),
        (spec.skins, "skins", "not expressible"),
        (spec.hfields, "height fields", "not expressible"),
        (spec.plugins, "plugins", "not expressible"),
        (spec.materials, "materials", "not imported (geom rgba becomes color)"),
        (spec.textures, "textures", "not imported"),
    ]
    for items, what, why in groups:
        if len(items):
            notes.add(f"{_names(items, what)}: {why}")
    opt = m.opt
    if np.any(opt.wind):
        notes.add("option wind: not imported (physdsl's `wind` effect acts per body)")
    if opt.density > 0 or opt.viscosity > 0:
        notes.add("option density/viscosity (MuJoCo's fluid forces): not imported; physdsl has "
                  "linear_drag, quadratic_drag and buoyancy effects per body")
    if opt.disableflags or opt.enableflags:
        notes.add(f"option flags (disable {int(opt.disableflags)}, enable {int(opt.enableflags)}): "
                  "not expressible")
    if np.any(m.body_gravcomp):
        notes.add("body gravcomp: not expressible")
