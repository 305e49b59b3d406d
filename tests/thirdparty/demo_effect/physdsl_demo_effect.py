"""A third-party physdsl effect, as a plug-in package ships it: one module and one line of
packaging (``pyproject.toml``: the entry point of group ``physdsl.effects``).

``demo_tether``: a linear spring from a body's centre of mass to a fixed world point,
F = -k (x - anchor). What it acts on is said once, to ``register``; its parameters (units,
prior, off value) are the .phys block below: physdsl's own files are not touched.
"""
from physdsl.physics.effects.base import register, wrenches
from physdsl.physics.rows import take

DECLARATION = """{
  doc: "Tether to a world point: F = -k (x - anchor)"
  param stiffness: N/m ~ half_normal(1 N/m) off 0 strength above
  param anchor: vector m = (0, 0, 0)
}
"""


@register("demo_tether", ("body",), declaration=DECLARATION, central=True)
def demo_tether(model, site, p, ctx):
    x = take(ctx.kin.com, site.bodies)
    return wrenches(model, ctx, site.bodies, -p["stiffness"] * (x - p["anchor"][None, :]))
