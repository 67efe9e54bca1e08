"""The evaluation behind ``sik-eval``: the paper's experiments, its baselines and the report.

Modules: :mod:`~sik_ros.eval.paper` (the paper's figures and targets), :mod:`~.baselines`
(PSIK, FCN, ANFIS, TRAC-IK), :mod:`~.metrics` (errors by forward kinematics),
:mod:`~.studies` (experiments 1, 3, 4 and 5), :mod:`~.timing` (2), :mod:`~.histories` (the
latent-size study), :mod:`~.obstacle` (6), :mod:`~.run` (all of them in order, and the
figures), :mod:`~.report` (``results.md``), :mod:`~.summary` (``results.json``) and
:mod:`~.plots` (the figures' drawing).
"""

from sik_ros.eval.baselines import (Baseline, BASELINE_KINDS, load_baselines, Method,
                                    psik_solver, TracIK)
from sik_ros.eval.metrics import arm_points, orientation_cosine, position_errors
from sik_ros.eval.paper import DIVERSITY_TARGETS, PAPER, RADII, SWEEP_TARGET
from sik_ros.eval.report import report
from sik_ros.eval.run import machine_info, Results, run_evaluation, Settings
from sik_ros.eval.shipped import BASELINE_FILES
from sik_ros.eval.summary import summary, summary_json

__all__ = ['arm_points', 'Baseline', 'BASELINE_FILES', 'BASELINE_KINDS', 'DIVERSITY_TARGETS',
           'load_baselines', 'machine_info', 'Method', 'orientation_cosine', 'PAPER',
           'position_errors', 'psik_solver', 'RADII', 'report', 'Results', 'run_evaluation',
           'Settings', 'summary', 'summary_json', 'SWEEP_TARGET', 'TracIK']
