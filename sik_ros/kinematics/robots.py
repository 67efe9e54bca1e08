"""Loading an arm: an example-robot-data name or a URDF file, to a :class:`Robot`.

Any serial chain of revolute joints works:

- continuous joints become revolute joints over [-2 pi, 2 pi] and, like revolute joints whose
  range spans a turn, are *periodic* (the data sweeps one turn; the solver adds the 2 pi
  equivalents back);
- a floating or planar root, every joint off the base-to-tip chain (grippers, other limbs) and
  every joint above the base are locked;
- a prismatic joint in the chain is refused, naming it;
- an ambiguous frame name resolves to the body (or fixed) frame;
- without frames, the base is the parent link of the chain's first joint and the tip the end of
  the longest revolute chain (a frame named like ``tool0``, ``*tcp*``, ``*end_effector*``,
  ``*eef*``, ``*ee*`` on it when there is one; gripper and finger joints do not count).

Artifacts record the robot's manifest (:meth:`Robot.manifest`); :func:`robot_from_manifest`
loads it back and refuses a URDF that moved or changed.
"""

from collections import Counter
import functools
import os
from pathlib import Path
import re
from typing import Dict, List, Mapping, Optional, Tuple
import xml.etree.ElementTree as ElementTree

import pinocchio as pin

from sik_ros.artifacts import check_robot_manifest
from sik_ros.errors import (ArtifactMismatch, CorruptArtifact, FrameNotFound, InvalidArgument,
                            InvalidModel, RobotNotFound)
from sik_ros.kernels.angles import TURN
from sik_ros.kinematics.description import expand_xacro, is_xacro_text
from sik_ros.kinematics.model_tree import chain_joint, find_frame, rename_frame
from sik_ros.kinematics.robot import Robot, sha256_file

#: Default base and tip frames of robots whose own choice differs from the inferred one.
KNOWN_FRAMES = {
    'panda': ('panda_link0', 'panda_hand_tcp'),
}
#: Simplified collision geometry (capsules, spheres) used for a named robot when available.
COLLISION_VARIANTS = {
    'panda': 'panda_collision',
}
#: Tip frame names preferred on the last link, best first (regular expressions, lower case).
TIP_NAMES = (r'^tool0$', r'tcp', r'end_?effector', r'eef', r'(^|_)ee(_|$)', r'tool', r'flange')
#: Joints that are part of a hand, not of the arm (never counted for the default tip).
GRIPPER_JOINT = re.compile(r'finger|gripper|hand|thumb|knuckle|jaw', re.IGNORECASE)
#: Range given to continuous joints [rad].
CONTINUOUS_RANGE = TURN


def prepare_urdf(text: str) -> Tuple[str, List[str]]:
    """A URDF's text with its continuous joints turned into revolute joints over +-2 pi.

    Returns:
        the new text and the names of the joints changed.

    Raises:
        InvalidModel: the text is not XML.
    """
    try:
        root = ElementTree.fromstring(text)
    except ElementTree.ParseError as exc:
        raise InvalidModel(f'not a URDF (XML): {exc}') from exc
    changed = []
    for joint in root.iter('joint'):
        if joint.get('type') != 'continuous':
            continue
        joint.set('type', 'revolute')
        limit = joint.find('limit')
        if limit is None:
            limit = ElementTree.SubElement(joint, 'limit', effort='0', velocity='0')
        limit.set('lower', repr(-CONTINUOUS_RANGE))
        limit.set('upper', repr(CONTINUOUS_RANGE))
        changed.append(joint.get('name'))
    if not changed:
        return text, []
    return ElementTree.tostring(root, encoding='unicode'), changed


def build_model(urdf: Path) -> pin.Model:
    """The Pinocchio model of a URDF file, continuous joints made periodic revolute ones.

    Raises:
        InvalidModel: unreadable or unparsable.
    """
    try:
        text = Path(urdf).read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise InvalidModel(f'cannot read URDF {urdf}: {exc}') from exc
    text, _ = prepare_urdf(text)
    try:
        model = pin.buildModelFromXML(text)
    except (RuntimeError, ValueError) as exc:
        raise InvalidModel(f'cannot parse URDF {urdf}: {exc}') from exc
    return unique_frame_names(model)


def unique_frame_names(model: pin.Model) -> pin.Model:
    """``model`` with every fixed frame that shares a body's name renamed ``<name>_<type>``.

    A link and a joint may share a name in a URDF; Pinocchio's model reduction then refuses
    the name. The body keeps it, so a frame asked for by that name is the link (a moving
    joint keeps its name: :class:`~sik_ros.kinematics.robot.Robot` handles it at the reduction).
    """
    count = Counter(f.name for f in model.frames)
    for i, frame in enumerate(model.frames):
        kind = str(frame.type).split('.')[-1]
        if count[frame.name] > 1 and kind not in ('BODY', 'JOINT'):
            rename_frame(model, i, f'{frame.name}_{kind.lower()}')
    return model


def _depths(model: pin.Model, grippers: bool) -> Dict[int, int]:
    """Per joint, the number of arm joints (revolute; gripper ones only if ``grippers``) above."""
    depth = {0: 0}
    for j in range(1, model.njoints):
        arm = model.joints[j].shortname() in ('JointModelRX', 'JointModelRY', 'JointModelRZ',
                                              'JointModelRevoluteUnaligned') \
            and (grippers or not GRIPPER_JOINT.search(model.names[j]))
        depth[j] = depth[model.parents[j]] + int(arm)
    return depth


def tip_candidates(model: pin.Model) -> List[str]:
    """Frames that could be the tip, best first: those on the ends of the longest chains.

    Joints named like a gripper's do not count, unless no other revolute joint is there (a
    finger robot).
    """
    depth = _depths(model, grippers=False)
    grippers = max(depth.values()) == 0
    if grippers:
        depth = _depths(model, grippers=True)
    best = max(depth.values())
    if best == 0:
        return []
    ends = [j for j, d in depth.items() if d == best and j > 0
            and (grippers or not GRIPPER_JOINT.search(model.names[j]))
            and model.joints[j].shortname() != 'JointModelFreeFlyer']
    # the deepest arm joint of each end: the joint itself (gripper joints do not count)
    names: List[str] = []
    for j in ends:
        frames = [f for f in model.frames if f.parentJoint == j and f.name != model.names[j]
                  and str(f.type).endswith(('BODY', 'OP_FRAME', 'FIXED_JOINT'))]
        bodies = [f.name for f in frames if str(f.type).endswith(('BODY', 'OP_FRAME'))]
        for pattern in TIP_NAMES:
            names += [n for n in bodies if re.search(pattern, n.lower()) and n not in names]
        names += [n for n in reversed(bodies) if n not in names]
    return names


def default_frames(model: pin.Model) -> Tuple[str, str]:
    """The base (parent link of the chain's first joint) and the tip of a model's arm.

    Raises:
        InvalidModel: the model has no revolute chain (the message lists candidate tips).
    """
    tips = tip_candidates(model)
    if not tips:
        raise InvalidModel('no chain of revolute joints in the model: give --base and --tip')
    tip_id = find_frame(model, tips[0])
    j = model.frames[tip_id].parentJoint
    chain = []
    while j > 0:
        if chain_joint_or_none(model, j):
            chain.append(j)
        j = model.parents[j]
    first = chain[-1]
    joint_frame = [i for i, f in enumerate(model.frames)
                   if f.name == model.names[first] and str(f.type).endswith('JOINT')][0]
    base = model.frames[model.frames[joint_frame].parentFrame].name
    return base, tips[0]


def chain_joint_or_none(model: pin.Model, j: int) -> bool:
    """:func:`chain_joint`, False for a joint it would refuse."""
    try:
        return chain_joint(model, j)
    except InvalidModel:
        return False


def package_dirs(urdf: Path) -> List[str]:
    """Where the ``package://`` meshes of a URDF file may be: the folders that hold packages.

    First ``ROS_PACKAGE_PATH`` (the user's word wins), then the URDF's own folder and every
    folder above it (a URDF in ``src/my_arm_description/urdf`` names its meshes
    ``package://my_arm_description/...``, found from ``src``), then each ``share`` folder of a
    sourced ROS workspace (``AMENT_PREFIX_PATH``).
    """
    path = Path(urdf).resolve()
    dirs = [d for d in os.environ.get('ROS_PACKAGE_PATH', '').split(os.pathsep) if d]
    dirs += [str(d) for d in path.parents]
    for prefix in os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep):
        if prefix and Path(prefix, 'share').is_dir():
            dirs.append(str(Path(prefix, 'share')))
    return dirs


def available_robots() -> list:
    """Names of the robots example-robot-data can load."""
    from example_robot_data.robots_loader import ROBOTS
    return sorted(ROBOTS)


def _resolve_frames(model: pin.Model, name: str, base: Optional[str],
                    tip: Optional[str]) -> Tuple[str, str]:
    """The given frames, or the robot's known or inferred defaults; every name checked."""
    known = KNOWN_FRAMES.get(name)
    if base is None or tip is None:
        default = known if known else default_frames(model)
        base, tip = base or default[0], tip or default[1]
    for frame in (base, tip):
        find_frame(model, frame)
    return base, tip


@functools.lru_cache(maxsize=8)
def load_robot(name: str = 'panda', urdf: Optional[str] = None, base: Optional[str] = None,
               tip: Optional[str] = None) -> Robot:
    """Load a robot arm by example-robot-data name or from a URDF file.

    Args:
        name: example-robot-data robot name (ignored when ``urdf`` is given).
        urdf: path to a URDF file.
        base: base frame name (default: the robot's known one, else inferred).
        tip: tip frame name (default: the robot's known one, else inferred).

    Raises:
        RobotNotFound: unknown robot name (the message lists the available ones).
        FrameNotFound: a base or tip frame that is not in the model (the message lists frames).
        InvalidModel: a chain sik_ros cannot handle, naming the joint.
    """
    if urdf is not None:
        path = Path(urdf)
        if not path.is_file():
            raise InvalidArgument(f'URDF file not found: {path}')
        model = build_model(path)
        base, tip = _resolve_frames(model, '', base, tip)
        robot_name = model.name or path.stem
        return Robot(robot_name, path, model, base, tip, package_dirs=package_dirs(path),
                     urdf_source=path)
    robots = available_robots()
    if name not in robots:
        raise RobotNotFound(name, robots)
    import example_robot_data as erd
    from example_robot_data.robots_loader import ROBOTS
    loaded = erd.load(name)
    urdf_path = Path(loaded.urdf)
    model = build_model(urdf_path)
    base, tip = _resolve_frames(model, name, base, tip)
    share = urdf_path.parents[3] if len(urdf_path.parents) > 3 else urdf_path.parent
    collision_urdf, srdf = urdf_path, None
    variant = COLLISION_VARIANTS.get(name)
    if variant in ROBOTS:
        collision_urdf = Path(erd.load(variant).urdf)
    loader = ROBOTS[name]
    srdf_candidate = urdf_path.parent.parent / 'srdf' / f'{loader.srdf_filename}' \
        if getattr(loader, 'srdf_filename', None) else None
    if srdf_candidate is not None and srdf_candidate.is_file():
        srdf = srdf_candidate
    return Robot(name, urdf_path, model, base, tip,
                 package_dirs=[str(share.parent), str(share)],
                 collision_urdf=collision_urdf, srdf_path=srdf)


def robot_from_manifest(manifest: Mapping, what: str = 'artifact') -> Robot:
    """The robot an artifact's manifest names, checked against it.

    Raises:
        CorruptArtifact: a manifest without the robot's name, frames or joints.
        ArtifactMismatch: a URDF that moved or changed, or a chain that differs.
    """
    if not isinstance(manifest, Mapping) or not all(
            isinstance(manifest.get(k), str) for k in ('robot', 'base_frame', 'tip_frame')):
        raise CorruptArtifact(f'{what}: its robot manifest lacks robot, base_frame or tip_frame')
    urdf = manifest.get('urdf')
    if urdf is not None:
        path = Path(urdf)
        if not path.is_file():
            raise ArtifactMismatch(f'{what}: URDF (moved or deleted?)', str(path), 'no file')
        found = sha256_file(path)
        if found != manifest.get('urdf_sha256'):
            raise ArtifactMismatch(f'{what}: URDF {path} changed since it was made; sha256',
                                   manifest.get('urdf_sha256'), found)
    try:
        robot = load_robot(manifest['robot'], urdf, manifest['base_frame'],
                           manifest['tip_frame'])
    except FrameNotFound as exc:
        raise ArtifactMismatch(f'{what}: frame', exc.frame, 'not in the robot model') from exc
    check_robot_manifest(what, robot.manifest(), manifest)
    return robot


def chain_differences(robot: Robot, urdf_text: str, tol: float = 1e-6) -> List[str]:
    """How the base-to-tip chain of a URDF (a string) differs from ``robot``'s; empty if alike.

    Compared: the joint names, axes, placements and limits of the chain between the robot's
    base and tip frames, and the base and tip placements.

    A xacro text (one that declares the xacro namespace) is expanded first, its includes found
    from the current folder.

    Raises:
        InvalidModel: the text is not a URDF Pinocchio can read, or xacro failed on it.
    """
    import tempfile
    import numpy as np
    if is_xacro_text(urdf_text):
        urdf_text = expand_xacro(urdf_text)
    text, _ = prepare_urdf(urdf_text)
    try:
        model = unique_frame_names(pin.buildModelFromXML(text))
    except (RuntimeError, ValueError) as exc:
        raise InvalidModel(f'cannot parse the robot_description URDF: {exc}') from exc
    with tempfile.NamedTemporaryFile('w', suffix='.urdf') as f:
        f.write(urdf_text)
        f.flush()
        try:
            other = Robot(model.name, Path(f.name), model, robot.base_frame, robot.tip_frame)
        except (FrameNotFound, InvalidModel) as exc:
            return [f'its chain {robot.base_frame} -> {robot.tip_frame} cannot be built: {exc}']
    if other.joint_names != robot.joint_names:
        return [f'joints {other.joint_names} instead of {robot.joint_names}']
    out = []
    per_joint = (('lower limits', robot.lower, other.lower),
                 ('upper limits', robot.upper, other.upper),
                 ('axes', robot.chain.axes, other.chain.axes),
                 ('placements', robot.chain.joint_translations, other.chain.joint_translations),
                 ('orientations', robot.chain.joint_rotations, other.chain.joint_rotations))
    for what, a, b in per_joint:
        bad = [n for n, x, y in zip(robot.joint_names, a, b) if not np.allclose(x, y, atol=tol)]
        if bad:
            out.append(f'joint {what} differ at {bad}')
    for what, a, b in (('tip placement', robot.chain.tip_translation,
                        other.chain.tip_translation),
                       ('tip orientation', robot.chain.tip_rotation, other.chain.tip_rotation),
                       ('base placement', robot.chain.base_translation,
                        other.chain.base_translation),
                       ('base orientation', robot.chain.base_rotation,
                        other.chain.base_rotation)):
        if not np.allclose(a, b, atol=tol):
            out.append(f'{what} differs')
    return out
