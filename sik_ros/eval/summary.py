"""The machine-readable results ``results.json``: settings, targets and per-target errors [m].

The schema (its keys are documented by ``docs/results.json``) is built here from the typed
results of one run; joint angles are left out, distances are in metres, times in ms.
"""

from dataclasses import asdict, fields
import json
from typing import Any, Dict, Iterable

import numpy as np

from sik_ros.eval.obstacle import ObstacleCase
from sik_ros.eval.run import Results
from sik_ros.kinematics.collision import Obstacle


def to_jsonable(obj: Any) -> Any:
    """Numpy arrays and scalars as lists and floats (7 significant digits), recursively.

    An :class:`Obstacle` becomes its shape, dimensions [m] and position [m].
    """
    if isinstance(obj, dict):
        return {str(k): to_jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [to_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return to_jsonable(obj.tolist())
    if isinstance(obj, (np.floating, np.integer, np.bool_)):
        obj = obj.item()
    if isinstance(obj, float):
        return float(f'{obj:.7g}')
    if isinstance(obj, Obstacle):
        return {'shape': obj.shape, 'dimensions': list(obj.dimensions),
                'position': list(obj.position)}
    return obj


def pick(obj: Any, keep: Iterable[str] = (), drop: Iterable[str] = ()) -> Dict[str, Any]:
    """A dataclass's fields as a dict, in field order, without the joint angles (``q_*``).

    Args:
        obj: a dataclass instance.
        keep: the fields to keep (all when empty).
        drop: fields to leave out.
    """
    keep, drop = set(keep), set(drop)
    return {f.name: getattr(obj, f.name) for f in fields(obj)
            if (not keep or f.name in keep) and f.name not in drop
            and not f.name.startswith('q_')}


def summary(res: Results) -> Dict[str, Any]:
    """The content of ``results.json`` (before :func:`to_jsonable`)."""
    st, d = res.settings, res.distance
    timing = {k: {n: v for n, v in asdict(t).items() if not (n == 'success' and v is None)}
              for k, t in res.timing.items()}
    obstacle = res.obstacle
    if obstacle is not None:
        obstacle = pick(obstacle) if isinstance(obstacle, ObstacleCase) else \
            {'goal': None, 'reason': obstacle.reason}
    return {
        'machine': asdict(res.machine), 'date': res.date, 'quick': st.quick,
        'targets_per_radius': st.targets, 'samples': st.samples,
        'workspace': {'targets': res.workspace_targets, 'errors_m': d.workspace},
        'radius': {str(r): {'targets': res.spheres[r].positions,
                            'available': res.spheres[r].available,
                            'errors_m': {m: {v: per[i] for v, per in variants.items()}
                                         for m, variants in d.radius.items()}}
                   for i, r in enumerate(st.radii)},
        'timing_ms': timing,
        'diversity': {m: [pick(r, ('position', 'err_raw', 'err_refined', 'var_raw',
                                   'var_refined')) for r in recs]
                      for m, recs in res.diversity.items()},
        'sweep': {'median': res.sweep.median,
                  'elements': [pick(e) for e in res.sweep.elements]},
        'orientation': None if res.orientation is None else pick(res.orientation,
                                                                 drop=('targets',)),
        'pose_lookup': None if res.pose_lookup is None else asdict(res.pose_lookup),
        'obstacle': obstacle,
        'latent': None if res.latent is None else [pick(r, drop=('history',))
                                                   for r in res.latent],
        'figures': res.figures,
    }


def summary_json(res: Results) -> str:
    """``results.json``'s text."""
    return json.dumps(to_jsonable(summary(res)), indent=1) + '\n'
