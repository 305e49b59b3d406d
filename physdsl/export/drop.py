"""Dropping parts of a program (``--drop``, ``--no-observe``): a body with what hangs from it and
what refers to it, one effect use, one observation; an error names a reference left dangling."""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Sequence

from ..errors import PhysError, PhysErrors, UsageError
from ..syntax import ast as A
from ..syntax.contact_sugar import CONTACT_SUGAR
from .program import ensure_duration, scene_decl, with_items


@dataclass
class _Dead:
    """What ``--drop`` names, as sets of scene parts."""

    bodies: set[str] = field(default_factory=set)
    effects: set[tuple[str, tuple[str, ...]]] = field(default_factory=set)
    sugar: set[tuple[str, str, str]] = field(default_factory=set)  # (a, b, field)
    obs: set[tuple[str, str]] = field(default_factory=set)
    joints: set[str] = field(default_factory=set)

    @property
    def names(self) -> set[str]:
        return self.bodies | self.joints


def drop_parts(module, drop: Sequence[str] = (), observe: bool = True, duration: float | None = None,
               source: str | None = None):
    """``module`` without the named parts and everything that depends on them.

    A body (or ground) drops the bodies hanging from it through joints, its joints,
    effects, contacts, controls and observations; ``effect@target`` drops one effect use
    (contact sugar fields included); ``target.quantity`` drops one observation.
    ``observe=False`` drops every observation (then ``duration`` in s, if given, is written
    into the world block when the world has none). Raises a PhysError naming both places
    when something left still refers to a dropped body or joint.
    """
    decl = scene_decl(module)
    items = list(decl.items)
    dead = _named_parts(items, drop)
    _add_hanging(items, dead)
    kept, removed = [], []
    for item in items:
        item, gone = _without_dead(item, dead, observe)
        (removed if gone else kept).append(item)
    _check_references(kept, removed, dead, drop, source)
    if not observe and duration is not None:
        kept = ensure_duration(kept, duration)
    return with_items(module, decl, kept)


def _named_parts(items, drop: Sequence[str]) -> _Dead:
    """The parts ``drop`` names; a UsageError listing the choices for a name that is none."""
    bodies = {i.name for i in items if isinstance(i, A.BodyItem)}
    effects = [i for i in items if isinstance(i, A.EffectItem)]
    contacts = [i for i in items if isinstance(i, A.ContactItem)]
    observes = [i for i in items if isinstance(i, A.ObserveItem)]
    dead = _Dead()
    for name in drop:
        if name in bodies:
            dead.bodies.add(name)
            continue
        if "@" in name:
            eff, _, tgt = name.partition("@")
            target = tuple(t.strip() for t in tgt.split(","))
            hits = [e for e in effects if e.effect == eff and e.target == target]
            sugar = [c for c in contacts if target in ((c.a, c.b), (c.b, c.a))
                     and c.block is not None
                     and any(CONTACT_SUGAR.get(getattr(f, "key", "")) == eff for f in c.block.fields)]
            if hits or sugar:
                dead.effects |= {(e.effect, e.target) for e in hits}
                dead.sugar |= {(c.a, c.b, k) for c in sugar for k, v in CONTACT_SUGAR.items() if v == eff}
                continue
        elif "." in name:
            target, _, quantity = name.partition(".")
            if any(o.target == target and o.quantity == quantity for o in observes):
                dead.obs.add((target, quantity))
                continue
        else:
            hits = [e for e in effects if e.effect == name]
            if len(hits) == 1:
                dead.effects.add((hits[0].effect, hits[0].target))
                continue
        choices = sorted(bodies) + [f"{e.effect}@{','.join(e.target)}" for e in effects] \
            + [f"{o.target}.{o.quantity}" for o in observes]
        raise UsageError(f"--drop {name}: no body, effect or observation of that name in the scene",
                         hint="choose from: " + ", ".join(choices))
    return dead


def _add_hanging(items, dead: _Dead) -> None:
    """Bodies hanging from dropped bodies go too; so do the joints that hold them (in place)."""
    joints = {i.name: i for i in items if isinstance(i, A.JointItem)}
    changed = True
    while changed:
        changed = False
        for j in joints.values():
            if j.parent in dead.bodies and j.child not in dead.bodies:
                dead.bodies.add(j.child)
                changed = True
    dead.joints = {n for n, j in joints.items() if j.child in dead.bodies or j.parent in dead.bodies}


def _without_dead(item, dead: _Dead, observe: bool):
    """(item, gone): the item with dropped contact-sugar fields removed, and whether it goes."""
    gone = False
    if isinstance(item, A.BodyItem):
        gone = item.name in dead.bodies
    elif isinstance(item, A.JointItem):
        gone = item.name in dead.joints
    elif isinstance(item, A.ContactItem):
        gone = item.a in dead.bodies or item.b in dead.bodies
        if not gone and item.block is not None:
            fields = tuple(f for f in item.block.fields
                           if (item.a, item.b, getattr(f, "key", "")) not in dead.sugar)
            item = dataclasses.replace(item, block=dataclasses.replace(item.block, fields=fields))
    elif isinstance(item, A.EffectItem):
        gone = bool(set(item.target) & dead.names) or (item.effect, item.target) in dead.effects
    elif isinstance(item, A.ControlItem):
        gone = item.target in dead.names
    elif isinstance(item, A.ObserveItem):
        gone = (not observe or item.target in dead.names
                or (item.target, item.quantity) in dead.obs)
    return item, gone


def _check_references(kept, removed, dead: _Dead, drop: Sequence[str], source: str | None) -> None:
    """A PhysError (or PhysErrors) for every reference a kept item makes to a dropped body or joint."""
    errors = []
    declared = {i.name: i for i in removed if isinstance(i, (A.BodyItem, A.JointItem))}
    for item in kept:
        nodes: list = []
        _walk_exprs(item, nodes)
        for node in nodes:
            ref = None
            if isinstance(node, A.Dotted) and node.parts[0] in dead.names:
                ref = node.parts[0]
                text = ".".join(node.parts)
            elif isinstance(node, A.Name) and node.name in dead.names:
                ref = node.name
                text = node.name
            if ref is None:
                continue
            gone = declared[ref]
            where = f" (declared at {gone.span})" if gone.span else ""
            why = "" if ref in drop else f", dropped with {', '.join(drop)}"
            errors.append(PhysError(
                f"'{text}' in {_item_label(item)} refers to {_item_label(gone)}{where}, "
                f"which is dropped{why}",
                span=node.span, source=source,
                hint=f"drop {_item_label(item)} too, or replace '{text}' with a value"))
    if errors:
        raise errors[0] if len(errors) == 1 else PhysErrors(errors)


def _walk_exprs(node, found):
    """Every expression node under ``node`` (any AST value), depth first."""
    if isinstance(node, tuple):
        for n in node:
            _walk_exprs(n, found)
        return
    if dataclasses.is_dataclass(node) and not isinstance(node, type):
        found.append(node)
        for f in dataclasses.fields(node):
            if f.name not in ("span", "unit_span"):
                _walk_exprs(getattr(node, f.name), found)


_LABELS = ((A.BodyItem, lambda i: f"{i.kind} {i.name}"),
           (A.JointItem, lambda i: f"joint {i.name}"),
           (A.EffectItem, lambda i: f"effect {i.effect} on {','.join(i.target)}"),
           (A.ContactItem, lambda i: f"contact {i.a}, {i.b}"),
           (A.ObserveItem, lambda i: f"observe {i.target}.{i.quantity}"),
           (A.ControlItem, lambda i: f"control {i.name}"),
           (A.Param, lambda i: f"param {i.name}"),
           (A.CameraItem, lambda i: f"camera {i.name}"))


def _item_label(item) -> str:
    """An item as a reader names it: ``sphere ball``, ``joint hinge``, ``effect wind on ball``."""
    return next((label(item) for cls, label in _LABELS if isinstance(item, cls)), type(item).__name__)
