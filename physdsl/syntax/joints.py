"""Joints: their fields declared by kind, the built ``scene.Joint``, and the check that the
joints form a tree rooted at ``world``."""
from __future__ import annotations

import numpy as np

from .. import expr as E
from ..errors import PhysNameError, PhysStructureError, PhysTypeError
from ..scene import DH, Joint
from . import ast
from .schema import DH_FIELDS, JOINT_KINDS, joint_table
from .words import close


def declare_joint(res, item: ast.JointItem):
    """Register a joint's fields (their dimensions follow its kind) and its DH parameters."""
    kind = item.kind
    if kind not in JOINT_KINDS:
        res.errors.append(res.err(PhysNameError, f"unknown joint kind '{kind}'"
                                  f"{close(kind, JOINT_KINDS)}", item.span,
                                  "joints: " + ", ".join(JOINT_KINDS)))
        return
    table = joint_table(kind)
    extra = {"dh"} if kind in ("hinge", "slider") else set()
    fs = res.declare_fields(item.name, item.block, table, f"{kind} joint '{item.name}'", extra)
    dh = fs.get("dh")
    if dh is not None:
        if not isinstance(dh.value, ast.Record):
            res.errors.append(res.err(PhysTypeError, "'dh' needs (a: .., alpha: .., d: .., "
                                      "theta: ..)", dh.span))
        else:
            for a in dh.value.fields:
                if a.name not in DH_FIELDS:
                    res.errors.append(res.err(PhysNameError, f"dh has no parameter '{a.name}'"
                                              f"{close(a.name, DH_FIELDS)}", a.span,
                                              "dh: (a: .., alpha: .., d: .., theta: ..)"))
                    continue
                res.register(f"{item.name}.dh.{a.name}", a.value, DH_FIELDS[a.name])
            missing = [k for k in DH_FIELDS if f"{item.name}.dh.{k}" not in res.sources]
            if missing:
                res.errors.append(res.err(PhysTypeError, f"dh is missing "
                                          f"{', '.join(missing)}", dh.span))
    res.joint_fields[item.name] = fs


def build_joint(res, item: ast.JointItem) -> Joint | None:
    """The Joint of ``item``: parent and child are bodies, an axis (or DH) where the kind
    needs one, limits low < high."""
    if item.kind not in JOINT_KINDS:
        return None
    n = item.name
    for end, role in ((item.parent, "parent"), (item.child, "child")):
        if end == "world" and role == "parent":
            continue
        if end not in res.body_index:
            kind = res.items_by_name.get(end)
            msg = (f"the {role} of joint '{n}' is a {kind}, not a body" if kind else
                   f"joint '{n}': unknown {role} '{end}'"
                   f"{close(end, list(res.body_index) + (['world'] if role == 'parent' else []))}")
            raise res.err(PhysNameError, msg, item.span)
    if item.parent == item.child:
        raise res.err(PhysStructureError, f"joint '{n}' joins '{item.child}' to itself", item.span)
    child = res.body_index[item.child]
    if child.fixed:
        raise res.err(PhysStructureError, f"joint '{n}': the child '{item.child}' is fixed",
                      item.span, "a fixed body cannot move; remove 'fixed: true' or the joint")
    dh = None
    if f"{n}.dh.a" in res.sources:
        vals = [res.opt(f"{n}.dh.{k}") for k in DH_FIELDS]
        if all(v is not None for v in vals):
            dh = DH(*vals)
    axis = res.opt(f"{n}.axis")
    if item.kind in ("hinge", "slider") and axis is None and dh is None \
            and f"{n}.axis" not in res.sources:
        raise res.err(PhysStructureError, f"{item.kind} joint '{n}' needs an axis", item.span,
                      "e.g. axis: (0, 1, 0)")
    if isinstance(axis, E.Const) and not np.any(axis.array()):
        raise res.err(PhysTypeError, f"the axis of joint '{n}' is zero",
                      res.joint_fields[n]["axis"].span)
    lim = res.opt(f"{n}.limits")
    limits = None
    if lim is not None:
        if isinstance(lim, E.Const):
            lo, hi = lim.value
            if lo >= hi:
                raise res.err(PhysTypeError, f"the limits of joint '{n}' need low < high",
                              res.joint_fields[n]["limits"].span)
            limits = (E.Const(lo), E.Const(hi))
        else:
            limits = (lim.items[0], lim.items[1]) if isinstance(lim, E.Vec) else None
    return Joint(n, item.kind, item.parent, item.child, axis, res.opt(f"{n}.anchor"), limits,
                 res.opt(f"{n}.initial"), res.opt(f"{n}.initial_velocity"), dh, item.span)


def check_tree(res, joints: list[Joint]):
    """Joints form a tree: one parent per body, no cycles (errors recorded)."""
    parent_of: dict[str, Joint] = {}
    for j in joints:
        if j.child in parent_of:
            other = parent_of[j.child]
            res.errors.append(res.err(PhysStructureError, f"body '{j.child}' has two parents: "
                                      f"joints '{other.name}' and '{j.name}'", j.span,
                                      "a body hangs from one joint; remove one"))
            continue
        parent_of[j.child] = j
    reported = set()
    for j in joints:
        chain, body = [j.name], j.parent
        while body in parent_of and len(chain) <= len(joints):
            nxt = parent_of[body]
            if nxt.name == j.name:
                key = frozenset(chain)
                if key not in reported:
                    reported.add(key)
                    res.errors.append(res.err(
                        PhysStructureError, "joints form a cycle: "
                        + " -> ".join(chain + [j.name]), j.span,
                        "joints form a tree rooted at 'world'; break the cycle"))
                break
            chain.append(nxt.name)
            body = nxt.parent
