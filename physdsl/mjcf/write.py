"""A Scene at given values of its unknowns as MJCF, built with ``mujoco.MjSpec``.

Each physdsl body becomes an MJCF body at its reference pose (relative to its parent in the
joint tree) with an explicit inertial (mass, principal moments); its shape is one geom in the
body frame. Joints keep their names; joint effects become joint attributes; ``control``s on
joints become motors named after the control; the initial state is the keyframe ``initial``.
Contacts are explicit ``<pair>``s (every geom has contype = conaffinity = 0), so MuJoCo tests
exactly the pairs physdsl does. What MJCF cannot hold is returned as notes.
"""
from __future__ import annotations

import ctypes
import glob
import os
from contextlib import contextmanager

import numpy as np

from ..errors import UsageError
from ..expr import evaluate
from ..physics.model import build_model
from ..physics.params import evaluate_params, shape_size
from ..syntax import ast, parse
from .features import Notes
from .loading import require_mujoco

# effects that become MJCF attributes (the rest are listed as not exported)
_EXPORTED = {"gravity", "joint_damping", "joint_friction", "joint_spring", "control_force",
             "contact_friction"}


def _local(parent_pos, parent_quat, pos, quat, mj):
    """Pose (pos, quat) relative to the parent frame, from world poses."""
    R = np.zeros(9)
    mj.mju_quat2Mat(R, parent_quat)
    R = R.reshape(3, 3)
    inv = np.zeros(4)
    mj.mju_negQuat(inv, parent_quat)
    q = np.zeros(4)
    mj.mju_mulQuat(q, inv, quat)
    return R.T @ (pos - parent_pos), q


def _principal(inertia: np.ndarray):
    """(principal moments, quaternion of the principal axes) of a symmetric 3x3 inertia."""
    mj = require_mujoco()
    if np.allclose(inertia, np.diag(np.diag(inertia)), atol=1e-15):
        return np.diag(inertia).copy(), np.array([1.0, 0, 0, 0])
    w, V = np.linalg.eigh(inertia)
    if np.linalg.det(V) < 0:
        V[:, 2] = -V[:, 2]
    q = np.zeros(4)
    mj.mju_mat2Quat(q, V.reshape(9))
    return w, q


def _set_scalar(obj, attr: str, value: float) -> None:
    """Set a joint coefficient: a number in MuJoCo 3, the linear term of a polynomial in 4."""
    current = getattr(obj, attr)
    if np.ndim(current):
        setattr(obj, attr, np.r_[value, np.zeros(np.size(current) - 1)])
    else:
        setattr(obj, attr, value)


def _control_names(scene) -> dict[str, str]:
    """Target -> control name, read from the scene's source (the Scene keeps only the effect)."""
    if not scene.source:
        return {}
    decl = parse(scene.source, str(scene.path or "<scene>")).scene
    return {it.target: it.name for it in (decl.items if decl else ()) if isinstance(it, ast.ControlItem)}


class _Writer:
    def __init__(self, scene, values):
        self.mj = require_mujoco()
        self.scene = scene
        self.model = build_model(scene)
        self.prm = {k: (np.asarray(v) if not isinstance(v, list) else v)
                    for k, v in evaluate_params(scene, self.model, values).items()}
        self.effects = [{k: np.asarray(v, dtype=float) for k, v in e.items()}
                        for e in self.prm["effects"]]
        self.notes = Notes()
        self.spec = self.mj.MjSpec()
        self.spec.modelname = scene.name
        self.mjbody: dict[int, object] = {}
        self.geom_of: dict[str, str] = {}
        self.joint_of: dict[str, object] = {}

    def world(self):
        w, mj, opt = self.scene.world, self.mj, self.spec.option
        opt.timestep = float(w.timestep) / max(int(w.substeps), 1)
        if w.substeps > 1:
            self.notes.add(f"world substeps {w.substeps}: MJCF timestep is timestep/substeps")
        if w.integrator == "rk4":
            opt.integrator = mj.mjtIntegrator.mjINT_RK4
        else:
            opt.integrator = mj.mjtIntegrator.mjINT_EULER
            self.notes.add("integrator semi_implicit_euler: MuJoCo's Euler (damping integrated "
                           "implicitly); use rk4 for rollouts that agree closely")
        opt.gravity = np.zeros(3)
        if self.model.ncon and w.contact_model == "lcp":
            self.notes.add("contact lcp (hard, complementarity): MuJoCo's contacts are soft "
                           "(solref, solimp)")

    def _frames(self) -> set[int]:
        """Massless, shapeless bodies moved by a joint whose one child is moved by another:
        MuJoCo refuses massless moving bodies, so their joints go into the child's MJCF body
        (MJCF's several joints in one body, applied in order)."""
        m, out = self.model, set()
        marked = {mk.body for mk in getattr(self.scene, "markers", ())}
        for i, b in enumerate(self.scene.bodies):
            kids = m.children[i]
            if (m.joints[i].kind in ("hinge", "slider", "ball") and b.shape is None
                    and float(self.prm["mass"][i]) <= 0 and len(kids) == 1 and b.name not in marked
                    and m.joints[kids[0]].kind in ("hinge", "slider", "ball")):
                out.add(i)
        return out

    def bodies(self):
        m, prm, mj = self.model, self.prm, self.mj
        frames = self._frames()
        for i in m.order:
            if i in frames:
                continue
            b, tj = self.scene.bodies[i], m.joints[i]
            chain, p = [], tj.parent
            while p >= 0 and p in frames:
                chain.insert(0, p)
                p = m.joints[p].parent
            parent = self.spec.worldbody if p < 0 else self.mjbody[p]
            ppos = np.zeros(3) if p < 0 else prm["ref_pos"][p]
            pquat = np.array([1.0, 0, 0, 0]) if p < 0 else prm["ref_quat"][p]
            pos, quat = _local(ppos, pquat, prm["ref_pos"][i], prm["ref_quat"][i], mj)
            body = parent.add_body(name=b.name, pos=pos, quat=quat)
            self.mjbody[i] = body
            mass = float(prm["mass"][i])
            if mass > 0:
                body.explicitinertial = True
                body.mass = mass
                body.inertia, body.iquat = _principal(np.asarray(prm["inertia"][i]))
                body.ipos = np.asarray(prm["com"][i])
            self.geom(b, body, massless=mass <= 0)
            self.sites(b, body)
            for k in chain + [i]:
                self.joint(k, i, body)

    def geom(self, b, body, massless: bool):
        mj, G = self.mj, self.mj.mjtGeom
        if b.shape is None:
            return
        size = {k: np.asarray(v, dtype=float) for k, v in shape_size(b.shape, self.prm_values).items()}
        kind = b.shape.kind
        if kind == "sphere":
            t, s = G.mjGEOM_SPHERE, [size["radius"], 0, 0]
        elif kind == "box":
            t, s = G.mjGEOM_BOX, 0.5 * size["size"]
        elif kind in ("capsule", "cylinder"):
            t = G.mjGEOM_CAPSULE if kind == "capsule" else G.mjGEOM_CYLINDER
            s = [size["radius"], 0.5 * size["length"], 0]
        elif kind == "plane":
            t, s = G.mjGEOM_PLANE, [0, 0, 1]
        elif kind == "mesh":  # vertices in the body frame, as physdsl reads the file
            import trimesh

            mesh = trimesh.load(b.shape.mesh_path, force="mesh")
            self.spec.add_mesh(name=f"{b.name}_mesh", uservert=np.asarray(mesh.vertices, float).ravel(),
                               userface=np.asarray(mesh.faces).ravel())
            t, s = G.mjGEOM_MESH, [0, 0, 0]
        else:
            self.notes.add(f"body '{b.name}': shape {kind} is not exported (mass and inertia are)")
            return
        geom = body.add_geom(name=b.name, type=t, size=np.asarray(s, dtype=float), contype=0,
                             conaffinity=0)
        if kind == "mesh":
            geom.meshname = f"{b.name}_mesh"
        if kind == "plane":  # the plane's surface passes through the body position, normal n
            n = np.asarray(size["normal"], dtype=float)
            n = n / np.linalg.norm(n)
            q = np.zeros(4)
            mj.mju_quatZ2Vec(q, n)
            # the body frame is the world frame rotated by ref_quat; the geom lies in it
            inv = np.zeros(4)
            mj.mju_negQuat(inv, self.prm["ref_quat"][self.scene.bodies.index(b)])
            geom.quat = np.zeros(4)
            gq = np.zeros(4)
            mj.mju_mulQuat(gq, inv, q)
            geom.quat = gq
        if massless:
            geom.density = 0.0
        if b.color is not None:
            geom.rgba = np.r_[np.asarray(evaluate(b.color, self.prm_values), dtype=float), 1.0]
        self.geom_of[b.name] = b.name

    def sites(self, b, body):
        """Markers on body ``b`` as MJCF sites (the MJCF body frame is the physdsl body frame)."""
        for mk in getattr(self.scene, "markers", ()):
            if mk.body == b.name:
                site = body.add_site(name=mk.name,
                                     pos=np.asarray(evaluate(mk.position, self.prm_values), dtype=float))
                if mk.color is not None:
                    site.rgba = np.r_[np.asarray(evaluate(mk.color, self.prm_values), dtype=float), 1.0]

    def joint(self, k, i, body):
        """Tree joint of body ``k`` into the MJCF body of physdsl body ``i`` (k == i, or a
        massless frame above i)."""
        mj, J, prm = self.mj, self.mj.mjtJoint, self.prm
        tj = self.model.joints[k]
        if tj.kind == "fixed":
            return
        name = self.scene.joints[tj.scene_joint].name if tj.scene_joint is not None else None
        if tj.kind == "free":
            jt = body.add_freejoint()
            if name:
                jt.name = name
            return
        R = np.zeros(9)
        mj.mju_quat2Mat(R, prm["ref_quat"][i])
        R = R.reshape(3, 3)
        kind = {"hinge": J.mjJNT_HINGE, "slider": J.mjJNT_SLIDE, "ball": J.mjJNT_BALL}[tj.kind]
        jt = body.add_joint(name=name, type=kind, pos=R.T @ (prm["anchor"][k] - prm["ref_pos"][i]),
                            axis=R.T @ prm["axis"][k])
        joint = self.scene.joints[tj.scene_joint]
        if joint.limits is not None:
            jt.range = [float(evaluate(joint.limits[0], self.prm_values)),
                        float(evaluate(joint.limits[1], self.prm_values))]
            jt.limited = mj.mjtLimited.mjLIMITED_TRUE
            self.notes.add(f"joint '{name}': limits become MuJoCo's soft limits")
        self.joint_of[name] = jt

    def effects_(self):
        controls = _control_names(self.scene)
        mj = self.mj
        for use, p in zip(self.scene.effects, self.effects):
            t = use.target
            if use.effect == "gravity":
                self.spec.option.gravity = self.spec.option.gravity + p["acceleration"]
            elif use.effect in ("joint_damping", "joint_friction", "joint_spring") and t[0] in self.joint_of:
                jt = self.joint_of[t[0]]
                if use.effect == "joint_damping":
                    _set_scalar(jt, "damping", float(p["coefficient"]))
                elif use.effect == "joint_friction":
                    jt.frictionloss = float(p["torque"])
                    self.notes.add(f"joint_friction on {t[0]}: MuJoCo's frictionloss is exact dry "
                                   "friction, physdsl's is smoothed (tanh)")
                else:
                    _set_scalar(jt, "stiffness", float(p["stiffness"]))
                    jt.springref = float(p["rest"])
            elif use.effect == "control_force" and t[0] in self.joint_of:
                name = controls.get(t[0], f"{t[0]}_control")
                act = self.spec.add_actuator(name=name, target=t[0], trntype=mj.mjtTrn.mjTRN_JOINT)
                act.set_to_motor()
                act.gear = np.r_[float(p["gain"]), np.zeros(5)]
                self.notes.add(f"control {name}: its force sequence is not part of MJCF; set "
                               f"actuator '{name}''s ctrl to it (held over each sample)")
            elif use.effect == "contact_friction":
                pass  # written with the pairs
            else:
                self.notes.add(f"effect {use.key}: not exported (MJCF has no equivalent)")

    def pairs(self):
        fric = {frozenset(u.target): float(p["coefficient"])
                for u, p in zip(self.scene.effects, self.effects) if u.effect == "contact_friction"}
        rest = {frozenset(u.target) for u in self.scene.effects if u.effect == "restitution"}
        for a, b in self.scene.contact_pairs:
            if a not in self.geom_of or b not in self.geom_of:
                continue
            mu = fric.get(frozenset((a, b)), 0.0)
            self.spec.add_pair(geomname1=a, geomname2=b, condim=3 if mu > 0 else 1,
                               friction=[max(mu, 1e-5), max(mu, 1e-5), 0.005, 1e-4, 1e-4])
            self.notes.add(f"contact {a}, {b}: restitution is not expressible in MJCF (MuJoCo's "
                           "default soft contact is nearly inelastic)"
                           if frozenset((a, b)) in rest else
                           f"contact {a}, {b}: elastic in physdsl (no restitution effect); "
                           "MuJoCo's default soft contact is nearly inelastic")

    def keyframe(self):
        """The initial state as keyframe 'initial' (physdsl q0/v0 into MuJoCo's qpos/qvel order)."""
        m = self.spec.compile()
        qpos, qvel = m.qpos0.copy(), np.zeros(m.nv)
        q0, v0 = np.asarray(self.prm["q0"]), np.asarray(self.prm["v0"])
        for i, tj in enumerate(self.model.joints):
            if tj.nq == 0:
                continue
            if tj.scene_joint is not None:
                j = self.mj.mj_name2id(m, self.mj.mjtObj.mjOBJ_JOINT, self.scene.joints[tj.scene_joint].name)
            else:  # an implicit free joint: the body's only joint
                j = m.body_jntadr[self.mj.mj_name2id(m, self.mj.mjtObj.mjOBJ_BODY, self.scene.bodies[i].name)]
            qpos[m.jnt_qposadr[j]:m.jnt_qposadr[j] + tj.nq] = q0[tj.qadr:tj.qadr + tj.nq]
            qvel[m.jnt_dofadr[j]:m.jnt_dofadr[j] + tj.nv] = v0[tj.vadr:tj.vadr + tj.nv]
        self.spec.add_key(name="initial", qpos=qpos, qvel=qvel)


@contextmanager
def _exact_numbers(mj, notes: Notes):
    """MuJoCo writes 6 significant digits by default; ask its writer for exact numbers (the
    shortest text that reads back as the same double) while we write, then restore it."""
    lib = None
    for path in glob.glob(os.path.join(os.path.dirname(mj.__file__), "libmujoco*")):
        try:
            cand = ctypes.CDLL(path)
            cand._mjPRIVATE__get_xml_precision  # noqa: B018 - probe the symbol
            lib = cand
            break
        except (OSError, AttributeError):
            continue
    if lib is None:
        notes.add("numbers: written with MuJoCo's default 6 significant digits (this MuJoCo "
                  "has no exact-number writer)")
        yield
        return
    before = lib._mjPRIVATE__get_xml_precision()
    lib._mjPRIVATE__set_xml_precision(0)
    try:
        yield
    finally:
        lib._mjPRIVATE__set_xml_precision(before)


def write_mjcf(scene, values) -> tuple[str, list[str]]:
    """(MJCF text, notes) of ``scene`` with unknowns at ``values``."""
    missing = [u.name for u in scene.unknowns if u.name not in values]
    if missing:
        raise UsageError(f"no value for unknown '{missing[0]}' of scene '{scene.name}'",
                         hint="export with the posterior fitted to this scene")
    w = _Writer(scene, values)
    w.prm_values = values
    w.world()
    w.bodies()
    w.effects_()
    w.pairs()
    w.keyframe()
    with _exact_numbers(w.mj, w.notes):
        head = f" Written by physdsl from scene '{scene.name}'. "
        if w.notes.items:
            head += "Not expressed in MJCF: " + "; ".join(n.replace("--", "-") for n in w.notes.items) + " "
        w.spec.comment = head
        text = w.spec.to_xml()
    return text, list(w.notes.items)
