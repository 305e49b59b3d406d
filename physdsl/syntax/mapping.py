"""Data labels and scene names: ``observe pole_hinge.angle from "joints.csv" where joint == "pole"``.

The name after ``observe`` is the scene's; the ``where`` value is the data's own label and need
not equal it. Errors about an unknown observed name, a clash of names, or a label that is the
name of another item of the same kind show this mapping form in their hint.
"""
from __future__ import annotations

import difflib

from ..errors import DataError, PhysNameError
from . import ast
from .data import first_row

# the item kind a data column usually labels, and a quantity to show in examples
_COLUMN_KIND = {"body": "body", "joint": "joint", "marker": "marker"}
_EXAMPLE_QUANTITY = {"body": "position", "ground": "position", "marker": "position",
                     "joint": "angle", "camera": "image"}


def mapping_form(target: str, quantity: str, file: str, column: str, label: str) -> str:
    """The observe line that reads the data's rows labelled ``label`` into ``target``."""
    return f'observe {target}.{quantity} from "{file}" where {column} == "{label}"'


def _best(name: str, options) -> str | None:
    found = difflib.get_close_matches(name, sorted(options), n=1, cutoff=0.6)
    return found[0] if found else None


def unknown_target(r, item: ast.ObserveItem, kind: str, names, words: str) -> PhysNameError:
    """The error for ``observe T.q`` where T is no ``kind`` of the scene (``names``: those that
    are); ``words``: which items ``q`` is observed on."""
    t, q = item.target, item.quantity
    other = r.items_by_name.get(t)
    near = _best(t, names)
    if other is not None:
        msg = f"'{q}' is observed on {words}; '{t}' is a {other}"
        if kind == "joint" and other == "body":  # the joint that moves it
            near = next((j.name for j in r.joint_index.values() if j.child == t), near)
    else:
        what = kind + (" or marker" if "markers" in words else "")
        msg = f"'{q}' is observed on {words}; unknown {what} '{t}'"
        if near:
            msg += f" (did you mean '{near}'?)"
    column, label = item.where if item.where is not None else (kind, t)
    example = mapping_form(near or "NAME", q, item.file, column, label)
    return r.err(PhysNameError, msg, item.span, "the name after 'observe' is the scene's; the "
                 f"data's own label goes after 'where': {example}")


def clash_hint(name: str, kind: str) -> str:
    """Hint for a name used twice: rename, and map the data's label to the new name."""
    q = _EXAMPLE_QUANTITY.get(kind)
    if q is None:
        return f"give this {kind} another name"
    column = "joint" if kind == "joint" else "body"
    example = mapping_form(f"{name}_{kind}", q, "data.csv", column, name)
    return (f"give this {kind} another name; data labelled '{name}' can still be read into it: "
            f"{example}")


def check_label(r, item: ast.ObserveItem, file, kinds: dict[str, str]) -> None:
    """Raise if the ``where`` label is the name of another item of the kind its column labels
    (``kinds``: scene name -> kind), e.g. ``observe ball.position .. where body == "cup"``
    while the scene has a body ``cup``: its rows would be read into ``ball``."""
    if item.where is None:
        return
    column, label = item.where
    kind = _COLUMN_KIND.get(column)
    if kind is None or label == item.target or kinds.get(label) not in _same(kind):
        return
    row = first_row(file, column, label)
    if row is None:
        return
    raise DataError(f"'{label}' is another {kinds[label]} of the scene, but these rows are "
                    f"read into '{item.target}'", file, row=row, column=column, span=item.span,
                    hint=f"to observe '{label}' itself: "
                    + mapping_form(label, item.quantity, item.file, column, label))


def _same(kind: str) -> tuple[str, ...]:
    return ("body", "ground", "marker") if kind in ("body", "marker") else (kind,)
