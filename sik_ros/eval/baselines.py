"""The methods SIK is compared with: PSIK, FCN, ANFIS (trained here) and TRAC-IK.

A ``--baselines`` folder holds ``psik/`` (a bundle with its own table) or ``psik.pt`` (a PSIK
model alone: its candidate indices are then draws from its prior, see
:class:`sik_ros.tables.prior_table.PriorTable`), and the single-solution models ``fcn.pt``,
``fcn_uni.pt`` and ``anfis.pt`` (:class:`Baseline`).
"""

from pathlib import Path
from typing import Dict, List, Optional, Tuple, Union

import numpy as np
import torch

from sik_ros.artifacts import check_robot_manifest
from sik_ros.errors import ArtifactMismatch, CorruptArtifact
from sik_ros.eval.shipped import BASELINE_FILES, check_shipped
from sik_ros.kinematics.robot import Robot
from sik_ros.learning.checkpoints import load_checkpoint, model_from_checkpoint
from sik_ros.learning.models import make_goal, ModelConfig, Normalizer
from sik_ros.learning.provenance import trained_summary
from sik_ros.solver import GoalModel, SelectiveIK
from sik_ros.tables.prior_table import PriorTable

#: Model kind each baseline file must hold.
BASELINE_KINDS = {'psik': 'psik', 'fcn': 'fcn', 'fcn_uni': 'fcn', 'anfis': 'anfis'}
#: Prior draws standing in for the table of a PSIK model given without one.
PRIOR_DRAWS = 48


class Baseline:
    """A single-solution model (FCN or ANFIS): position [m] -> joint angles [rad].

    Attributes:
        name: the baseline's key (``fcn``, ``fcn_uni``, ``anfis``).
        path: its checkpoint.
        robot: the arm it was trained for.
        model: the network; ``cfg`` its :class:`ModelConfig`, ``norm`` its normaliser.
        train_config: the training settings stored in the checkpoint.
        history: the training records stored in the checkpoint.
        step: training steps taken.
        trained: where, how long and on how many samples it was trained
            (:func:`~sik_ros.learning.provenance.trained_summary`).
    """

    def __init__(self, name: str, path: Path, robot: Robot):
        """Load a checkpoint made for ``robot`` with a position goal.

        Raises:
            CorruptArtifact: a missing or damaged file.
            ArtifactMismatch: a checkpoint of another robot or goal kind.
        """
        ckpt = load_checkpoint(path)
        check_robot_manifest(f'baseline {path}', robot.manifest(), ckpt['robot'])
        model, cfg, norm = model_from_checkpoint(ckpt)
        if cfg.goal != 'position':
            raise ArtifactMismatch(f'baseline {path}: goal', 'position', cfg.goal)
        self.model: torch.nn.Module = model
        self.cfg: ModelConfig = cfg
        self.norm: Normalizer = norm
        self.name, self.path, self.robot = name, Path(path), robot
        self.train_config: Dict = ckpt.get('train_config', {})
        self.history: List[Dict] = ckpt.get('history', [])
        self.step = int(ckpt.get('step', 0))
        self.trained: Dict = trained_summary(ckpt)

    @torch.no_grad()
    def predict(self, positions: np.ndarray) -> np.ndarray:
        """Joint angles (N, n) [rad], clipped to the limits, for positions (N, 3) [m]."""
        goal = make_goal('position', np.atleast_2d(positions), None).astype(np.float32)
        x = self.model(self.norm.goal_to_net(torch.from_numpy(goal)))
        q = self.norm.q_from_net(x).double().numpy()
        return np.clip(q, self.robot.lower, self.robot.upper)


#: A compared method: a multi-solution solver (SIK, PSIK) or a single-solution model.
Method = Union[SelectiveIK, Baseline]


def psik_solver(path: Path, robot: Robot, count: int = PRIOR_DRAWS) -> SelectiveIK:
    """A :class:`SelectiveIK` over a PSIK checkpoint, its indices ``count`` prior draws.

    Raises:
        CorruptArtifact: a missing or damaged file.
        ArtifactMismatch: a checkpoint of another robot, or not a PSIK position model.
    """
    ckpt = load_checkpoint(path)
    check_robot_manifest(f'baseline {path}', robot.manifest(), ckpt['robot'])
    model, cfg, norm = model_from_checkpoint(ckpt)
    if cfg.kind != 'psik' or cfg.goal != 'position':
        raise ArtifactMismatch(f'baseline {path}: kind/goal', 'psik/position',
                               f'{cfg.kind}/{cfg.goal}')
    table = PriorTable(cfg.latent_dim, count)
    return SelectiveIK(robot, {'position': GoalModel(model, cfg, norm, table)},
                       bundle=Path(path))


def load_baselines(directory: Optional[Path],
                   robot: Robot) -> Tuple[Dict[str, Method], Dict[str, str]]:
    """The baselines found in a directory, and why each missing one is missing.

    ``psik/`` (a bundle with its own table) is preferred over ``psik.pt`` (see
    :func:`psik_solver`); ``fcn.pt``, ``fcn_uni.pt`` and ``anfis.pt`` are :class:`Baseline`
    models. A folder with ``baselines.json`` (shipped, :mod:`~sik_ros.eval.shipped`) has its
    files checked against it first.

    Raises:
        CorruptArtifact: the folder's ``baselines.json`` is unreadable.

    Returns:
        ``({name: SelectiveIK or Baseline}, {name: reason it is absent})``.
    """
    found: Dict[str, Method] = {}
    missing: Dict[str, str] = {}
    # a shipped folder's manifest: files that do not match it are refused, not evaluated
    damaged = {} if directory is None else check_shipped(Path(directory))
    for name, fname in BASELINE_FILES.items():
        if name in damaged:
            missing[name] = f'refused: {damaged[name]}'
            continue
        path = None if directory is None else Path(directory) / fname
        if name == 'psik' and directory is not None and (Path(directory) / 'psik').is_dir():
            found[name] = SelectiveIK.load(Path(directory) / 'psik')
            continue
        if path is None or not path.is_file():
            missing[name] = 'not provided' if directory is None else f'not provided ({path})'
            continue
        try:
            if name == 'psik':
                found[name] = psik_solver(path, robot)
            else:
                base = Baseline(name, path, robot)
                if base.cfg.kind != BASELINE_KINDS[name]:
                    raise ArtifactMismatch(f'baseline {path}: kind', BASELINE_KINDS[name],
                                           base.cfg.kind)
                found[name] = base
        except (CorruptArtifact, ArtifactMismatch) as exc:
            missing[name] = f'refused: {exc}'
    return found, missing


def multi_solution(ik: SelectiveIK, baselines: Dict[str, Method]) -> Dict[str, SelectiveIK]:
    """SIK (as ``sik``) and the baselines that are multi-solution solvers (PSIK)."""
    return {'sik': ik, **{k: v for k, v in baselines.items() if isinstance(v, SelectiveIK)}}


def single_solution(baselines: Dict[str, Method]) -> Dict[str, Baseline]:
    """The baselines that predict one solution (FCN, ANFIS)."""
    return {k: v for k, v in baselines.items() if isinstance(v, Baseline)}


def has_prior_table(ik: SelectiveIK) -> bool:
    """Whether a solver's position indices are prior draws (a PSIK model given alone)."""
    return isinstance(ik.models['position'].table, PriorTable)


class TracIK:
    """TRAC-IK through pytracik: full pose goals, 5 ms timeout, eps 1e-5, Speed mode.

    Raises:
        ImportError: pytracik is not installed.
    """

    def __init__(self, robot: Robot, timeout: float = 0.005):
        """A solver for ``robot``'s chain with a ``timeout`` [s] per solve."""
        import pytracik
        self._ik = pytracik.ik
        self.robot = robot
        self.solver = pytracik.TRAC_IK(robot.base_frame, robot.tip_frame,
                                       robot.urdf_path.read_text(), timeout, 1e-5,
                                       pytracik.SolveType.Speed)
        pytracik.set_joint_limits(self.solver, list(robot.lower), list(robot.upper))

    def solve(self, position: np.ndarray, quat: np.ndarray,
              q0: np.ndarray) -> Tuple[bool, np.ndarray]:
        """One solve from ``q0`` [rad] towards a pose: position [m], quaternion x y z w.

        Returns:
            whether it succeeded within the limits, and the joint angles (n,) [rad].
        """
        out = self._ik(self.solver, np.asarray(q0, dtype=float), *position, *quat)
        q = np.asarray(out[1:], dtype=float)
        ok = out[0] >= 0 and np.all(q >= self.robot.lower - 1e-9) and \
            np.all(q <= self.robot.upper + 1e-9)
        return bool(ok), q
