"""A MuJoCo model as rerun entities: its geoms once, its body poses every frame.

Entity paths mirror the model's names: body ``car/gearshift_lever`` becomes
``world/car/gearshift_lever`` and its geom ``car/knob`` becomes
``world/car/gearshift_lever/knob`` (the prefix that ``MjSpec.attach`` adds is split on
``/``; the world body is ``world`` itself). Unnamed bodies and geoms get ``body_<id>`` and
``geom_<id>``.

Each body entity carries its pose relative to the nearest *entity* ancestor that is itself a
body (usually ``world``, so the pose is MuJoCo's ``xpos``/``xquat``), because rerun composes
transforms along entity paths, not along MuJoCo's kinematic tree. Geoms carry their fixed
pose in the body (``geom_pos``/``geom_quat``) and their shape, both static.

Only ``MjModel`` fields are read here; the per-frame poses come in as arrays (what
``WorldView.body_poses()`` returns: copies of ``xpos``/``xquat``), and :func:`default_view`
reads the reference pose through a :class:`~acoustic_sim.world.view.SceneView`, so this
module never touches ``MjData``, and nothing is written.
"""

from __future__ import annotations

import dataclasses

import mujoco
import numpy as np
import rerun as rr

from acoustic_sim.world import actuation
from acoustic_sim.world.view import SceneView

_GT = mujoco.mjtGeom
_DEFAULT_RGBA = np.array([0.5, 0.5, 0.5, 1.0], dtype=np.float32)


def _escape(name: str) -> str:
    return "/".join(rr.escape_entity_path_part(p) for p in name.split("/") if p)


def _rgba_u8(rgba) -> np.ndarray:
    return np.clip(np.round(np.asarray(rgba, dtype=np.float64) * 255.0), 0, 255).astype(np.uint8)


def _quat_xyzw(q_wxyz) -> np.ndarray:
    q = np.asarray(q_wxyz, dtype=np.float32)
    return q[..., [1, 2, 3, 0]]


def _quat_mul(a, b) -> np.ndarray:
    """Hamilton product of (..., 4) quaternions in MuJoCo's (w, x, y, z) order."""
    aw, ax, ay, az = np.moveaxis(a, -1, 0)
    bw, bx, by, bz = np.moveaxis(b, -1, 0)
    return np.stack([
        aw * bw - ax * bx - ay * by - az * bz,
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
    ], axis=-1)


def _rotate(q, v) -> np.ndarray:
    """Rotate (..., 3) vectors by (..., 4) unit quaternions (w, x, y, z)."""
    w = q[..., :1]
    u = q[..., 1:]
    t = 2.0 * np.cross(u, v)
    return v + w * t + np.cross(u, t)


def _vertex_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    tri = vertices[faces]
    fn = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    vn = np.zeros_like(vertices)
    for k in range(3):
        np.add.at(vn, faces[:, k], fn)
    norm = np.linalg.norm(vn, axis=1, keepdims=True)
    return (vn / np.where(norm > 0, norm, 1.0)).astype(np.float32)


@dataclasses.dataclass(frozen=True)
class GeomShape:
    """One geom, ready to log: entity path, fixed pose in its body, and the archetype."""

    entity: str
    translation: np.ndarray
    quaternion_xyzw: np.ndarray
    archetype: object
    kind: str


class SceneGeometry:
    """Entity paths, shapes and per-frame body poses of one ``mujoco.MjModel``.

    Parameters
    ----------
    model : mujoco.MjModel
        The compiled model (not modified).
    root : str
        Entity path of the world body (default ``world``).
    geom_groups : tuple of int
        Geom groups to draw (MuJoCo's viewer shows 0, 1 and 2; menagerie assets put
        collision geoms in group 3).
    plane_extent_m : float
        Half size, in metres, used for planes that MuJoCo declares infinite (size 0).
    """

    def __init__(self, model: mujoco.MjModel, *, root: str = "world", geom_groups: tuple[int, ...] = (0, 1, 2),
                 plane_extent_m: float = 5.0) -> None:
        self.model = model
        self.root = root
        self.geom_groups = tuple(int(g) for g in geom_groups)
        self.plane_extent_m = float(plane_extent_m)
        self.body_paths = self._body_paths()
        self.anchor = self._anchors()
        self.skipped: list[str] = []

    # -- names ---------------------------------------------------------------------------------

    def _body_paths(self) -> list[str]:
        m = self.model
        paths = [self.root]
        seen = {self.root}
        for b in range(1, m.nbody):
            name = _escape(mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, b) or "") or f"body_{b}"
            path = f"{self.root}/{name}"
            if path in seen:
                path = f"{path}_{b}"
            seen.add(path)
            paths.append(path)
        return paths

    def _anchors(self) -> np.ndarray:
        """For each body, the index of the nearest body whose path is an ancestor path (-1 for world)."""
        index = {p: i for i, p in enumerate(self.body_paths)}
        anchor = np.full(len(self.body_paths), -1, dtype=np.int64)
        for i, p in enumerate(self.body_paths[1:], start=1):
            parts = p.split("/")
            for k in range(len(parts) - 1, 0, -1):
                j = index.get("/".join(parts[:k]))
                if j is not None:
                    anchor[i] = j if j != 0 else -1
                    break
        return anchor

    # -- shapes --------------------------------------------------------------------------------

    def shapes(self) -> list[GeomShape]:
        """Every drawable geom of the model (groups in ``geom_groups``, alpha > 0)."""
        m = self.model
        out: list[GeomShape] = []
        used: set[str] = set(self.body_paths)
        self.skipped = []
        for g in range(m.ngeom):
            if int(m.geom_group[g]) not in self.geom_groups:
                continue
            rgba = np.array(m.geom_rgba[g], dtype=np.float32)
            matid = int(m.geom_matid[g])
            if matid >= 0 and np.allclose(rgba, _DEFAULT_RGBA):
                rgba = np.array(m.mat_rgba[matid], dtype=np.float32)
            if rgba[3] <= 0.0:
                continue
            name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, g) or ""
            leaf = rr.escape_entity_path_part(name.split("/")[-1]) if name.split("/")[-1] else f"geom_{g}"
            entity = f"{self.body_paths[int(m.geom_bodyid[g])]}/{leaf}"
            if entity in used:
                entity = f"{entity}_{g}"
            arch = self._archetype(g, _rgba_u8(rgba))
            if arch is None:
                self.skipped.append(entity)
                continue
            used.add(entity)
            out.append(GeomShape(entity=entity, translation=np.array(m.geom_pos[g], dtype=np.float32),
                                 quaternion_xyzw=_quat_xyzw(m.geom_quat[g]), archetype=arch,
                                 kind=_GT(int(m.geom_type[g])).name))
        return out

    def _archetype(self, g: int, color: np.ndarray):
        m = self.model
        t = int(m.geom_type[g])
        size = np.array(m.geom_size[g], dtype=np.float32)
        solid = rr.components.FillMode.Solid
        if t == _GT.mjGEOM_SPHERE:
            return rr.Ellipsoids3D(half_sizes=[[size[0]] * 3], colors=[color], fill_mode=solid)
        if t == _GT.mjGEOM_ELLIPSOID:
            return rr.Ellipsoids3D(half_sizes=[size], colors=[color], fill_mode=solid)
        if t == _GT.mjGEOM_BOX:
            return rr.Boxes3D(half_sizes=[size], colors=[color], fill_mode=solid)
        if t == _GT.mjGEOM_CAPSULE:  # rerun's capsule runs from its origin along +z
            return rr.Capsules3D(lengths=[2 * size[1]], radii=[size[0]], translations=[[0, 0, -size[1]]], colors=[color])
        if t == _GT.mjGEOM_CYLINDER:
            return rr.Cylinders3D(lengths=[2 * size[1]], radii=[size[0]], centers=[[0, 0, 0]], colors=[color], fill_mode=solid)
        if t == _GT.mjGEOM_PLANE:
            hx = size[0] if size[0] > 0 else self.plane_extent_m
            hy = size[1] if size[1] > 0 else self.plane_extent_m
            v = np.array([[-hx, -hy, 0], [hx, -hy, 0], [hx, hy, 0], [-hx, hy, 0]], dtype=np.float32)
            return rr.Mesh3D(vertex_positions=v, triangle_indices=[[0, 1, 2], [0, 2, 3]],
                             vertex_normals=np.tile([0, 0, 1], (4, 1)).astype(np.float32), albedo_factor=color)
        if t == _GT.mjGEOM_MESH:
            mid = int(m.geom_dataid[g])
            va, vn = int(m.mesh_vertadr[mid]), int(m.mesh_vertnum[mid])
            fa, fnum = int(m.mesh_faceadr[mid]), int(m.mesh_facenum[mid])
            verts = np.array(m.mesh_vert[va:va + vn], dtype=np.float32)
            faces = np.array(m.mesh_face[fa:fa + fnum], dtype=np.uint32)
            return rr.Mesh3D(vertex_positions=verts, triangle_indices=faces,
                             vertex_normals=_vertex_normals(verts, faces.astype(np.int64)), albedo_factor=color)
        if t == _GT.mjGEOM_HFIELD:
            return self._hfield(int(m.geom_dataid[g]), color)
        return None  # SDF and plugin geoms have no explicit shape to draw

    def _hfield(self, hid: int, color: np.ndarray):
        m = self.model
        nrow, ncol = int(m.hfield_nrow[hid]), int(m.hfield_ncol[hid])
        rx, ry, top, _base = (float(s) for s in m.hfield_size[hid])
        adr = int(m.hfield_adr[hid])
        z = np.array(m.hfield_data[adr:adr + nrow * ncol], dtype=np.float32).reshape(nrow, ncol) * top
        x, y = np.meshgrid(np.linspace(-rx, rx, ncol, dtype=np.float32), np.linspace(-ry, ry, nrow, dtype=np.float32))
        verts = np.stack([x, y, z], axis=-1).reshape(-1, 3)
        i = np.arange(nrow * ncol).reshape(nrow, ncol)
        a, b, c, d = i[:-1, :-1].ravel(), i[:-1, 1:].ravel(), i[1:, 1:].ravel(), i[1:, :-1].ravel()
        faces = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)]).astype(np.int64)
        return rr.Mesh3D(vertex_positions=verts, triangle_indices=faces.astype(np.uint32),
                         vertex_normals=_vertex_normals(verts, faces), albedo_factor=color)

    # -- poses ---------------------------------------------------------------------------------

    def body_poses(self, xpos, xquat) -> tuple[np.ndarray, np.ndarray]:
        """Pose of every body entity relative to its anchor entity.

        Parameters
        ----------
        xpos : array_like
            (nbody, 3) world positions of the bodies, metres, indexed by body id
            (``WorldView.body_poses()[0]``).
        xquat : array_like
            (nbody, 4) world orientations, MuJoCo's (w, x, y, z) order
            (``WorldView.body_poses()[1]``).

        Returns
        -------
        translation : numpy.ndarray
            float32 (nbody, 3), metres.
        quaternion : numpy.ndarray
            float32 (nbody, 4), rerun's (x, y, z, w) order.

        Raises
        ------
        ValueError
            If the arrays do not have one row per body of the model.
        """
        n = len(self.body_paths)
        pos = np.array(xpos, dtype=np.float64)
        quat = np.array(xquat, dtype=np.float64)
        if pos.shape != (n, 3) or quat.shape != (n, 4):
            raise ValueError(f"body poses must be ({n}, 3) positions and ({n}, 4) quaternions for this model, "
                             f"got {pos.shape} and {quat.shape}")
        rel = self.anchor >= 0
        if rel.any():
            a = self.anchor[rel]
            qa_conj = quat[a] * np.array([1.0, -1.0, -1.0, -1.0])
            pos[rel] = _rotate(qa_conj, pos[rel] - pos[a])
            quat[rel] = _quat_mul(qa_conj, quat[rel])
        return pos.astype(np.float32), _quat_xyzw(quat)


def default_view(model: mujoco.MjModel) -> tuple[np.ndarray, np.ndarray]:
    """A 3D-view pose for the model at its reference configuration: (look target, eye position).

    Looks at the robot's head (a body named ``.../head``) from behind, left and above, so the
    head, its arrows and the direction sphere are in front; without a head, at the centre of
    the geoms from outside their bounding box.
    """
    at_rest = SceneView(model, actuation.reference_pose(model))
    names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, b) or "" for b in range(model.nbody)]
    head = next((b for b, n in enumerate(names) if n == "head" or n.endswith("/head")), None)
    if head is not None:
        h = at_rest.body_poses()[0][head]
        return h + np.array([0.35, 0.0, -0.15]), h + np.array([-1.1, 1.0, 0.75])
    if model.ngeom:
        geoms = at_rest.geom_positions()
        lo, hi = geoms.min(axis=0), geoms.max(axis=0)
        c = (lo + hi) / 2
        r = max(float(np.linalg.norm(hi - lo)), 1.0)
        return c, c + r * np.array([-0.8, 0.6, 0.5])
    return np.zeros(3), np.array([-3.0, 2.0, 2.0])
