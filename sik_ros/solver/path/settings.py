"""What a path request asks for and gets: settings, beams, joint paths and results."""

from dataclasses import dataclass, field
from typing import List

import numpy as np

from sik_ros.solver.config import (ORIENTATION_PATH_TOLERANCE, PATH_DEFAULTS, POSE_BEAM,
                                   POSITION_BEAM, SEED_WEIGHT)


@dataclass
class JointPath:
    """One joint path through every waypoint (or through the feasible prefix).

    Attributes:
        q: joint positions (N, n) [rad], within the limits.
        position_errors: (N,) [m]; orientation_errors: (N,) [rad].
        max_step: largest joint change between consecutive waypoints [rad].
        travel: total joint travel, the sum of the steps' L2 norms [rad].
        min_obstacle_distance: smallest clearance along the path [m] (+inf without obstacles).
        cost: the ranking cost (travel plus the start's distance from the seed).
    """

    q: np.ndarray
    position_errors: np.ndarray
    orientation_errors: np.ndarray
    max_step: float
    travel: float
    min_obstacle_distance: float
    cost: float


@dataclass
class PathResult:
    """The answer to a path request: ranked joint paths, best first."""

    success: bool
    fraction: float
    paths: List[JointPath] = field(default_factory=list)
    elapsed: float = 0.0
    timed_out: bool = False
    message: str = ''


@dataclass(frozen=True)
class PathSettings:
    """How a path is planned (see :meth:`SelectiveIK.solve_path`).

    ``starts``: distinct solutions asked for at the first waypoint (and where every track is
    lost); ``tracks``: the beam, the cheapest candidates kept per waypoint (both raised to
    ``num_paths`` when below it); ``ladder``: every ``ladder``-th waypoint is joined to the
    previous one by the whole ladder (tracks may switch, merge, be refilled by new starts); the
    waypoints between are solved in one batch, each track continuing itself (:func:`chunk`).
    ``near_seed``: a position path with a seed starts from the seed and the table's postures
    nearest it (else from the seed and the solver's first solutions, spread over the
    postures: :func:`track_starts`). The defaults are :data:`POSE_BEAM`'s; :meth:`for_paths`
    takes them from :data:`POSE_BEAM` or :data:`POSITION_BEAM` by the paths' kind.
    """

    num_paths: int = PATH_DEFAULTS.num_paths
    max_joint_step: float = PATH_DEFAULTS.max_joint_step
    path_tolerance: float = PATH_DEFAULTS.path_tolerance
    orientation_path_tolerance: float = ORIENTATION_PATH_TOLERANCE
    starts: int = POSE_BEAM['starts']
    tracks: int = POSE_BEAM['tracks']
    ladder: int = POSE_BEAM['ladder']
    seed_weight: float = SEED_WEIGHT
    near_seed: bool = True

    def __post_init__(self):
        """Starts and tracks enough for ``num_paths`` paths from distinct starts."""
        object.__setattr__(self, 'starts', max(self.starts, self.num_paths))
        object.__setattr__(self, 'tracks', max(self.tracks, self.num_paths))

    @classmethod
    def for_paths(cls, pose: bool, **kw) -> 'PathSettings':
        """The settings of pose paths (``pose``) or position paths, the beam by their kind."""
        return cls(**{**(POSE_BEAM if pose else POSITION_BEAM), **kw})
