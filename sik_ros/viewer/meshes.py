"""The arm's geometry for drawing: one triangle mesh per URDF visual, posed by forward kinematics.

The meshes come from the URDF's ``<visual>`` elements as Pinocchio loads them (meshes through
assimp, so Collada and STL alike; boxes, spheres, cylinders and capsules as triangle meshes),
and from ``<collision>`` for an arm whose URDF has no visual geometry. Poses are in the robot's
base frame, the frame of the solver's targets.
"""

from dataclasses import dataclass
from typing import List, Tuple

import coal
import numpy as np
import pinocchio as pin

from sik_ros.errors import InvalidModel
from sik_ros.kinematics.model_tree import find_frame
from sik_ros.kinematics.robot import Robot


@dataclass(frozen=True)
class Part:
    """One drawable piece of the arm.

    Attributes:
        name: the geometry object's name (``<link>_<i>``).
        vertices: (V, 3) float32 vertices in the piece's own frame [m].
        faces: (F, 3) uint32 vertex indices.
        color: RGB 0-255 from the URDF's material (grey where it gives none).
    """

    name: str
    vertices: np.ndarray
    faces: np.ndarray
    color: Tuple[int, int, int]


def _shape_mesh(geometry) -> Tuple[np.ndarray, np.ndarray]:
    """Vertices and faces of a coal geometry; empty arrays for a kind it cannot draw."""
    import trimesh
    if isinstance(geometry, coal.BVHModelBase):
        tris = geometry.tri_indices
        faces = np.array([[tris(i)[k] for k in range(3)] for i in range(geometry.num_tris)],
                         dtype=np.uint32).reshape(-1, 3)
        return np.asarray(geometry.vertices(), dtype=np.float32).reshape(-1, 3), faces
    if isinstance(geometry, coal.Box):
        mesh = trimesh.creation.box(extents=2 * np.asarray(geometry.halfSide))
    elif isinstance(geometry, coal.Sphere):
        mesh = trimesh.creation.icosphere(subdivisions=2, radius=geometry.radius)
    elif isinstance(geometry, coal.Cylinder):
        mesh = trimesh.creation.cylinder(radius=geometry.radius, height=2 * geometry.halfLength)
    elif isinstance(geometry, coal.Capsule):
        mesh = trimesh.creation.capsule(height=2 * geometry.halfLength, radius=geometry.radius)
    else:
        return np.zeros((0, 3), np.float32), np.zeros((0, 3), np.uint32)
    return np.asarray(mesh.vertices, np.float32), np.asarray(mesh.faces, np.uint32)


def _parts(geom: pin.GeometryModel) -> Tuple[List[Part], List[int]]:
    """The drawable parts of a geometry model and their object indices."""
    parts, ids = [], []
    for i, obj in enumerate(geom.geometryObjects):
        vertices, faces = _shape_mesh(obj.geometry)
        if len(faces) == 0:
            continue
        rgb = np.clip(np.asarray(obj.meshColor[:3], dtype=float), 0.0, 1.0)
        parts.append(Part(obj.name, vertices, faces, tuple(int(round(255 * c)) for c in rgb)))
        ids.append(i)
    return parts, ids


class ArmMeshes:
    """The arm's parts and their poses for given joint values.

    Raises:
        InvalidModel: neither its visual nor its collision geometry can be loaded or drawn.
    """

    def __init__(self, robot: Robot):
        self.robot = robot
        parts: List[Part] = []
        for load in (robot.visual_model, lambda: robot.collision_model):
            try:
                geom = load()
            except InvalidModel:
                continue
            parts, ids = _parts(geom)
            if parts:
                break
        if not parts:
            raise InvalidModel(f'{robot.name}: no visual or collision geometry to draw')
        self.parts = parts
        self._geom, self._ids = geom, ids
        self._gdata = pin.GeometryData(geom)
        self._data = robot.model.createData()
        self._base = find_frame(robot.model, robot.base_frame)

    def poses(self, q: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
        """Each part's orientation (P, 4) quaternion w x y z and position (P, 3) [m].

        Args:
            q: joint values (n,) [rad].

        Returns:
            poses in the base frame.
        """
        model, data = self.robot.model, self._data
        pin.forwardKinematics(model, data, np.asarray(q, dtype=float))
        pin.updateGeometryPlacements(model, data, self._geom, self._gdata)
        base_inv = pin.updateFramePlacement(model, data, self._base).inverse()
        wxyz = np.empty((len(self._ids), 4))
        xyz = np.empty((len(self._ids), 3))
        for k, i in enumerate(self._ids):
            placement = base_inv * self._gdata.oMg[i]
            x, y, z, w = pin.Quaternion(placement.rotation).coeffs()
            wxyz[k] = (w, x, y, z)
            xyz[k] = placement.translation
        return wxyz, xyz

    def poses_batch(self, qs: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
        """:meth:`poses` for (k, n) joint values: (k, P, 4) and (k, P, 3)."""
        out = [self.poses(q) for q in np.asarray(qs, dtype=float).reshape(-1, self.robot.dof)]
        if not out:
            return np.zeros((0, len(self.parts), 4)), np.zeros((0, len(self.parts), 3))
        return np.stack([o[0] for o in out]), np.stack([o[1] for o in out])
