"""Posture families: what a family is, how every family of a goal is found, how answers spread.

A posture family is a connected set of a goal's exact solutions within the joint limits (a
*branch* of a pose of an arm of six joints or fewer; a connected piece of the self-motion of a
redundant arm). The parts, from the concept to the routes that use it:

- :mod:`~sik_ros.solver.families.membership`: which exact solutions are one family (their
  labels, the distance under which two are one solution), the rounds that spread an answer
  over its families, and the numbering of an answer's families;
- :mod:`~sik_ros.solver.families.branches`: a 6-joint arm's branches (each with a branch code)
  and starts for the branches a refinement missed, its exact rows polished onto their
  solutions;
- :mod:`~sik_ros.solver.families.isolated`: every branch of an isolated pose goal in a few
  compiled calls (the lean route of an arm of six joints or fewer);
- :mod:`~sik_ros.solver.families.search`: the family search of a redundant arm: each curve of
  its self-motion traced past the limits into an atlas of pieces, starts spread on them.

Below them: the compiled kernels (:mod:`sik_ros.kernels.families`: which exact solutions are
connected, the rounds; :mod:`sik_ros.kernels.selfmotion`: the step along a self-motion and its
corrector; :mod:`sik_ros.kernels.atlas` and :mod:`sik_ros.kernels.atlas_points`: the traced
atlas and points spread on its pieces) and the arm's branch signs and exact flips
(:mod:`sik_ros.kinematics.branches`). The package builds on the solver's base (settings,
context, candidates, results, refinement, the networks, restarts and scores) and is used by
the ranking and the pipeline above it; ``test/test_house.py`` holds it to that floor.
"""

from sik_ros._lazy import lazy_exports

#: Where each public name lives (loaded on first use): what a family is. The routes are named
#: by their modules (``families.search.search``, ``families.isolated.every_branch``).
_EXPORTS = {
    name: 'sik_ros.solver.families.membership'
    for name in ('labels', 'number', 'one_per_family', 'roots', 'rounds', 'same_solution',
                 'traced')
}

__all__ = sorted(_EXPORTS)

__getattr__, __dir__ = lazy_exports(__name__, globals(), _EXPORTS)
