"""An arm from ``robot_description`` (URDF text) and two frames, as a ROS node receives it.

:func:`read_description` checks the text (size, XML, xacro) and builds the Pinocchio model;
:func:`arm_files` writes the URDF and its collision variant (the ``<collision>`` elements whose
meshes resolve here; meshes are not needed for IK) into a folder; :func:`chain_key` names the
chain by a hash of what defines it (kinematics, limits, frames, collision geometry), the key of
an arm's cache entry (:mod:`sik_ros.bundles.cache`).
"""

from dataclasses import dataclass
import hashlib
import json
import os
from pathlib import Path
from typing import List, Sequence, Tuple
from urllib.parse import unquote, urlparse
import xml.etree.ElementTree as ElementTree

import numpy as np
import pinocchio as pin

from sik_ros.errors import FrameNotFound, InvalidModel
from sik_ros.kinematics.description import expand_xacro, is_xacro_text
from sik_ros.kinematics.model_tree import chain_path
from sik_ros.kinematics.robot import Robot
from sik_ros.kinematics.robots import prepare_urdf, unique_frame_names

#: Largest robot_description taken [bytes] (a whole robot's URDF is well under 1 MB).
MAX_DESCRIPTION_BYTES = 16 * 1024 * 1024
#: Most joints a chain may have (an arm; the tables and the training are sized for arms).
MAX_CHAIN_JOINTS = 16
#: Version of the chain key's content: a change of what it hashes changes every key.
KEY_VERSION = 1
#: The arm's URDF in a folder (a cache entry).
ARM_FILE = 'arm.urdf'
#: Frames a "not found" message lists at most.
LISTED_FRAMES = 12


@dataclass(frozen=True)
class Description:
    """A checked robot_description.

    Attributes:
        text: the URDF (xacro expanded).
        model: its Pinocchio model (continuous joints made periodic revolute ones).
        name: the robot's name in the URDF.
    """

    text: str
    model: pin.Model
    name: str


def read_description(text: str) -> Description:
    """Check a robot_description and build its model.

    Raises:
        InvalidModel: empty, too large, not XML, not a URDF Pinocchio reads, or xacro failed.
    """
    if not isinstance(text, str) or not text.strip():
        raise InvalidModel('robot_description is empty')
    size = len(text.encode('utf-8', errors='replace'))
    if size > MAX_DESCRIPTION_BYTES:
        raise InvalidModel(f'robot_description is {size / 1e6:.1f} MB, over the '
                           f'{MAX_DESCRIPTION_BYTES / 1e6:.0f} MB a URDF may have here')
    if is_xacro_text(text):
        text = expand_xacro(text)
    prepared, _ = prepare_urdf(text)
    root = ElementTree.fromstring(prepared)
    if root.tag != 'robot':
        raise InvalidModel(f'robot_description is XML but not a URDF (root <{root.tag}>)')
    try:
        model = unique_frame_names(pin.buildModelFromXML(prepared))
    except (RuntimeError, ValueError) as exc:
        raise InvalidModel(f'robot_description: Pinocchio cannot read it: '
                           f'{" ".join(str(exc).split())[:300]}') from exc
    return Description(text, model, root.get('name') or model.name or 'robot')


def check_chain(desc: Description, base: str, tip: str) -> List[str]:
    """The joints of the chain ``base`` -> ``tip`` (names), checked for an arm.

    Raises:
        InvalidModel: no frames given, an unknown frame (naming a few that exist), a tip not
            below the base, no movable joint between them, a joint the chain cannot have, a
            mimic joint in it, or more than :data:`MAX_CHAIN_JOINTS` joints.
    """
    if not base or not tip:
        raise InvalidModel('base_frame and tip_frame must name the chain\'s frames')
    model = desc.model
    for what, frame in (('base_frame', base), ('tip_frame', tip)):
        if not any(f.name == frame for f in model.frames):
            links = [f.name for f in model.frames if f.type == pin.FrameType.BODY]
            more = f', ... ({len(links)} links)' if len(links) > LISTED_FRAMES else ''
            raise InvalidModel(f'{what} {frame!r} is not in robot_description (links: '
                               f'{", ".join(links[:LISTED_FRAMES])}{more})')
    try:
        path = chain_path(model, base, tip)
    except FrameNotFound as exc:  # pragma: no cover - checked above
        raise InvalidModel(str(exc)) from exc
    names = [model.names[j] for j in path]
    if len(names) > MAX_CHAIN_JOINTS:
        raise InvalidModel(f'the chain {base} -> {tip} has {len(names)} joints; sik_ros '
                           f'serves arms of at most {MAX_CHAIN_JOINTS}')
    mimic = mimic_joints(desc.text)
    bad = [n for n in names if n in mimic]
    if bad:
        raise InvalidModel(f'joints {bad} of the chain {base} -> {tip} mimic others; a chain '
                           f'of independent joints is needed')
    return names


def mimic_joints(text: str) -> List[str]:
    """Names of the joints a URDF declares as mimicking another."""
    root = ElementTree.fromstring(text)
    return [j.get('name') for j in root.iter('joint') if j.find('mimic') is not None]


def collision_text(text: str, folders: Sequence[str]) -> Tuple[str, List[str]]:
    """The URDF with each ``<collision>`` whose mesh does not resolve here taken out.

    Meshes named ``package://pkg/...`` are looked for in ``folders`` (folders holding
    packages: ROS_PACKAGE_PATH, sourced workspaces), ``file://`` and plain paths as given;
    those found are written as absolute paths. Shapes (boxes, cylinders, spheres) always stay.

    Returns:
        the text and the mesh names left out (empty: every mesh resolved).
    """
    root = ElementTree.fromstring(text)
    missing = []
    for link in root.iter('link'):
        for col in list(link.findall('collision')):
            mesh = col.find('geometry/mesh')
            if mesh is None:
                continue
            uri = mesh.get('filename', '')
            found = resolve_mesh(uri, folders)
            if found is None:
                missing.append(uri)
                link.remove(col)
            else:
                mesh.set('filename', str(found))
    return ElementTree.tostring(root, encoding='unicode'), missing


def resolve_mesh(uri: str, folders: Sequence[str]):
    """The file a mesh URI names, or None where it cannot be found here."""
    if uri.startswith('package://'):
        rel = unquote(uri[len('package://'):])
        for folder in folders:
            path = Path(folder, rel)
            if path.is_file():
                return path.resolve()
        return None
    path = Path(unquote(urlparse(uri).path)) if uri.startswith('file://') else Path(uri)
    return path.resolve() if uri and path.is_absolute() and path.is_file() else None


def arm_files(desc: Description, folder: Path) -> Tuple[Path, List[str]]:
    """Write the arm's URDF into ``folder``: the description, its collision meshes resolved.

    The collision meshes found here are named by their absolute paths and those not found are
    left out (:func:`collision_text`), so that the file loads anywhere on this machine (a
    build in another process reads the same file).

    Returns:
        the URDF file (``arm.urdf``) and the meshes left out.
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    urdf = folder / ARM_FILE
    text, missing = collision_text(desc.text, mesh_folders())
    tmp = folder / f'.{ARM_FILE}.{os.getpid()}.tmp'
    tmp.write_text(text)
    os.replace(tmp, urdf)
    return urdf, missing


def mesh_folders() -> List[str]:
    """Folders that hold packages here: ROS_PACKAGE_PATH, then sourced workspaces' share."""
    dirs = [d for d in os.environ.get('ROS_PACKAGE_PATH', '').split(os.pathsep) if d]
    for prefix in os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep):
        if prefix and Path(prefix, 'share').is_dir():
            dirs.append(str(Path(prefix, 'share')))
    return dirs


def arm_robot(desc: Description, urdf: Path, base: str, tip: str) -> Robot:
    """The :class:`Robot` of the chain ``base`` -> ``tip`` of a file :func:`arm_files` wrote.

    Raises:
        InvalidModel: a chain sik_ros cannot serve (see :func:`check_chain`), or a file that
            is not the description's.
    """
    check_chain(desc, base, tip)
    try:
        model = unique_frame_names(pin.buildModelFromXML(prepare_urdf(Path(urdf).read_text())[0]))
    except (OSError, RuntimeError, ValueError) as exc:
        raise InvalidModel(f'cannot read {urdf}: {exc}') from exc
    return Robot(model.name or Path(urdf).stem, urdf, model, base, tip, urdf_source=urdf)


def chain_key(robot: Robot) -> str:
    """A hash of what defines the chain: kinematics, limits, frames, collision geometry.

    Two descriptions that differ elsewhere (other limbs, comments, visual meshes) give the
    same key; a moved joint, a changed limit or collision shape another.
    """
    c = robot.chain

    def rounded(a) -> list:
        return np.round(np.asarray(a, dtype=float), 9).tolist()

    content = {
        'key_version': KEY_VERSION, 'base_frame': robot.base_frame,
        'tip_frame': robot.tip_frame, 'joints': list(robot.joint_names),
        'lower': rounded(robot.lower), 'upper': rounded(robot.upper),
        'velocity': rounded(robot.velocity_limits), 'axes': rounded(c.axes),
        'rotations': rounded(c.joint_rotations), 'translations': rounded(c.joint_translations),
        'base': rounded(np.c_[c.base_rotation, c.base_translation]),
        'tip': rounded(np.c_[c.tip_rotation, c.tip_translation]),
        'collision': collision_signature(robot),
    }
    text = json.dumps(content, sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()[:24]


def collision_signature(robot: Robot) -> list:
    """Each collision part's link, placement, shape and local bounding box (rounded)."""
    out = []
    geom = robot.collision_model
    for obj in geom.geometryObjects:
        obj.geometry.computeLocalAABB()
        box = obj.geometry.aabb_local
        out.append([robot.model.names[obj.parentJoint], type(obj.geometry).__name__,
                    np.round(obj.placement.homogeneous, 9).tolist(),
                    np.round(np.r_[box.min_, box.max_], 9).tolist()])
    return sorted(out, key=json.dumps)
