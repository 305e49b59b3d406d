"""Contact pairs of an imported model: the geom pairs MuJoCo tests (its filters and explicit
pairs, with the friction it would use), compared with the pairs physdsl's own rule tests, as
``contact`` statements; where the two rules differ, a note says so."""
from __future__ import annotations

import tempfile
from pathlib import Path

from ..syntax import ast, loads
from ..syntax.printer import format_module
from .build import block, field, quantity
from .features import Notes


def geom_pairs(mj, m) -> list[tuple[int, int, float]]:
    """Geom pairs MuJoCo tests for contact (its filters: same weld body, parent, contype/
    conaffinity, exclude; plus explicit pairs), with the friction it would use."""
    out = []
    weld, parent = m.body_weldid, m.body_parentid
    filterparent = not (m.opt.disableflags & mj.mjtDisableBit.mjDSBL_FILTERPARENT)
    excluded = {int(s) for s in m.exclude_signature}
    for g1 in range(m.ngeom):
        for g2 in range(g1 + 1, m.ngeom):
            b1, b2 = m.geom_bodyid[g1], m.geom_bodyid[g2]
            w1, w2 = weld[b1], weld[b2]
            if w1 == w2:
                continue
            if filterparent and w1 and w2 and (weld[parent[w1]] == w2 or weld[parent[w2]] == w1):
                continue
            if not (m.geom_contype[g1] & m.geom_conaffinity[g2]
                    or m.geom_contype[g2] & m.geom_conaffinity[g1]):
                continue
            if ((min(b1, b2) << 16) + max(b1, b2)) in excluded:
                continue
            out.append((g1, g2, float(max(m.geom_friction[g1][0], m.geom_friction[g2][0]))))
    for p in range(m.npair):
        out.append((int(m.pair_geom1[p]), int(m.pair_geom2[p]), float(m.pair_friction[p][0])))
    return out


def mujoco_pairs(pairs, geom_body: dict[int, str]) -> dict[frozenset, float]:
    """Pairs of physdsl bodies (``geom_body``: geom -> body carrying it) among the geom
    ``pairs`` MuJoCo tests, with the friction it would use."""
    out: dict[frozenset, float] = {}
    for g1, g2, mu in pairs:
        a, b = geom_body.get(g1), geom_body.get(g2)
        if a is None or b is None or a == b:
            continue
        out[frozenset((a, b))] = float(mu)
    return out


def physdsl_pairs(bodies, joints, files: dict[str, str], contacts=()) -> set[frozenset]:
    """The pairs physdsl tests among ``bodies`` and ``joints`` (items) plus ``contacts``: the
    language's own rule, by resolving the text (controls left out: their file may not exist
    yet; mesh ``files`` written to a temporary folder)."""
    items = (ast.WorldItem(block()), *bodies, *joints, *contacts)
    text = format_module(ast.Module((ast.SceneDecl("pairs", items),)))
    with tempfile.TemporaryDirectory() as tmp:
        for name, content in files.items():
            (Path(tmp) / name).write_text(content)
        scene = loads(text, "<imported scene>", tmp)
    return {frozenset(p) for p in scene.contact_pairs}


def contact_items(pairs, geom_body, bodies, joints, files, notes: Notes) -> list:
    """``contact`` statements for the pairs MuJoCo tests (friction as MuJoCo combines it,
    restitution 0); pairs only one side tests are listed in ``notes``."""
    mj_pairs = mujoco_pairs(pairs, geom_body)
    default = physdsl_pairs(bodies, joints, files)
    for pair in sorted(default - set(mj_pairs), key=sorted):
        a, b = sorted(pair)
        notes.add(f"contact {a}, {b}: physdsl tests this pair, MuJoCo's contype/"
                  "conaffinity, parent filter or exclude does not")
    contacts = []
    for pair, mu in mj_pairs.items():
        a, b = sorted(pair)
        fs = ([field("friction", quantity(mu))] if mu > 0 else []) + \
            [field("restitution", quantity(0.0))]
        contacts.append(ast.ContactItem(a, b, block(*fs)))
    if set(mj_pairs) - default:  # a contact statement may switch a pair on; check
        tested = physdsl_pairs(bodies, joints, files, contacts)
        for pair in set(mj_pairs) - tested:
            a, b = sorted(pair)
            notes.add(f"contact {a}, {b}: MuJoCo tests this pair, physdsl does not "
                      "(physdsl's contact rules leave it out)")
            contacts = [c for c in contacts if {c.a, c.b} != {a, b}]
    if contacts:
        notes.add("contacts: MuJoCo's soft contacts (solref, solimp, condim, torsional "
                  "and rolling friction) become hard contacts with Coulomb friction and "
                  "restitution 0")
    return contacts
