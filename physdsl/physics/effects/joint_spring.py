"""joint_spring: tau = -k (q - rest) on a hinge (torsion spring) or slider (linear spring).

The spring a scene can gain without new geometry: the joint itself gives its anchor and line,
so the diagnosis can propose it on every hinge and slider.
"""
from ...errors import ModelError
from .base import joint_forces, register


def _check(scene, use, joint):
    kind = scene.joints[joint].kind if joint is not None else None
    if kind not in (None, "hinge", "slider"):
        raise ModelError(f"joint_spring acts on hinges and sliders, not on the {kind} "
                         f"joint '{scene.joints[joint].name}'", span=use.span,
                         hint="use `spring` between bodies for other joints")


@register("joint_spring", ("joint",), validate=_check)
def joint_spring(model, site, p, ctx):
    tree = next(j for j in model.joints if j.scene_joint == site.joint)
    q = ctx.kin.q[tree.qadr: tree.qadr + tree.nq]
    return joint_forces(model, site, -p["stiffness"] * (q - p.get("rest", 0.0)))
