"""A compiled MuJoCo model as a .phys scene (syntax tree, printed in canonical ``fmt`` form).

Numbers come from MuJoCo's compiled ``mjModel`` (defaults, ``fromto``, inertia from geoms all
resolved by MuJoCo) and world poses from ``mj_kinematics`` at the reference configuration
(``qpos0``; free bodies at the chosen keyframe). A physdsl body sits at its MuJoCo body's
inertial frame (centre of mass, principal axes), which is what physdsl's ``position``,
``orientation`` and ``inertia`` mean. Whatever the language cannot say is returned as notes.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..errors import UsageError
from ..physics.inertia import unit_inertia
from ..syntax import ast
from ..syntax.printer import format_module
from .build import Names, block, call, field, quantity, quat
from .contacts import contact_items, geom_pairs
from .features import Notes, scan_spec
from .loading import require_mujoco

_TOL = 1e-9


def _mat_quat(mujoco, mat) -> np.ndarray:
    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, np.asarray(mat, dtype=float).reshape(9))
    return q


def _units(kind: str) -> dict[str, str]:
    """Units of a joint's quantities: angles for hinge and ball joints, lengths for sliders."""
    if kind == "slider":
        return dict(q="m", v="m/s", damp="N*s/m", fric="N", stiff="N/m", ctrl="N")
    return dict(q="rad", v="rad/s", damp="N*m*s/rad", fric="N*m", stiff="N*m/rad", ctrl="N*m")


class _Reader:
    def __init__(self, spec, m, key):
        self.mj = require_mujoco()
        self.spec, self.m = spec, m
        self.notes = Notes()
        self.names = Names()
        self.bodies: list = []  # body / ground items
        self.joints: list = []
        self.effects: list = []
        self.controls: list = []
        self.contacts: list = []
        self.markers: list = []
        self.files: dict[str, str] = {}  # mesh files to write beside the scene
        self.files_names: dict[int, str] = {}
        self.file_names = Names()
        # physdsl name of each MuJoCo body ("world" for the world and static bodies)
        self.body_name: dict[int, str] = {0: "world"}
        self.joint_name: dict[int, str] = {}
        self.joint_kind: dict[int, str] = {}
        self.geom_body: dict[int, str] = {}  # geom -> physdsl body carrying its shape
        self.key = self._key(key)
        self.geom_pairs = geom_pairs(self.mj, m)
        self.d = self._reference()

    # ---- state -----------------------------------------------------------------------------
    def _key(self, key):
        m = self.m
        if key is None:
            if m.nkey:
                self.notes.add(f"keyframes ({m.nkey}): not used; the initial state is MuJoCo's "
                               "qpos0 (choose one with --key NAME)")
            return None
        names = [self.mj.mj_id2name(m, self.mj.mjtObj.mjOBJ_KEY, k) for k in range(m.nkey)]
        if key in names:
            return names.index(key)
        if key.isdigit() and int(key) < m.nkey:
            return int(key)
        raise UsageError(f"no keyframe '{key}' in the model",
                         hint="keyframes: " + (", ".join(n or str(i) for i, n in enumerate(names))
                                               or "none"))

    def _reference(self):
        """MjData at the reference pose: qpos0, with free joints at the keyframe's pose."""
        m, mj = self.m, self.mj
        d = mj.MjData(m)
        q = m.qpos0.copy()
        if self.key is not None:
            for j in range(m.njnt):
                if m.jnt_type[j] == mj.mjtJoint.mjJNT_FREE:
                    a = m.jnt_qposadr[j]
                    q[a:a + 7] = m.key_qpos[self.key][a:a + 7]
        d.qpos[:] = q
        mj.mj_kinematics(m, d)
        return d

    def _key_q(self, j):
        if self.key is None:
            return None, None
        m = self.m
        qa, va = m.jnt_qposadr[j], m.jnt_dofadr[j]
        return m.key_qpos[self.key][qa:], m.key_qvel[self.key][va:]

    # ---- geometry ----------------------------------------------------------------------------
    def _name(self, obj, i: int, fallback: str) -> str:
        return self.names.make(self.mj.mj_id2name(self.m, obj, i), fallback)

    def _shape(self, g: int):
        """The shape call of geom ``g``, or None (with a note) when physdsl has no such shape."""
        m, G = self.m, self.mj.mjtGeom
        t, s = int(m.geom_type[g]), m.geom_size[g]
        if t == G.mjGEOM_SPHERE:
            return call("sphere", radius=quantity(s[0], "m"))
        if t == G.mjGEOM_BOX:
            return call("box", size=quantity(2 * s, "m"))
        if t in (G.mjGEOM_CAPSULE, G.mjGEOM_CYLINDER):
            kind = "capsule" if t == G.mjGEOM_CAPSULE else "cylinder"
            return call(kind, radius=quantity(s[0], "m"), length=quantity(2 * s[1], "m"))
        label = self.mj.mj_id2name(m, self.mj.mjtObj.mjOBJ_GEOM, g) or f"#{g}"
        if t == G.mjGEOM_MESH:
            return self._mesh(g, label)
        kind = str(G(t)).split("_")[-1].lower()
        self.notes.add(f"geom '{label}' ({kind}): no physdsl shape; its mass is in the body's "
                       "inertia, but it neither collides nor renders")
        return None

    def _mesh(self, g: int, label: str):
        """``mesh("NAME.obj")``: MuJoCo's compiled vertices (in the geom frame) written as OBJ
        beside the scene; physdsl needs a closed volume and has no mesh contacts."""
        import trimesh

        m, k = self.m, self.m.geom_dataid[g]
        v = m.mesh_vert[m.mesh_vertadr[k]:m.mesh_vertadr[k] + m.mesh_vertnum[k]]
        f = m.mesh_face[m.mesh_faceadr[k]:m.mesh_faceadr[k] + m.mesh_facenum[k]]
        mesh = trimesh.Trimesh(np.asarray(v, dtype=float), np.asarray(f), process=False)
        if not mesh.is_volume:
            self.notes.add(f"geom '{label}' (mesh): not a closed volume, not imported (its mass "
                           "is in the body's inertia)")
            return None
        raw = self.mj.mj_id2name(m, self.mj.mjtObj.mjOBJ_MESH, k) or f"mesh{k}"
        fname = self.files_names.setdefault(k, self.file_names.make(raw, "mesh") + ".obj")
        self.files[fname] = trimesh.exchange.obj.export_obj(mesh, include_normals=False)
        self.notes.add(f"geom '{label}' (mesh): written to {fname}; it renders but does not "
                       "collide (physdsl has no mesh contacts)")
        return ast.Call("mesh", (ast.Arg(None, ast.Str(fname)),))

    def _color(self, g: int):
        rgba = self.m.geom_rgba[g]
        if np.allclose(rgba, (0.5, 0.5, 0.5, 1.0)):
            return None
        return field("color", quantity(rgba[:3], digits=6))  # float32 in MuJoCo

    def _collides(self, g: int) -> bool:
        if self.m.geom_type[g] == self.mj.mjtGeom.mjGEOM_MESH:
            return False
        return any(g in (g1, g2) for g1, g2, _ in self.geom_pairs)

    def _pose_fields(self, pos, mat):
        q = _mat_quat(self.mj, mat)
        out = [field("position", quantity(pos, "m"))]
        if not np.allclose(np.abs(q[0]), 1.0, atol=1e-12):
            out.append(field("orientation", quat(q)))
        return out

    def _same_frame(self, g: int, b: int) -> bool:
        d = self.d
        return (np.allclose(d.geom_xpos[g], d.xipos[b], atol=_TOL)
                and np.allclose(d.geom_xmat[g], d.ximat[b], atol=_TOL))

    def _inertia_from_shape(self, g: int, b: int) -> bool:
        """Whether physdsl's own inertia of the shape at this mass equals MuJoCo's (then it is left out)."""
        m, G = self.m, self.mj.mjtGeom
        t, s = int(m.geom_type[g]), m.geom_size[g]
        kinds = {int(G.mjGEOM_SPHERE): ("sphere", {"radius": s[0]}),
                 int(G.mjGEOM_BOX): ("box", {"size": 2 * s}),
                 int(G.mjGEOM_CAPSULE): ("capsule", {"radius": s[0], "length": 2 * s[1]}),
                 int(G.mjGEOM_CYLINDER): ("cylinder", {"radius": s[0], "length": 2 * s[1]})}
        if t not in kinds:
            return False
        kind, size = kinds[t]
        ours = m.body_mass[b] * np.asarray(unit_inertia(kind, size))
        return bool(np.allclose(ours, m.body_inertia[b], rtol=1e-9, atol=1e-15))

    # ---- bodies ------------------------------------------------------------------------------
    def static_geoms(self, b: int):
        """Geoms of the world and of bodies welded to it: grounds (planes) and fixed bodies."""
        m, d, G = self.m, self.d, self.mj.mjtGeom
        bname = self.mj.mj_id2name(m, self.mj.mjtObj.mjOBJ_BODY, b) or f"body{b}"
        for g in range(m.body_geomadr[b], m.body_geomadr[b] + m.body_geomnum[b]):
            name = self._name(self.mj.mjtObj.mjOBJ_GEOM, g, f"{bname}_geom{g}")
            if m.geom_type[g] == G.mjGEOM_PLANE:
                normal = d.geom_xmat[g].reshape(3, 3)[:, 2]
                fs = [field("normal", quantity(normal)), field("point", quantity(d.geom_xpos[g], "m")),
                      self._color(g)]
                if not self._collides(g):
                    fs.append(field("collide", ast.Name("false")))
                self.bodies.append(ast.BodyItem("ground", name, block(*fs)))
            else:
                shape = self._shape(g)
                if shape is None:
                    continue
                fs = [field("shape", shape), *self._pose_fields(d.geom_xpos[g], d.geom_xmat[g]),
                      self._color(g), field("fixed", ast.Name("true"))]
                if not self._collides(g):
                    fs.append(field("collide", ast.Name("false")))
                self.bodies.append(ast.BodyItem("body", name, block(*fs)))
            self.geom_body[g] = name

    def moving_body(self, b: int):
        m, d, mj = self.m, self.d, self.mj
        name = self._name(mj.mjtObj.mjOBJ_BODY, b, f"body{b}")
        self.body_name[b] = name
        geoms = list(range(m.body_geomadr[b], m.body_geomadr[b] + m.body_geomnum[b]))
        fs = []
        own = None
        if len(geoms) == 1 and self._same_frame(geoms[0], b):
            own = self._shape(geoms[0])
            if own is not None:
                fs.append(field("shape", own))
        fs.append(field("mass", quantity(m.body_mass[b], "kg")))
        if own is None or not self._inertia_from_shape(geoms[0], b):
            fs.append(field("inertia", quantity(m.body_inertia[b], "kg*m^2")))
        fs += self._pose_fields(d.xipos[b], d.ximat[b])
        free = any(m.jnt_type[j] == mj.mjtJoint.mjJNT_FREE for j in self._body_joints(b))
        if free:
            fs += self._free_velocity(b)
        if own is not None:
            fs.append(self._color(geoms[0]))
            self.geom_body[geoms[0]] = name
            if not self._collides(geoms[0]):
                fs.append(field("collide", ast.Name("false")))
        self.bodies.append(ast.BodyItem("body", name, block(*fs)))
        if own is None:
            for g in geoms:
                self._geom_body(g, name)
        return name

    def _geom_body(self, g: int, owner: str):
        """A massless body carrying geom ``g``'s shape, welded to its owner."""
        m, d, mj = self.m, self.d, self.mj
        shape = self._shape(g)
        if shape is None:
            return
        name = self._name(mj.mjtObj.mjOBJ_GEOM, g, f"{owner}_geom{g - m.body_geomadr[m.geom_bodyid[g]]}")
        fs = [field("shape", shape), field("mass", quantity(0.0, "kg")),
              field("inertia", quantity(np.zeros(3), "kg*m^2")),
              *self._pose_fields(d.geom_xpos[g], d.geom_xmat[g]), self._color(g)]
        if not self._collides(g):
            fs.append(field("collide", ast.Name("false")))
        self.bodies.append(ast.BodyItem("body", name, block(*fs)))
        weld = self.names.make(f"{name}_weld", "weld")
        self.joints.append(ast.JointItem(weld, "fixed", owner, name))
        self.geom_body[g] = name

    def _body_joints(self, b: int) -> list[int]:
        m = self.m
        return list(range(m.body_jntadr[b], m.body_jntadr[b] + m.body_jntnum[b])) \
            if m.body_jntnum[b] else []

    def _free_velocity(self, b: int):
        """Initial velocity of a free body's centre of mass and its angular velocity, world frame."""
        j = self._body_joints(b)[0]
        _, kv = self._key_q(j)
        if kv is None or not np.any(kv[:6]):
            return []
        d = self.d
        w = d.xmat[b].reshape(3, 3) @ kv[3:6]  # MuJoCo: local angular velocity
        v = kv[:3] + np.cross(w, d.xipos[b] - d.xpos[b])  # MuJoCo: velocity of the body origin
        return [field("velocity", quantity(v, "m/s")), field("angular_velocity", quantity(w, "rad/s"))]

    # ---- joints ------------------------------------------------------------------------------
    def body_joints(self, b: int, child: str):
        """The joints between body ``b`` and its parent; several become a chain of massless bodies."""
        m, mj = self.m, self.mj
        parent = self.body_name[m.body_parentid[b]]
        js = self._body_joints(b)
        if not js:
            weld = self.names.make(f"{child}_weld", "weld")
            self.joints.append(ast.JointItem(weld, "fixed", parent, child))
            return
        if m.jnt_type[js[0]] == mj.mjtJoint.mjJNT_FREE:
            return  # a body without a joint moves freely
        d = self.d
        for k, j in enumerate(js):
            last = k == len(js) - 1
            target = child if last else self.names.make(f"{child}_dof{k + 1}", "dof")
            if not last:  # an intermediate frame: no mass, no shape, at the body's pose
                self.bodies.append(ast.BodyItem("body", target, block(
                    field("mass", quantity(0.0, "kg")), field("inertia", quantity(np.zeros(3), "kg*m^2")),
                    *self._pose_fields(d.xipos[b], d.ximat[b]))))
            self._joint(j, parent, target)
            parent = target

    def _joint(self, j: int, parent: str, child: str):
        m, mj, d = self.m, self.mj, self.d
        t = int(m.jnt_type[j])
        J = mj.mjtJoint
        kind = {int(J.mjJNT_HINGE): "hinge", int(J.mjJNT_SLIDE): "slider",
                int(J.mjJNT_BALL): "ball"}.get(t)
        name = self._name(mj.mjtObj.mjOBJ_JOINT, j, f"{child}_joint")
        if kind is None:
            self.notes.add(f"joint '{name}': a free joint below another body is not expressible")
            return
        self.joint_name[j], self.joint_kind[j] = name, kind
        u = _units(kind)
        qa, va = m.jnt_qposadr[j], m.jnt_dofadr[j]
        fs = []
        if kind != "ball":
            fs.append(field("axis", quantity(d.xaxis[j])))
        if kind != "slider":
            fs.append(field("anchor", quantity(d.xanchor[j], "m")))
        kq, kv = self._key_q(j)
        if kind == "ball":
            if kq is not None and (not np.allclose(kq[:4], (1, 0, 0, 0)) or np.any(kv[:3])):
                self.notes.add(f"joint '{name}': the keyframe's ball orientation and velocity are "
                               "not imported (the joint starts at rest in its reference pose)")
        else:
            ref = m.qpos0[qa]
            if abs(ref) > 0:
                self.notes.add(f"joint '{name}': MuJoCo's ref = {ref:.6g}; physdsl measures the "
                               "joint from the reference pose (its value is MuJoCo's minus ref)")
            if kq is not None:
                fs.append(field("initial", quantity(kq[0] - ref, u["q"])))
                fs.append(field("initial_velocity", quantity(kv[0], u["v"])))
            if m.jnt_limited[j]:
                fs.append(field("limits", quantity(m.jnt_range[j] - ref, u["q"])))
                self.notes.add(f"joint '{name}': limits become physdsl's hard limits (MuJoCo's are "
                               "soft, solref/solimp)")
        if kind == "ball" and m.jnt_limited[j]:
            self.notes.add(f"joint '{name}': a ball joint's cone limit is not expressible")
        self.joints.append(ast.JointItem(name, kind, parent, child, block(*fs)))
        self._joint_effects(j, name, kind, u)

    def _joint_effects(self, j: int, name: str, kind: str, u):
        m = self.m
        va, qa = m.jnt_dofadr[j], m.jnt_qposadr[j]
        damping = m.dof_damping[va]
        if damping > 0:
            self.effects.append(ast.EffectItem("joint_damping", (name,), block(
                field("coefficient", quantity(damping, u["damp"])))))
        fric = m.dof_frictionloss[va]
        if fric > 0:
            self.effects.append(ast.EffectItem("joint_friction", (name,), block(
                field("torque", quantity(fric, u["fric"])))))
            self.notes.add(f"joint '{name}': frictionloss becomes joint_friction, a smoothed "
                           "(tanh) dry friction; MuJoCo's is a constraint")
        k = m.jnt_stiffness[j]
        if k > 0:
            if kind == "ball":
                self.notes.add(f"joint '{name}': stiffness of a ball joint is not expressible")
            else:
                rest = m.qpos_spring[qa] - m.qpos0[qa]
                self.effects.append(ast.EffectItem("joint_spring", (name,), block(
                    field("stiffness", quantity(k, u["stiff"])), field("rest", quantity(rest, u["q"])))))
        poly = [getattr(m, a, None) for a in ("dof_dampingpoly", "jnt_stiffnesspoly")]
        if any(p is not None and np.any(p[i]) for p, i in zip(poly, (va, j))):
            self.notes.add(f"joint '{name}': polynomial damping/stiffness terms are not expressible")
        if m.dof_armature[va] > 0:
            self.notes.add(f"joint '{name}': armature {m.dof_armature[va]:.6g} (rotor inertia) is "
                           "not expressible")

    # ---- sites --------------------------------------------------------------------------------
    def sites(self):
        """Sites on moving bodies become markers (a point in the physdsl body's frame)."""
        m, d, mj = self.m, self.d, self.mj
        for s in range(m.nsite):
            b = m.site_bodyid[s]
            label = mj.mj_id2name(m, mj.mjtObj.mjOBJ_SITE, s) or f"#{s}"
            body = self.body_name.get(b, "world")
            if body == "world":
                self.notes.add(f"site '{label}' on the world or a static body: not expressed "
                               "(a marker rides on a moving body)")
                continue
            name = self._name(mj.mjtObj.mjOBJ_SITE, s, f"{body}_site")
            R = d.ximat[b].reshape(3, 3)
            local = R.T @ (d.site_xpos[s] - d.xipos[b])
            fs = [field("position", quantity(local, "m"))]
            if not np.allclose(m.site_rgba[s], (0.5, 0.5, 0.5, 1.0)):
                fs.append(field("color", quantity(m.site_rgba[s][:3], digits=6)))
            self.markers.append(ast.MarkerItem(name, body, block(*fs)))

    # ---- actuators, contacts, world ----------------------------------------------------------
    def actuators(self, controls: str | None):
        m, mj = self.m, self.mj
        used: set[str] = set()
        for a in range(m.nu):
            label = mj.mj_id2name(m, mj.mjtObj.mjOBJ_ACTUATOR, a) or f"#{a}"
            j = m.actuator_trnid[a][0]
            plain = (m.actuator_trntype[a] == mj.mjtTrn.mjTRN_JOINT and j in self.joint_name
                     and m.actuator_gaintype[a] == mj.mjtGain.mjGAIN_FIXED
                     and m.actuator_biastype[a] == mj.mjtBias.mjBIAS_NONE
                     and m.actuator_dyntype[a] == mj.mjtDyn.mjDYN_NONE
                     and self.joint_kind.get(j) in ("hinge", "slider"))
            if not plain:
                self.notes.add(f"actuator '{label}': only force actuators (motor/general with a fixed "
                               "gain, no bias, no dynamics) on a hinge or slide joint become controls")
                continue
            target = self.joint_name[j]
            if target in used:
                self.notes.add(f"actuator '{label}': a second control on joint '{target}' is not "
                               "expressible")
                continue
            used.add(target)
            name = self._name(mj.mjtObj.mjOBJ_ACTUATOR, a, f"{target}_motor")
            gain = m.actuator_gainprm[a][0] * m.actuator_gear[a][0]
            unit = _units(self.joint_kind[j])["ctrl"]
            gfield = None if abs(gain - 1) < 1e-15 else field("gain", quantity(gain))
            if controls is not None:
                self.controls.append(ast.ControlItem(name, target, controls, (name,),
                                                     block(gfield) if gfield else None))
            else:
                self.controls.append(ast.ControlItem(name, target, None, (), block(
                    gfield, field("times", quantity((0.0, 1.0), "s")),
                    field("values", quantity((0.0, 0.0), unit)))))
                self.notes.add(f"actuator '{label}': a control held at 0; give its sequence with "
                               f"`control {name} on {target} from \"controls.csv\" column {name}` "
                               "(or import with --controls FILE)")
            if m.actuator_ctrllimited[a]:
                self.notes.add(f"actuator '{label}': ctrlrange clamping is not expressible")
            if m.actuator_forcelimited[a]:
                self.notes.add(f"actuator '{label}': forcerange clamping is not expressible")

    def contact_items(self):
        """``contact`` statements for the pairs MuJoCo tests (see ``contacts``)."""
        self.contacts = contact_items(self.geom_pairs, self.geom_body, self.bodies, self.joints,
                                      self.files, self.notes)

    def world(self):
        m, mj = self.m, self.mj
        integ = "rk4" if m.opt.integrator == mj.mjtIntegrator.mjINT_RK4 else "semi_implicit_euler"
        if integ != "rk4":
            self.notes.add(f"integrator {str(mj.mjtIntegrator(m.opt.integrator)).split('_')[-1]}: "
                           "becomes semi_implicit_euler (MuJoCo's Euler integrates damping "
                           "implicitly); rollouts agree closely only with RK4")
        return ast.WorldItem(block(
            field("gravity", quantity(m.opt.gravity, "m/s^2")),
            field("timestep", quantity(m.opt.timestep, "s")),
            field("integrator", ast.Name(integ))))


class Imported(NamedTuple):
    """An imported scene: its text, what it could not express, mesh files to write beside it."""

    text: str
    notes: list[str]
    files: dict[str, str]


def read_model(spec, m, *, source: str, controls: str | None = None,
               key: str | None = None) -> Imported:
    """The scene of compiled model ``m`` (from ``spec``); ``source`` names the file in the
    header; ``controls``: a CSV file (relative to the scene) whose columns, named after the
    actuators, drive them; ``key``: keyframe name or index giving the initial state."""
    r = _Reader(spec, m, key)
    mj = r.mj
    static = {0}
    r.static_geoms(0)
    for b in range(1, m.nbody):
        if m.body_jntnum[b] == 0 and m.body_parentid[b] in static:
            static.add(b)
            r.body_name[b] = "world"
            if m.body_mocapid[b] >= 0:
                r.notes.add(f"mocap body '{mj.mj_id2name(m, mj.mjtObj.mjOBJ_BODY, b)}': imported "
                            "as fixed")
            r.static_geoms(b)
            continue
        child = r.moving_body(b)
        r.body_joints(b, child)
    r.sites()
    r.actuators(controls)
    r.contact_items()
    scan_spec(spec, m, r.notes)
    world = r.world()
    items = (world, *r.bodies, *r.markers, *r.joints, *r.effects, *r.contacts, *r.controls)
    scene_name = Names().make(spec.modelname or "imported", "imported")
    module = ast.Module((ast.SceneDecl(scene_name, items),))
    body = format_module(module)
    head = [f"# Imported from {source} by `physdsl import` (MuJoCo {mj.__version__})."]
    if r.notes.items:
        head.append("# Not expressed in physdsl (left out or approximated):")
        head += [f"#   - {n}" for n in r.notes.items]
    else:
        head.append("# Everything in the model is expressed in this scene.")
    return Imported("\n".join(head) + "\n\n" + body, list(r.notes.items), dict(r.files))
