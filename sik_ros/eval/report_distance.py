"""Experiment 1 in the report: the paper's comparison, then the product's answers apart.

The paper's figures are set beside ours only for what its protocol measures: for SIK and PSIK the
look-up's indices decoded at the target with none selected by error
(:mod:`~sik_ros.eval.lookup`), for FCN and ANFIS their one prediction. The solver's raw answers
(the best of many decoded indices by FK error) and refined answers are figures of the product,
shown in a table of their own with no paper column.
"""

from typing import Dict, List, Sequence

import numpy as np

from sik_ros.eval.baselines import Method
from sik_ros.eval.lookup import MIN_INDICES, POSE_INDICES
from sik_ros.eval.markdown import fmt, table, verdict
from sik_ros.eval.metrics import mean_cm
from sik_ros.eval.paper import NAMES, PAPER, RADII
from sik_ros.eval.run import Results
from sik_ros.eval.shipped import BASELINE_FILES

#: The variant compared with the paper, per kind of model.
PAPER_VARIANT = {'sik': 'lookup', 'psik': 'lookup'}
#: The product's variants and their names in the report.
PRODUCT = (('raw_first', 'raw answer, best of the decoded indices by FK error'),
           ('raw_mean', 'raw answers, mean of the 10 returned (best by FK error)'),
           ('refined', 'refined answer (damped least squares)'))

PROTOCOL = (
    'The distance error is the distance between the target and the tip that the joint angles '
    'reach, by Pinocchio\'s forward kinematics (the paper\'s definition). Targets are reachable '
    'by construction: the tip positions of joint angles drawn uniformly within the limits.', '',
    '**The paper\'s protocol** (the only figures set beside the paper\'s): for SIK and PSIK, '
    'the posture indices of the table cells nearest the target (the paper takes those of the '
    'collected poses nearest the target): the nearest cell first, as few cells as give at '
    f'least {MIN_INDICES} indices, every index those cells hold for the look-up by position. '
    'Each is decoded at the target as it is, and every one counts: a target\'s error is the '
    'mean over all of them, none selected or dropped by its error. Which indices a cell holds '
    'is fixed when the table is built (see "Models": a table that marks the indices its '
    'decoder realises gives only those). FCN and ANFIS predict one solution, '
    'clipped to the limits. The paper trained FCN on the original and on the uni-position '
    'dataset (one row per position), ANFIS on the uni-position one. Self-collisions are not '
    'excluded (the paper switched them off too).')


def _models(baselines: Dict[str, Method]) -> List[str]:
    return ['sik'] + [k for k in BASELINE_FILES if k in baselines]


def _key(name: str) -> str:
    return PAPER_VARIANT.get(name, 'raw')


def distance_section(res: Results, baselines: Dict[str, Method]) -> List[str]:
    """Experiment 1: the paper's comparison over the workspace and per radius, then ours."""
    d = res.distance
    lines = ['## 1. Distance error over the workspace', '', *PROTOCOL, '',
             f'### Over the workspace ({len(res.workspace_targets)} targets)', '']
    rows = []
    for name in _models(baselines):
        e = d.workspace[name][_key(name)]
        count = d.workspace[name].get('lookup_count')
        rows.append([NAMES[name], fmt(mean_cm(e)), fmt(100 * np.median(e)),
                     '1' if count is None else f'{np.min(count):.0f}-{np.max(count):.0f}',
                     fmt(PAPER['workspace_cm'][name], 1)])
    lines += table(['model', 'mean [cm]', 'median [cm]', 'indices decoded per target',
                    'paper mean [cm]'], rows) + ['']
    for name in _models(baselines):
        lines.append('- ' + verdict(mean_cm(d.workspace[name][_key(name)]),
                                    PAPER['workspace_cm'][name], 'cm',
                                    f'{NAMES[name]} over the workspace'))
    return lines + [''] + radius_lines(res, baselines) + product_lines(res, baselines)


def radius_lines(res: Results, baselines: Dict[str, Method]) -> List[str]:
    """Per radius: ours by the paper's protocol against its Table 2, and the count of radii."""
    st = res.settings
    means = res.distance.radius_means_cm()
    lines = [f'### Per radius ({st.targets} targets per radius)', '',
             'Targets lie within 1 cm of a sphere of the given radius around the base origin '
             f'(the robot\'s base frame): among {st.samples:,} tips of uniform joint samples, '
             f'those within 1 cm of the sphere, {st.targets} picked at random. "targets" says '
             'how many there were when fewer than asked. Errors in cm by the paper\'s protocol; '
             'the paper\'s figures (Table 2) beside ours.', '']
    if len(st.radii) < len(RADII):
        lines += [f'Only {len(st.radii)} of the paper\'s {len(RADII)} radii were run: our '
                  'averages cover those, the paper\'s cover all of its radii.', '']
    header, cols = ['radius [cm]', 'targets'], []
    for name in _models(baselines):
        header += [f'{NAMES[name]} ours', f'{NAMES[name]} paper']
        cols += [means[name][_key(name)], [PAPER['radius_cm'][name][RADII.index(r)]
                                           for r in st.radii]]
    lines += ['<!-- per-radius table -->'] + table(header, _radius_rows(res, cols)) + ['']
    for name in _models(baselines):
        ours = means[name][_key(name)]
        paper = [PAPER['radius_cm'][name][RADII.index(r)] for r in st.radii]
        at = sum(o <= p for o, p in zip(ours, paper))
        lines.append('- ' + verdict(float(np.nanmean(ours)), PAPER['radius_avg_cm'][name], 'cm',
                                    f'{NAMES[name]} averaged over the radii')
                     + f' At or under the paper at {at} of {len(paper)} radii.')
    missing = [NAMES[k] for k in BASELINE_FILES if k not in baselines]
    if missing:
        lines.append(f'- Not measured (no model given): {", ".join(missing)}.')
    return lines + ['', f'![error against radius]({res.figures["error_vs_radius"]})', '']


def _radius_rows(res: Results, cols: Sequence[Sequence[float]]) -> List[List[str]]:
    st = res.settings
    rows = []
    for i, r in enumerate(st.radii):
        sph = res.spheres[r]
        n = str(len(sph.positions))
        if sph.available < st.targets:
            n += f' (of {st.targets}: only {sph.available} exist)'
        rows.append([f'{100 * r:.0f}', n] + [fmt(c[i]) for c in cols])
    rows.append(['average', ''] + [fmt(np.nanmean(c)) for c in cols])
    return rows


def product_lines(res: Results, baselines: Dict[str, Method]) -> List[str]:
    """The solver's own answers at the same targets: figures of the product, not the paper's."""
    d = res.distance
    solvers = [m for m in _models(baselines) if 'raw_first' in d.workspace[m]]
    lines = ['### The product\'s answers (not the paper\'s protocol)', '',
             'What `solve()` returns at the same targets. A raw call decodes up to 192 posture '
             'indices from the table and returns the ones of least FK error first (self-'
             'colliding postures last): its answers are selected by their error, so they are '
             'not comparable with the paper\'s figures and none is set beside them. A refined '
             'answer adds damped least squares on top of the decoder.', '']
    rows = []
    for name in solvers:
        for key, label in PRODUCT:
            e = d.workspace[name][key]
            per = res.distance.radius_means_cm()[name][key]
            rows.append([NAMES[name], label, fmt(mean_cm(e)), fmt(np.nanmean(per)),
                         fmt(np.nanmax(per))])
    lines += table(['model', 'answer', 'workspace mean [cm]', 'mean over the radii [cm]',
                    'worst radius [cm]'], rows) + ['']
    counts = d.workspace['sik']['raw_count']
    lines += [f'- SIK raw calls returned {np.mean(counts):.1f} distinct solutions on average '
              '(at most 10 were asked).', '']
    return lines


def pose_lookup_lines(res: Results) -> List[str]:
    """The pose model by the paper's protocol over uniform targets, against the paper's."""
    look = res.pose_lookup
    if look is None:
        return []
    n = len(look.distance)
    dist, angle = mean_cm(look.distance), float(np.degrees(look.angle.mean()))
    paper = PAPER['orientation']['distance_cm']
    lines = ['### The pose model by the paper\'s protocol', '',
             f'{n} pose targets uniform in joint space (seed 2024). For each, the '
             f'{POSE_INDICES} table rows of the cells around the target position whose tips '
             'had the orientation nearest the target\'s (the paper\'s KD-tree over positions '
             'and orientations) are decoded at the target, every one counted; errors by '
             'Pinocchio\'s FK.', '']
    lines += table(['pose model', 'distance [cm]', 'orientation [°]'],
                   [['ours, paper\'s protocol', fmt(dist), fmt(angle, 1)],
                    ['paper', fmt(paper), '≈3']]) + ['']
    lines.append('- ' + verdict(dist, paper, 'cm', 'pose model, distance'))
    lines.append('- ' + verdict(angle, 3.0, '°', 'pose model, orientation', 1))
    return lines + ['']
