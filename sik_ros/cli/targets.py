"""``sik-solve --targets FILE``: many targets from a CSV or NPZ file, solved on every core."""

import json
from pathlib import Path
from typing import List, Optional, Tuple, TYPE_CHECKING

import numpy as np

from sik_ros.artifacts import atomic_write
from sik_ros.errors import InvalidArgument
from sik_ros.solver.results import IKResult, result_to_dict

if TYPE_CHECKING:  # loaded in main(): it brings torch and Pinocchio
    from sik_ros.solver.selective_ik import SelectiveIK

#: The answers file's format (its manifest's ``format``).
ANSWERS_FORMAT = 'sik-solve-targets-v1'


def read_targets(path: str) -> Tuple[np.ndarray, Optional[np.ndarray]]:
    """Positions (N, 3) and quaternions (N, 4) or None, from rows ``x y z [qx qy qz qw]``.

    A ``.npz`` file holds one (N, 3) or (N, 7) array (or ``positions`` and ``orientations``);
    any other file is text: one row per line, numbers split by commas or spaces, ``#`` lines
    skipped.

    Raises:
        InvalidArgument: unreadable, empty, or rows that are not 3 or 7 numbers alike.
    """
    file = Path(path)
    try:
        if file.suffix == '.npz':
            with np.load(file, allow_pickle=False) as data:
                if 'positions' in data:
                    pos = np.asarray(data['positions'], dtype=float)
                    quat = data['orientations'] if 'orientations' in data else None
                    arr = pos if quat is None else np.hstack([pos, np.asarray(quat, float)])
                elif len(data.files) == 1:
                    arr = np.asarray(data[data.files[0]], dtype=float)
                else:
                    raise ValueError(f'expected one array or positions/orientations, found '
                                     f'{sorted(data.files)}')
        else:
            rows = [[float(v) for v in line.replace(',', ' ').split()]
                    for line in file.read_text().splitlines()
                    if line.strip() and not line.lstrip().startswith('#')]
            arr = np.array(rows, dtype=float)
    except (OSError, ValueError, TypeError, KeyError) as exc:
        raise InvalidArgument(f'cannot read targets from {file}: {exc}') from exc
    except Exception as exc:  # a damaged archive raises zipfile's and pickle's errors
        raise InvalidArgument(f'cannot read targets from {file}: {type(exc).__name__}') \
            from exc
    if arr.ndim != 2 or arr.shape[1] not in (3, 7) or len(arr) == 0:
        raise InvalidArgument(f'{file}: each target needs 3 (x y z) or 7 (x y z qx qy qz qw) '
                              f'numbers, one row each; got shape {arr.shape}')
    return arr[:, :3], (arr[:, 3:] if arr.shape[1] == 7 else None)


def answers_arrays(results: List[IKResult], dof: int) -> dict:
    """The answers as arrays padded with NaN to the most solutions of any target."""
    k = max([len(r.solutions) for r in results] + [1])
    n = len(results)
    q = np.full((n, k, dof), np.nan)
    perr, oerr = np.full((n, k), np.nan), np.full((n, k), np.nan)
    family = np.full((n, k), 65535, dtype=np.uint16)
    for i, r in enumerate(results):
        for j, s in enumerate(r.solutions):
            q[i, j], perr[i, j], oerr[i, j], family[i, j] = (s.q, s.position_error,
                                                             s.orientation_error, s.family)
    return dict(q=q, position_error=perr, orientation_error=oerr, family=family,
                count=np.array([len(r.solutions) for r in results], dtype=np.int32),
                success=np.array([r.success for r in results], dtype=bool),
                num_families=np.array([r.num_families for r in results], dtype=np.int32))


def write_answers(out: str, ik: 'SelectiveIK', results: List[IKResult]) -> Path:
    """The answers as an NPZ with a manifest (robot, joints, bundle), written atomically."""
    path = Path(out)
    manifest = dict(format=ANSWERS_FORMAT, robot=ik.robot.name,
                    joint_names=ik.joint_names, bundle=str(ik.bundle), targets=len(results))
    try:
        with atomic_write(path) as tmp:
            np.savez(tmp, manifest=np.array(json.dumps(manifest)),
                     **answers_arrays(results, ik.robot.dof))
    except OSError as exc:
        raise InvalidArgument(f'cannot write {path}: {exc}') from exc
    return path


def solve_targets(ik: 'SelectiveIK', args) -> int:
    """``--targets``: every row's ranked solutions (one line each, or JSON), optionally an NPZ."""
    positions, quats = read_targets(args.targets)
    results = ik.solve_batch(positions, quats, num_solutions=args.num_solutions,
                             seed=args.seed, timeout=args.timeout, workers=args.workers,
                             progress=True)
    if args.json:
        print(json.dumps([result_to_dict(r, ik.joint_names) for r in results]))
    else:
        for i, r in enumerate(results):
            best = r.solutions[0].position_error * 1e3 if r.solutions else float('nan')
            print(f"{i:>5} {'success' if r.success else 'FAILED':>7} "
                  f'{len(r.solutions):>3} solutions, {r.num_families} families, best error '
                  f'{best:.4f} mm')
        print(f'{sum(r.success for r in results)} of {len(results)} targets solved')
    if args.out:
        write_answers(args.out, ik, results)
    return 0 if all(r.success for r in results) else 1
