"""A pose model's index where its use needs it: looked up from a neighbouring pose, decoded.

For targets uniform in joint space (their tip poses by Pinocchio) a pose model's postures are
decoded at the target's pose from three kinds of index, and their errors measured by Pinocchio:

- **own**: the target configuration's own index (encoded at its pose): the decoder's floor;
- **neighbours**: the indices of the collected configurations (the dataset's rows) whose tips
  are within ``--radius`` of the target and whose orientations are ``--angles`` away from
  its (20-30 degrees: the look-up's nearest rows are 25-35 degrees away), each encoded at its
  own pose, up to ``--neighbours`` of them (nearest tip first): the goal, not the index, must
  decide the orientation;
- **turned**: the target configuration moved in joint space until its tip turns by the same
  angles (the same posture family), encoded there, decoded at the target;

and, with ``--table`` (built by ``sik-index`` for the model) the paper's protocol as sik-eval
measures it (:func:`sik_ros.eval.lookup.pose_lookup` over a copy of the bundled Panda bundle
whose pose model and table are the given ones; sik-eval's 100 targets).

    python bench/pose_index.py MODEL.pt [MODEL.pt ...] [--table TABLE.npz ...] [--json out.json]
"""

import argparse
import os
from pathlib import Path
import shutil
import sys
import tempfile

os.environ.setdefault('OMP_NUM_THREADS', '1')

import numpy as np  # noqa: E402
from scipy.spatial import cKDTree  # noqa: E402
from scipy.spatial.transform import Rotation  # noqa: E402
import torch  # noqa: E402

from sik_ros.eval.metrics import orientation_cosine, pin_tips  # noqa: E402
from sik_ros.learning.checkpoints import load_checkpoint, model_from_checkpoint  # noqa: E402
from sik_ros.learning.models import make_goal  # noqa: E402

from report import add_json_argument, write_json  # noqa: E402,I100 (bench/report.py)


def errors(robot, q: np.ndarray, pos: np.ndarray, rot: np.ndarray):
    """Distance [m] and angle [deg] errors of configurations (N, n) against poses (N, ...)."""
    tip, r = pin_tips(robot, q)
    dist = np.linalg.norm(tip - pos, axis=1)
    ang = np.array([orientation_cosine(rt, ri[None])[1][0] for rt, ri in zip(rot, r)])
    return dist, np.degrees(ang)


class PoseModel:
    """A pose model's encoder and decoder on joints [rad] and poses (positions, rotations)."""

    def __init__(self, path: Path):
        self.model, self.cfg, self.norm = model_from_checkpoint(load_checkpoint(path))
        if self.cfg.goal != 'pose':
            raise SystemExit(f'{path}: not a pose model')

    def _goal(self, pos, rot):
        goal = torch.as_tensor(make_goal('pose', pos, rot), dtype=torch.float32)
        return self.norm.goal_to_net(goal)

    @torch.no_grad()
    def encode(self, q, pos, rot) -> torch.Tensor:
        """The posture indices of configurations at their poses."""
        x = self.norm.q_to_net(torch.as_tensor(q, dtype=torch.float32))
        return self.model.encode(self._goal(pos, rot), x)[0]

    @torch.no_grad()
    def decode(self, z, pos, rot) -> np.ndarray:
        """Joints [rad] of indices decoded at poses."""
        x = self.model.decode(self._goal(pos, rot), z)
        return self.norm.q_from_net(x).double().numpy()


def quat_angle_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angles [deg] between unit quaternions (N, 4) and (N, 4) or (4,)."""
    return np.degrees(2 * np.arccos(np.clip(np.abs((a * b).sum(-1)), 0, 1)))


def neighbour_rows(tree, ds_quat, pos, quat, radius, angles, count):
    """The dataset rows near a target pose: tips within ``radius``, orientations in ``angles``."""
    rows = np.asarray(tree.query_ball_point(pos, radius), dtype=np.int64)
    if not len(rows):
        return rows
    ang = quat_angle_deg(ds_quat[rows], quat)
    rows = rows[(ang >= angles[0]) & (ang <= angles[1])]
    d = np.linalg.norm(tree.data[rows] - pos, axis=1)
    return rows[np.argsort(d)[:count]]


def turned(robot, q, rot, angles, rng, tries=60):
    """``q`` moved in joint space until its tip's orientation is ``angles`` [deg] from ``rot``."""
    goal = np.radians(np.mean(angles))
    for _ in range(tries):
        d = rng.normal(size=q.shape)
        d /= np.linalg.norm(d)
        lo, hi = 0.0, 1.5
        for _ in range(20):  # bisection on the step length
            mid = (lo + hi) / 2
            qm = np.clip(q + mid * d, robot.lower, robot.upper)
            _, r = robot.fk_rot(qm[None])
            if orientation_cosine(rot, r)[1][0] < goal:
                lo = mid
            else:
                hi = mid
        qm = np.clip(q + hi * d, robot.lower, robot.upper)
        _, r = robot.fk_rot(qm[None])
        a = np.degrees(orientation_cosine(rot, r)[1][0])
        if angles[0] <= a <= angles[1]:
            return qm
    return None


def neighbour_study(model: PoseModel, robot, ds, tree, args) -> dict:
    """Own, neighbours' and turned indices decoded at the targets: mean errors."""
    rng = np.random.default_rng(args.seed)
    q_t = rng.uniform(robot.lower, robot.upper, (args.targets, robot.dof))
    pos_t, rot_t = robot.fk_rot(q_t)
    quat_t = Rotation.from_matrix(rot_t).as_quat()
    z = model.encode(q_t, pos_t, rot_t)
    own = errors(robot, model.decode(z, pos_t, rot_t), pos_t, rot_t)
    nd, na, seen, found = [], [], [], 0
    td, ta = [], []
    for i in range(args.targets):
        rows = neighbour_rows(tree, ds['quat'], pos_t[i], quat_t[i], args.radius,
                              args.angles, args.neighbours)
        if len(rows):
            found += 1
            qn = np.asarray(ds['q'][rows], dtype=float)
            pn, rn = robot.fk_rot(qn)
            zn = model.encode(qn, pn, rn)
            k = len(rows)
            d, a = errors(robot, model.decode(zn, np.repeat(pos_t[i:i + 1], k, 0),
                                              np.repeat(rot_t[i:i + 1], k, 0)),
                          np.repeat(pos_t[i:i + 1], k, 0), np.repeat(rot_t[i:i + 1], k, 0))
            nd.append(d.mean())
            na.append(a.mean())
            seen.append(quat_angle_deg(ds['quat'][rows], quat_t[i]).mean())
        qm = turned(robot, q_t[i], rot_t[i], args.angles, rng)
        if qm is not None:
            pm, rm = robot.fk_rot(qm[None])
            d, a = errors(robot, model.decode(model.encode(qm[None], pm, rm), pos_t[i:i + 1],
                                              rot_t[i:i + 1]), pos_t[i:i + 1], rot_t[i:i + 1])
            td.append(d[0])
            ta.append(a[0])
    return {'own_cm': 100 * own[0].mean(), 'own_deg': own[1].mean(),
            'own_median_deg': float(np.median(own[1])),
            'neighbours_cm': 100 * np.mean(nd), 'neighbours_deg': np.mean(na),
            'neighbours_median_deg': float(np.median(na)),
            'neighbours_away_deg': np.mean(seen), 'targets_with_neighbours': found,
            'turned_cm': 100 * np.mean(td), 'turned_deg': np.mean(ta),
            'turned_targets': len(td)}


def protocol(model_path: Path, table: Path) -> dict:
    """sik-eval's pose-model figure (the paper's protocol) with this model and table."""
    from sik_ros.bundles.bundle import read_bundle_manifest, resolve_bundle
    from sik_ros.eval.lookup import pose_lookup
    from sik_ros.eval.raw_pose import SEED, TARGETS
    from sik_ros.solver import SelectiveIK
    import json
    with tempfile.TemporaryDirectory() as work:
        bundle = Path(work) / 'bundle'
        shutil.copytree(resolve_bundle('panda'), bundle, ignore=shutil.ignore_patterns(
            'baselines', 'sik_pose*'))
        shutil.copy(model_path, bundle / 'sik_pose.pt')
        shutil.copy(table, bundle / 'sik_pose_table.npz')
        manifest = read_bundle_manifest(bundle)
        manifest['models']['pose'] = {'model': 'sik_pose.pt', 'table': 'sik_pose_table.npz'}
        (bundle / 'bundle.json').write_text(json.dumps(manifest, indent=2))
        ik = SelectiveIK.load(str(bundle))
        q = np.random.default_rng(SEED).uniform(ik.robot.lower, ik.robot.upper,
                                                (TARGETS, ik.robot.dof))
        look = pose_lookup(ik, *ik.robot.fk_rot(q))
    return {'protocol_cm': 100 * look.distance.mean(),
            'protocol_deg': float(np.degrees(look.angle.mean()))}


def main() -> int:
    """Print the study of each model (and the protocol of each with a table)."""
    p = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    p.add_argument('models', nargs='+', type=Path, help='pose models or checkpoints')
    p.add_argument('--table', nargs='*', type=Path, default=[],
                   help='a sik-index table per model, in order (the paper\'s protocol)')
    p.add_argument('--dataset', default='data/panda30')
    p.add_argument('--targets', type=int, default=100)
    p.add_argument('--seed', type=int, default=7)
    p.add_argument('--radius', type=float, default=0.03, help='neighbours\' tip radius [m]')
    p.add_argument('--angles', type=float, nargs=2, default=(20.0, 30.0),
                   help='neighbours\' orientation from the target\'s [deg]')
    p.add_argument('--neighbours', type=int, default=10)
    add_json_argument(p)
    args = p.parse_args()
    from sik_ros.kinematics.robots import robot_from_manifest
    from sik_ros.tables.dataset import Dataset
    ds_dir = Path(args.dataset)
    ds = Dataset.load(ds_dir)
    robot = robot_from_manifest(ds.manifest['robot'], f'dataset {ds_dir}')
    rows = {'q': np.load(ds_dir / 'q.npy', mmap_mode='r'),
            'quat': np.load(ds_dir / 'quaternion.npy', mmap_mode='r')}
    tree = cKDTree(np.load(ds_dir / 'position.npy'))
    out = {}
    for i, path in enumerate(args.models):
        res = neighbour_study(PoseModel(path), robot, rows, tree, args)
        if i < len(args.table):
            res.update(protocol(path, args.table[i]))
        out[str(path)] = res
        print(f'{path}: ' + ', '.join(f'{k} {v:.2f}' if isinstance(v, float) else f'{k} {v}'
                                      for k, v in res.items()), flush=True)
    write_json(args.json, 'pose_index', out)
    return 0


if __name__ == '__main__':
    sys.exit(main())
