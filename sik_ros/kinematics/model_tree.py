"""Pinocchio model trees: frames by name, the joints of a base-to-tip chain, renames.

What :class:`~sik_ros.kinematics.robot.Robot` needs to cut an arm out of a whole model (a robot
with grippers, other limbs or a floating root) and :mod:`sik_ros.kinematics.robots` to check a
URDF's joints.
"""

from typing import Dict, List, Set

import pinocchio as pin

from sik_ros.errors import FrameNotFound, InvalidModel

#: Pinocchio's revolute joint types and their axes.
REVOLUTE_AXES = {
    'JointModelRX': (1.0, 0.0, 0.0),
    'JointModelRY': (0.0, 1.0, 0.0),
    'JointModelRZ': (0.0, 0.0, 1.0),
}


#: Frame types in the order an ambiguous frame name resolves to (a body before its joint).
FRAME_PREFERENCE = ('BODY', 'OP_FRAME', 'FIXED_JOINT', 'JOINT', 'SENSOR')
#: Joint types that can only be a floating or planar root: locked at their neutral value.
ROOT_JOINTS = ('JointModelFreeFlyer', 'JointModelPlanar', 'JointModelSpherical',
               'JointModelSphericalZYX', 'JointModelTranslation')


def unused_name(taken: Set[str], name: str) -> str:
    """``name``, or ``name_2``, ``name_3``, ... : the first not in ``taken`` (then added to it)."""
    candidate, k = name, 2
    while candidate in taken:
        candidate, k = f'{name}_{k}', k + 1
    taken.add(candidate)
    return candidate


def rename_frame(model: pin.Model, i: int, name: str) -> None:
    """Give frame ``i`` of ``model`` a new name (Pinocchio's frames are copied out and back)."""
    frame = model.frames[i]
    frame.name = name
    model.frames[i] = frame


def pinocchio_reason(exc: Exception) -> str:
    """A Pinocchio error's message on one line, without the C++ file and function it names."""
    text = ' '.join(str(exc).split())
    return text.rsplit('message: ', 1)[-1] if 'message: ' in text else text


def find_frame(model: pin.Model, name: str) -> int:
    """The id of the frame called ``name``; a body (or fixed frame) when several share it.

    Raises:
        FrameNotFound: no frame has that name (the message lists the frames).
    """
    ids = [i for i, f in enumerate(model.frames) if f.name == name]
    if not ids:
        raise FrameNotFound(name, [f.name for f in model.frames])
    rank = {t: k for k, t in enumerate(FRAME_PREFERENCE)}
    return min(ids, key=lambda i: (rank.get(str(model.frames[i].type).split('.')[-1], 99), i))


def chain_joint(model: pin.Model, j: int) -> bool:
    """Whether joint ``j`` is an arm joint of a chain (revolute), False for a root to lock.

    Raises:
        InvalidModel: a joint sik_ros cannot put in a chain (prismatic, continuous left as
            such, composite), naming it.
    """
    kind = model.joints[j].shortname()
    if kind in REVOLUTE_AXES or kind == 'JointModelRevoluteUnaligned':
        return True
    if kind in ROOT_JOINTS:
        return False
    what = {'JointModelPX': 'prismatic', 'JointModelPY': 'prismatic', 'JointModelPZ':
            'prismatic', 'JointModelPrismaticUnaligned': 'prismatic'}.get(kind, kind)
    if kind.startswith('JointModelRUB'):
        what = ('continuous (load it with sik_ros.kinematics.robots.load_robot, which makes '
                'it periodic)')
    raise InvalidModel(f'joint {model.names[j]!r} in the chain is {what}; sik_ros supports '
                       f'chains of revolute joints')


def chain_path(full_model: pin.Model, base_frame: str, tip_frame: str) -> List[int]:
    """The joints (ids, base to tip) that move ``tip_frame`` relative to ``base_frame``.

    Raises:
        InvalidModel: the tip is not below the base, or no revolute joint moves it.
    """
    base_joint = full_model.frames[find_frame(full_model, base_frame)].parentJoint
    tip_joint = full_model.frames[find_frame(full_model, tip_frame)].parentJoint
    path = []
    j = tip_joint
    while j > 0 and j != base_joint:
        path.append(j)
        j = full_model.parents[j]
    if j != base_joint:
        raise InvalidModel(f'tip frame {tip_frame!r} is not below base frame {base_frame!r} '
                           f'in the kinematic tree')
    path = [j for j in reversed(path) if chain_joint(full_model, j)]
    if not path:
        raise InvalidModel(f'no revolute joint moves tip frame {tip_frame!r} relative to '
                           f'{base_frame!r}')
    return path


def rename_link_joints(full_model: pin.Model, lock: List[int]) -> Dict[str, str]:
    """Joints that share a link's name renamed (in place); the arm joints' names to restore.

    A joint that shares a link's name makes Pinocchio's model reduction refuse the name. A
    locked joint becomes a fixed frame of its name, so it is renamed for good; an arm joint is
    renamed for the reduction only and gets its name back after it (the returned map: new
    name -> old). New names are ones no frame or joint has.
    """
    bodies = {f.name for f in full_model.frames if f.type == pin.FrameType.BODY}
    taken = {f.name for f in full_model.frames} | set(full_model.names)
    kept_names = {}
    for j in range(1, full_model.njoints):
        name_j = full_model.names[j]
        if name_j not in bodies or not lock:
            continue
        new_name = unused_name(taken, f'{name_j}{"_locked" if j in lock else "_joint"}')
        for i, frame in enumerate(full_model.frames):
            if frame.name == name_j and frame.type == pin.FrameType.JOINT:
                rename_frame(full_model, i, new_name)
        full_model.names[j] = new_name
        if j not in lock:
            kept_names[new_name] = name_j
    return kept_names
