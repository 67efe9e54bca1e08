"""Error types of sik_ros: every failure the library reports is a :class:`SikError`."""

from typing import Sequence


class SikError(Exception):
    """Base class of every error raised on purpose by sik_ros."""


class RobotNotFound(SikError):
    """A robot name that example-robot-data does not know."""

    def __init__(self, name: str, available: Sequence[str]):
        self.name = name
        self.available = sorted(available)
        super().__init__(
            f"unknown robot {name!r}; available: {', '.join(self.available)}")


class FrameNotFound(SikError):
    """A frame name that the robot model does not have."""

    def __init__(self, frame: str, available: Sequence[str]):
        self.frame = frame
        self.available = list(available)
        super().__init__(
            f"frame {frame!r} not in the model; frames: {', '.join(self.available)}")


class InvalidModel(SikError):
    """A robot model that sik_ros cannot use (unsupported joints, bad chain, ...)."""


class InvalidArgument(SikError, ValueError):
    """A parameter with a wrong value, shape or type."""


class InvalidGoal(InvalidArgument):
    """A target position or orientation that is not a valid goal."""


class InvalidFrame(InvalidGoal):
    """A goal given in a frame other than the base frame (sik_ros does not transform frames)."""


class InvalidSeed(InvalidArgument):
    """A seed configuration of the wrong length, non-finite, or outside the joint limits."""


class JointLimitViolation(InvalidSeed):
    """A joint value outside its limits."""

    def __init__(self, joint: str, value: float, lower: float, upper: float):
        self.joint, self.value, self.lower, self.upper = joint, value, lower, upper
        super().__init__(
            f"joint {joint!r} = {value:.6g} rad is outside its limits "
            f"[{lower:.6g}, {upper:.6g}] rad")


class ArtifactError(SikError):
    """An artifact (dataset, checkpoint, index table, bundle) that cannot be used."""


class ArtifactExists(ArtifactError):
    """An output path that already exists and would be overwritten."""


class ArtifactMismatch(ArtifactError):
    """An artifact whose manifest does not match what it is used with."""

    def __init__(self, what: str, expected: object, found: object):
        self.what, self.expected, self.found = what, expected, found
        super().__init__(f"{what} mismatch: expected {expected!r}, found {found!r}")


class CorruptArtifact(ArtifactError):
    """An artifact that is truncated, unreadable or inconsistent with its manifest."""


class TrainingDiverged(SikError):
    """A training run whose loss stopped being finite."""


class SolverUnavailable(SikError):
    """No solver could take a request (every solver process busy or being restarted)."""


class SolverTimeout(SolverUnavailable):
    """No solver answered within the request's deadline."""


class SolverCrashed(SikError):
    """A solver process died while it served a request (it is being replaced)."""


class ModelNotReady(SikError):
    """A request that needs the learned model (raw answers) before the arm has one."""
