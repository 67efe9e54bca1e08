"""The report's sections on postures: diversity, posture indices, orientation, obstacles."""

from typing import List

import numpy as np

from sik_ros.eval.index_properties import index_properties_lines
from sik_ros.eval.markdown import fmt, table, verdict
from sik_ros.eval.metrics import mean_cm
from sik_ros.eval.obstacle import NoObstacleCase
from sik_ros.eval.orientation_study import ORIENTED_POOL
from sik_ros.eval.paper import LETTERS, NAMES, PAPER
from sik_ros.eval.raw_pose import raw_pose_lines
from sik_ros.eval.report_distance import pose_lookup_lines
from sik_ros.eval.run import Results


def diversity_section(res: Results) -> List[str]:
    """Experiment 3."""
    lines = ['## 3. Diversity: ten postures per target', '',
             'For each of the paper\'s four targets, ten posture indices far apart from each '
             'other (farthest-point sampling among the indices of the table cells nearest the '
             'target, as the paper picks far-apart indices from its KD-tree and dictionary) are '
             'decoded (raw) and then refined. The variance is the population variance of each '
             'joint over the ten solutions in deg²: the paper\'s Table 3 prints no unit, but its '
             'values fit only deg² (joint 5\'s 335 would be an impossible standard deviation in '
             'degrees for a ±166° joint, and an impossible variance in rad²).', '']
    for name, recs in res.diversity.items():
        paper_var = PAPER['variance_deg2'][name]
        paper_err = PAPER['diversity_cm'][name]
        rows = []
        for i, r in enumerate(recs):
            tgt = LETTERS[i]
            rows.append([tgt, 'ours raw'] + [fmt(v) for v in r.var_raw])
            rows.append([tgt, 'ours refined'] + [fmt(v) for v in r.var_refined])
            rows.append([tgt, 'paper'] + [fmt(v) for v in paper_var[i]])
        lines += [f'### {NAMES[name]}: per-joint variance [deg²] (paper Table 3)', '']
        joints = [f'joint {j + 1}' for j in range(len(recs[0].var_raw))]
        lines += table(['target', ''] + joints, rows) + ['']
        rows = []
        for i, r in enumerate(recs):
            pos = '(' + ', '.join(f'{v:g}' for v in r.position) + ')'
            k = len(r.err_raw)
            pad = [''] * (10 - k)
            rows.append([pos, 'ours raw'] + [fmt(100 * e) for e in r.err_raw] + pad
                        + [fmt(mean_cm(r.err_raw))])
            rows.append(['', 'ours refined'] + [fmt(100 * e) for e in r.err_refined] + pad
                        + [fmt(mean_cm(r.err_refined))])
            rows.append(['', 'paper'] + [fmt(v) for v in paper_err[i]]
                        + [fmt(np.mean(paper_err[i]))])
        lines += [f'### {NAMES[name]}: distance errors [cm] (paper Table 4)', '']
        lines += table(['goal [m]', ''] + [f'No. {j + 1}' for j in range(10)] + ['avg'], rows)
        ours = float(np.mean([mean_cm(r.err_raw) for r in recs]))
        paper = float(np.mean(paper_err))
        distinct = ', '.join(f'{LETTERS[i]}: {r.distinct_raw}/{len(r.err_raw)} raw, '
                             f'{r.distinct_refined} refined' for i, r in enumerate(recs))
        lines += ['', '- ' + verdict(ours, paper, 'cm', f'{NAMES[name]} raw error of the ten '
                                     'postures, mean over the four targets'),
                  f'- Distinct postures (at least {0.5} rad apart over joints 1-6): {distinct}.',
                  '', f'![{name} postures]({res.figures[f"diversity_{name}"]})', '']
    return lines


def indices_section(res: Results) -> List[str]:
    """Experiment 4."""
    lines = ['## 4. Posture indices', '', '### Latent size (1 to 7)', '']
    if res.latent is None:
        lines += ['Not run: this is a training study (one model per latent size). Train '
                  '`latent_<d>.pt` for d = 1..7 (`sik-train --latent-dim d --export '
                  'DIR/latent_d.pt`) and pass `--latent-study DIR`. The paper: sizes below 3 '
                  'fail to fit (their loss stops decreasing early); 3 and more reach comparable '
                  'errors, larger ones converge faster.', '']
    elif not res.latent:
        lines += [f'Not run: no `latent_<d>.pt` in `{res.settings.latent_dir}`.', '']
    else:
        rows = [[r.latent_dim, r.step, fmt(r.final_loss, 4),
                 fmt(None if r.val_dist_mean_m is None else 100 * r.val_dist_mean_m)]
                for r in res.latent]
        lines += ['Final training loss and validation distance error (decoded from the true '
                  'posture index) of each checkpoint. The paper reports no numbers, only that '
                  'sizes below 3 fail to fit and 3 or more converge, faster when larger.', '']
        lines += table(['latent size', 'steps', 'final loss', 'validation error [cm]'], rows)
        lines += ['', 'Made with `scripts/latent_study.sh`: one SIK position model per size on '
                  'the 30° grid, the paper\'s joint loss, the same seed, layers and schedule, a '
                  'short budget (see the steps column), so the ordering of the sizes is the '
                  'finding, not the absolute errors. As in the paper, sizes 1-2 barely fit and '
                  'larger indices fit faster. A large index is not automatically better for the '
                  'method: a 7-d index can carry all seven joints, so the decoder can ignore the '
                  'goal; the bundled model keeps the paper\'s 4.']
        lines += ['', f'![latent study]({res.figures["latent_study"]})', '']
    lines += index_properties_lines(res.index_props)
    if 'training_curves' in res.figures:
        lines += ['Training curves of the evaluated models (from their checkpoints):', '',
                  f'![training curves]({res.figures["training_curves"]})', '']
    sw = res.sweep
    lines += ['### One element at a time at (-0.25, -0.25, 0.25) (paper Table 5)', '',
              f'The other elements stay at the median of the {sw.pool_size} table indices '
              'near the target; the varied element takes six evenly spaced values from the '
              'smallest to the largest of those indices. Errors in cm.', '']
    rows = []
    for d, e in enumerate(sw.elements):
        paper = PAPER['sweep_cm'][d] if d < len(PAPER['sweep_cm']) else [None] * 6
        rows.append([f'element {d + 1}', 'value'] + [fmt(v) for v in e.values] + [''])
        rows.append(['', 'ours raw'] + [fmt(100 * v) for v in e.err_raw]
                    + [fmt(mean_cm(e.err_raw))])
        rows.append(['', 'ours refined'] + [fmt(100 * v) for v in e.err_refined]
                    + [fmt(mean_cm(e.err_refined))])
        rows.append(['', 'paper'] + [fmt(v) for v in paper]
                    + [fmt(None if paper[0] is None else np.mean(paper))])
    lines += table(['element', ''] + [f'{k + 1}' for k in range(6)] + ['avg'], rows)
    ours = float(np.mean([mean_cm(e.err_raw) for e in sw.elements]))
    lines += ['', '- ' + verdict(ours, float(np.mean(PAPER['sweep_cm'])), 'cm',
                                 'raw error over the sweep'), '',
              f'![element sweep]({res.figures["element_sweep"]})', '']
    return lines


def orientation_section(res: Results) -> List[str]:
    """Experiment 5."""
    o = res.orientation
    lines = ['## 5. Orientation as goal', '']
    if o is None:
        return lines + ['Not run: the bundle has no pose model.', '']
    paper = PAPER['orientation']
    pose = res.histories.get('pose')
    latent = int(pose.config['latent_dim']) if pose is not None else 1
    chosen = (f'of the pose model ({latent} elements) far apart among the {ORIENTED_POOL} table '
              'rows near the target position whose tips had the orientation nearest the '
              'target\'s (as the solver looks them up)' if latent > 1 else
              'of the pose model (1-d) at the 0, 25, 50, 75 and 100 % quantiles of the table '
              'indices near the target position')
    lines += ['Four reachable poses (tips of seeded uniform joint samples); for each, five '
              f'posture indices {chosen}, decoded (raw) and '
              'refined. Cosine similarity of orientation: the mean over the three axes of the '
              'tip frame of the cosine between the target axis and the reached one, '
              '(1 + 2 cos θ) / 3 for a rotation error θ. (The paper does not define its cosine; '
              'its 0.9983 read as cos θ of one axis is the "about 3 degrees" it states, read as '
              'our mean over axes it is 4.1°.)', '']
    rows = []
    for i, t in enumerate(o.targets):
        pos = '(' + ', '.join(f'{v:.3f}' for v in t.position) + ')'
        rows.append([LETTERS[i], pos, fmt(mean_cm(t.err_raw)), fmt(np.mean(t.cos_raw), 4),
                     fmt(np.degrees(np.mean(t.angle_raw)), 1), fmt(mean_cm(t.err_refined)),
                     fmt(np.mean(t.cos_refined), 4),
                     fmt(np.degrees(np.mean(t.angle_refined)), 1)])
    rows.append(['mean', '', fmt(100 * o.err_raw), fmt(o.cos_raw, 4),
                 fmt(np.degrees(o.angle_raw), 1), fmt(100 * o.err_refined),
                 fmt(o.cos_refined, 4), fmt(np.degrees(o.angle_refined), 1)])
    rows.append(['paper', '', fmt(paper['distance_cm']), fmt(paper['cosine'], 4), '≈3', '—',
                 '—', '—'])
    lines += table(['target', 'position [m]', 'raw error [cm]', 'raw cosine', 'raw angle [°]',
                    'refined error [cm]', 'refined cosine', 'refined angle [°]'], rows)
    lines += ['', '- ' + verdict(100 * o.err_raw, paper['distance_cm'], 'cm',
                                 'raw distance error with orientation held'),
              '- ' + verdict(1 - o.cos_raw, 1 - paper['cosine'], '', 'raw orientation, as '
                             '1 − cosine similarity', 4), '']
    if 'orientation' in res.figures:
        lines += [f'![orientation]({res.figures["orientation"]})', '']
    return lines + pose_lookup_lines(res) + raw_pose_lines(res.raw_pose)


def obstacle_section(res: Results) -> List[str]:
    """Experiment 6."""
    ob = res.obstacle
    lines = ['## 6. Obstacle avoidance (Algorithm 2)', '']
    if ob is None:
        return lines + ['Not run: the bundle has no position model.', '']
    if isinstance(ob, NoObstacleCase):
        return lines + [f'Not run: {ob.reason}.', '']
    b = ob.box
    goal = ', '.join(f'{v:g}' for v in ob.goal)
    how = ('found by Algorithm 2 (posture-index adjustment): none of the unconstrained '
           'solutions' if ob.from_adjustment else 'one of the unconstrained solutions, '
           'ranked first once collisions count')
    ok = ob.converged and ob.clearance_chosen > 0
    lines += [f'Goal ({goal}) m. The first-ranked unconstrained solution is found; then a box '
              f'{" × ".join(f"{100 * v:.0f}" for v in b.dimensions)} cm (depth along the '
              'base-goal line × width × height) is stood on the table (z = 0) between the robot '
              'and the goal, facing the goal: slid from near the goal towards the base (lowest '
              'height first) until that posture hits it, with the goal at least 5 cm outside '
              f'(the posture\'s clearance: {100 * ob.clearance_first:+.1f} cm; '
              f'{ob.unconstrained_colliding} of the {ob.unconstrained_total} distinct '
              'unconstrained solutions hit it). We check the goal posture only: no motion is '
              'planned from a start point, unlike the paper\'s demonstration. '
              '`solve(goal, obstacles=[box])` ranks collision-free exact solutions first and runs '
              'Algorithm 2 (posture-index adjustment) when none of its candidates is free. '
              'Clearances are signed distances between the robot\'s collision geometry and the '
              'box (negative: penetration).', '',
              f'- Chosen solution: clearance {100 * ob.clearance_chosen:+.1f} cm, distance '
              f'error {1000 * ob.error_chosen:.3f} mm, '
              f'{"exact" if ob.converged else "not within tolerance"}; {how}; '
              f'{1000 * ob.elapsed_s:.0f} ms.',
              '- ' + ('It clears the box where the first unconstrained solution does not.' if ok
                      else '**It does not clear the box: Algorithm 2 failed in this case.**'),
              '', f'![obstacle]({res.figures["obstacle"]})', '']
    return lines
