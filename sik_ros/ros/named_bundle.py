"""A bundle the node is told to serve (``robot`` or ``model_dir``), held to robot_description.

:func:`load_named` loads it and checks the frames and the ``robot_description`` parameter
against it (a mismatch stops the start); :class:`DescriptionCheck` holds the
``robot_description`` topic to it while it is served: a description whose chain differs makes
every request ``ROBOT_MISMATCH`` with what differs (the node never follows it: the bundle was
asked for by name).
"""

from typing import Callable, Optional, Tuple

from sik_ros.errors import SikError
from sik_ros.kinematics.robots import chain_differences
from sik_ros.solver import SelectiveIK


class StartupError(SikError):
    """The node cannot start: bad parameters or an unusable bundle."""


def differences(robot, urdf: str) -> str:
    """How a URDF's chain differs from the bundle's robot ('' if it does not)."""
    try:
        return '; '.join(chain_differences(robot, urdf))
    except SikError as exc:
        return str(exc)


def load_named(p, settings: dict) -> SelectiveIK:
    """The bundle the parameters ``p`` name, checked against their frames and description.

    Raises:
        StartupError: it cannot be loaded, or it does not fit the frames or the description.
    """
    bundle = p.model_dir or p.robot
    try:
        ik = SelectiveIK.load(bundle)
    except SikError as exc:
        raise StartupError(f'cannot load the IK bundle {bundle!r}: {exc}') from exc
    robot = ik.robot
    for name, value, actual in (('base_frame', p.base_frame, robot.base_frame),
                                ('tip_frame', p.tip_frame, robot.tip_frame)):
        if value and value != actual:
            raise StartupError(f'parameter {name} is {value!r} but bundle {bundle!r} was '
                               f'made for {actual!r}')
    if p.robot_description:
        reason = differences(robot, p.robot_description)
        if reason:
            raise StartupError(f'bundle {bundle!r} does not fit the robot_description: '
                               f'{reason}')
    return ik.with_config(**settings)


class DescriptionCheck:
    """The robot_description topic held to the served bundle (see the module)."""

    def __init__(self, refused_code: int, info: Callable[[str], None],
                 error: Callable[[str], None]):
        self.code, self.info, self.error = refused_code, info, error
        #: the last description the topic gave, or None
        self.description: Optional[str] = None
        #: why requests are refused (the description's chain differs), or None
        self.mismatch: Optional[str] = None

    def take(self, urdf: str, ik: Optional[SelectiveIK]) -> None:
        """A description from the topic: checked now if a bundle is served, else kept."""
        self.description = urdf
        if ik is not None:
            self.check(ik)

    def check(self, ik: SelectiveIK) -> None:
        """Hold the last description to ``ik``'s chain (nothing to do without one)."""
        if self.description is None:
            return
        reason = differences(ik.robot, self.description)
        self.mismatch = (f'the bundle {ik.bundle} does not fit the robot_description '
                         f'topic: {reason}') if reason else None
        if reason:
            self.error(f'{self.mismatch}; refusing requests')
        else:
            self.info('robot_description matches the bundle\'s chain')

    def refusal(self) -> Optional[Tuple[int, str]]:
        """``(ROBOT_MISMATCH, why)`` while the description differs, else None."""
        return None if self.mismatch is None else (self.code, self.mismatch)
