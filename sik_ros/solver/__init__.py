"""SelectiveIK: several distinct, exact, ranked joint solutions per target.

:class:`SelectiveIK` is a facade over a pipeline of short stages, one module each
(:mod:`~sik_ros.solver.pipeline` runs them in order; :mod:`~sik_ros.solver.call` decides a
call's route once, from the goal checked by :mod:`~sik_ros.solver.inputs`):

- :mod:`~sik_ros.solver.single`: one solution with the default ranking, from a few starts;
- :mod:`~sik_ros.solver.families.isolated`: every branch of a pose of an arm of six joints or fewer
  (the lean path; its starts for the missed branches in :mod:`~sik_ros.solver.families.branches`);
- :mod:`~sik_ros.solver.candidates`: posture indices from the table near the goal, the seed's
  own index, oriented postures for pose goals, and the postures they stand for;
- :mod:`~sik_ros.solver.codec`: the networks at a goal (decode, encode);
- :mod:`~sik_ros.solver.refine`: batched damped least squares on the chain's Jacobians;
- :mod:`~sik_ros.solver.explore`: restarts and the self-motion walk;
- :mod:`~sik_ros.solver.families`: posture families, in one package: which exact solutions
  are one family and the rounds over them, the family search over a redundant arm's
  self-motion, a 6-joint arm's every branch;
- :mod:`~sik_ros.solver.scores`: the one score and distinct postures;
- :mod:`~sik_ros.solver.ranking`: tiers and the ranking;
- :mod:`~sik_ros.solver.adjust`: the paper's Algorithm 2 (index adjustment around obstacles);
- :mod:`~sik_ros.solver.path`: Cartesian paths (a ladder of rungs of candidates).

Settings are :class:`SolverConfig` (:mod:`~sik_ros.solver.config`), answers
:class:`IKResult` and :class:`Solution` (:mod:`~sik_ros.solver.results`). See the paper's
"Posture index selection" and Algorithm 2, and docs/interfaces.md for the public contract.
"""

from sik_ros._lazy import lazy_exports

#: Where each public name lives (loaded on first use, PEP 562: ``sik_ros.solver.config`` or
#: ``.results`` do not load torch).
_EXPORTS = {
    'GoalModel': 'sik_ros.bundles.bundle', 'IKResult': 'sik_ros.solver.results',
    'JointPath': 'sik_ros.solver.path', 'PathResult': 'sik_ros.solver.path',
    'SelectiveIK': 'sik_ros.solver.selective_ik', 'Solution': 'sik_ros.solver.results',
    'SolverConfig': 'sik_ros.solver.config', 'dumps': 'sik_ros.solver.results',
    'result_to_dict': 'sik_ros.solver.results',
}

__all__ = sorted(_EXPORTS)

__getattr__, __dir__ = lazy_exports(__name__, globals(), _EXPORTS)
