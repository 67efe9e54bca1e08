"""``sik-eval``: reproduce the paper's experiments; write ``results.md`` and PNG figures.

    sik-eval --out docs/                         # everything on the bundled models (minutes)
    sik-eval --quick --bundle DIR --out /tmp/e   # a reduced run (seconds)

Numbers come from :mod:`sik_ros.evaluation`, figures from :mod:`sik_ros.plots`; this module
only runs the experiments in order and writes the report beside the paper's figures.
"""

import argparse
import datetime
import json
import os
from pathlib import Path
import shlex
import sys
import tempfile
from typing import Dict, List, Optional, Sequence

import numpy as np
import torch
from tqdm import tqdm

from sik_ros import evaluation as ev
from sik_ros import plots
from sik_ros.artifacts import read_json
from sik_ros.cli import argv_or_default, run_cli
from sik_ros.errors import InvalidArgument
from sik_ros.solver import SelectiveIK
from sik_ros.training import load_checkpoint

NAMES = {'sik': 'SIK', 'psik': 'PSIK', 'fcn': 'FCN', 'fcn_uni': 'FCN-uni', 'anfis': 'ANFIS'}
DATASETS = {'sik': 'original dataset', 'psik': 'original dataset', 'fcn': 'original dataset',
            'fcn_uni': 'uni-position dataset', 'anfis': 'uni-position dataset'}
VARIANTS = {'raw_first': 'raw 1st', 'raw_mean': 'raw mean', 'refined': 'refined', 'raw': 'raw'}
QUICK_RADII = (0.1, 0.3, 0.5, 0.7)
LETTERS = 'abcd'


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of sik-eval."""
    p = argparse.ArgumentParser(prog='sik-eval', description='Reproduce the experiments of the '
                                'Selective IK paper and write a report with tables and figures.')
    p.add_argument('--out', default='docs', help='report folder: results.md, results.json and '
                   'figures/ (default: docs)')
    p.add_argument('--bundle', default='panda', help='bundle name or directory (default: panda)')
    p.add_argument('--baselines', help='folder with psik.pt (or a psik/ bundle), fcn.pt, '
                   'fcn_uni.pt, anfis.pt; missing ones are reported as not provided')
    p.add_argument('--latent-study', help='folder with latent_<d>.pt checkpoints (d = 1..7)')
    p.add_argument('--quick', action='store_true', help='a reduced run: few targets and radii')
    p.add_argument('--targets', type=int, help='targets per radius and over the workspace '
                   '(default: 100, quick: 5)')
    p.add_argument('--samples', type=int, help='joint samples searched for targets near each '
                   'radius (default: 1,000,000, quick: 100,000)')
    p.add_argument('--seed', type=int, default=0, help='seed of the target sampling')
    p.add_argument('--threads', type=int, default=1, help='torch threads (default: 1)')
    p.add_argument('--quiet', action='store_true', help='no progress bar')
    return p


# -- formatting -----------------------------------------------------------------------------------

def fmt(v, nd: int = 2) -> str:
    """A number for a table; a dash for missing or NaN."""
    if v is None:
        return '—'
    v = float(v)
    return '—' if not np.isfinite(v) else f'{v:.{nd}f}'


def table(header: Sequence[str], rows: Sequence[Sequence]) -> List[str]:
    """A markdown table."""
    lines = ['| ' + ' | '.join(str(h) for h in header) + ' |',
             '|' + '|'.join('---' for _ in header) + '|']
    lines += ['| ' + ' | '.join(str(c) for c in r) + ' |' for r in rows]
    return lines


def verdict(ours: float, paper: float, unit: str, what: str, nd: int = 2) -> str:
    """A plain sentence: ours against the paper's figure, lower is better."""
    if ours is None or not np.isfinite(ours):
        return f'{what}: not measured.'
    unit = f' {unit}' if unit else ''
    if ours > paper:
        return (f'**{what}: ours is worse than the paper** ({fmt(ours, nd)}{unit} against '
                f'{fmt(paper, nd)}{unit}).')
    return f'{what}: ours is as good or better ({fmt(ours, nd)}{unit} against ' \
        f'{fmt(paper, nd)}{unit}).'


def mean_cm(errors) -> float:
    """Mean of errors [m] in cm (NaN when empty)."""
    errors = np.asarray(errors, dtype=float)
    return float(errors.mean() * 100) if errors.size else float('nan')


def to_jsonable(obj):
    """Numpy arrays and scalars as lists and floats, recursively."""
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
    if isinstance(obj, ev.Obstacle):
        return {'shape': obj.shape, 'dimensions': list(obj.dimensions),
                'position': list(obj.position)}
    return obj


def write_text_atomic(path: Path, text: str) -> None:
    """Write a text file under a temporary name, then rename it."""
    fd, tmp = tempfile.mkstemp(prefix=f'.{path.name}.', suffix='.tmp', dir=path.parent)
    with os.fdopen(fd, 'w') as f:
        f.write(text)
    os.replace(tmp, path)


# -- the run --------------------------------------------------------------------------------------

class Run:
    """One evaluation run: settings, results and the figure paths."""

    def __init__(self, args: argparse.Namespace):
        self.args = args
        self.out = Path(args.out)
        self.fig_dir = self.out / 'figures'
        self.quick = args.quick
        self.n_targets = args.targets or (5 if args.quick else 100)
        self.samples = args.samples or (100_000 if args.quick else 1_000_000)
        self.radii = QUICK_RADII if args.quick else ev.RADII
        self.results: Dict = {}
        self.figures: Dict[str, str] = {}

    def figure(self, key: str, draw) -> None:
        """Draw a figure into ``figures/<key>.png`` and remember its relative path."""
        draw(self.fig_dir / f'{key}.png')
        self.figures[key] = f'figures/{key}.png'


def histories_of_bundle(ik: SelectiveIK) -> Dict[str, Dict]:
    """Training histories and summaries of a bundle's models, by goal kind."""
    out = {}
    if ik.bundle is None or not (Path(ik.bundle) / 'bundle.json').is_file():
        return out
    manifest = read_json(Path(ik.bundle) / 'bundle.json', f'bundle {ik.bundle}')
    for goal, files in manifest['models'].items():
        ckpt = load_checkpoint(Path(ik.bundle) / files['model'])
        out[goal] = {'history': ckpt.get('history', []), 'step': int(ckpt.get('step', 0)),
                     'elapsed_s': float(ckpt.get('elapsed_s', 0.0)),
                     'config': ckpt['model_config']}
    return out


def run_experiments(run: Run, ik: SelectiveIK, baselines: Dict, bar) -> None:
    """All six experiments, results into ``run.results``, figures into ``run.fig_dir``."""
    robot = ik.robot
    res = run.results

    def step(n=1):
        bar.update(n)

    bar.set_description('sampling targets')
    ws, _ = ev.workspace_targets(robot, run.n_targets, seed=run.args.seed)
    spheres = ev.sphere_targets(robot, run.radii, run.n_targets, run.samples,
                                seed=run.args.seed + 1)
    n_models = 1 + len(baselines)
    n_radius = sum(len(s['positions']) for s in spheres.values())
    n_timing = min(run.n_targets, 100)
    timed = 5 * (1 + sum(isinstance(b, SelectiveIK) for b in baselines.values())) + \
        sum(isinstance(b, ev.Baseline) for b in baselines.values()) + 1
    n_solvers = 1 + sum(isinstance(b, SelectiveIK) for b in baselines.values())
    bar.total = n_models * (len(ws) + n_radius) + n_timing * timed + 9 + n_solvers
    bar.refresh()

    bar.set_description('1 distance error')
    res['spheres'] = spheres
    res['workspace_targets'] = ws
    res['distance'] = ev.distance_error_study(ik, baselines, ws, spheres, step)

    bar.set_description('2 computing time')
    q_t = np.random.default_rng(run.args.seed + 2).uniform(robot.lower, robot.upper,
                                                           (n_timing, robot.dof))
    pos_t, quat_t = robot.fk_batch(q_t)
    try:
        tracik = ev.TracIK(robot)
        res['tracik_note'] = ''
    except ImportError as exc:
        tracik = None
        res['tracik_note'] = f'TRAC-IK not run: pytracik is not importable ({exc}).'
    res['timing'] = ev.timing_study(ik, baselines, pos_t, quat_t, tracik, run.args.seed, step)

    bar.set_description('3 diversity')
    solvers = {'sik': ik, **{k: v for k, v in baselines.items() if isinstance(v, SelectiveIK)}}
    res['diversity'] = {name: ev.diversity_study(s) for name, s in solvers.items()}
    step()

    bar.set_description('4 posture indices')
    res['latent'] = ev.latent_study(run.args.latent_study)
    res['sweep'] = ev.element_sweep(ik)
    res['histories'] = histories_of_bundle(ik)
    step()

    bar.set_description('5 orientation')
    res['orientation'] = ev.orientation_study(ik) if 'pose' in ik.goals else None
    step()

    bar.set_description('6 obstacle')
    res['obstacle'] = ev.obstacle_study(ik) if 'position' in ik.goals else None
    step()

    bar.set_description('figures')
    draw_figures(run, ik, baselines, step)


def radius_means(run: Run) -> Dict[str, Dict[str, List[float]]]:
    """Mean error [cm] per radius: ``{model: {variant: [per radius]}}``."""
    return {name: {v: [mean_cm(e) for e in per] for v, per in variants.items()}
            for name, variants in run.results['distance']['radius'].items()}


def draw_figures(run: Run, ik: SelectiveIK, baselines: Dict, step) -> None:
    """Every PNG of the report."""
    robot, res = ik.robot, run.results
    radii_cm = [100 * r for r in run.radii]
    means = radius_means(run)
    ours = {}
    for name, variants in means.items():
        for v in ('raw_mean', 'refined', 'raw'):
            if v in variants:
                ours[f'{NAMES[name]} {VARIANTS[v]}'] = variants[v]
    paper = {NAMES[k]: v for k, v in ev.PAPER['radius_cm'].items()
             if k == 'sik' or k in baselines}
    run.figure('error_vs_radius', lambda p: plots.error_vs_radius(
        radii_cm, ours, paper, p, paper_radii_cm=[100 * r for r in ev.RADII]))
    step()
    for name, recs in res['diversity'].items():
        rows = [(LETTERS[i], r['q_raw'], r['position'],
                 [f'{100 * e:.2f} cm' for e in r['err_raw']]) for i, r in enumerate(recs)]
        run.figure(f'diversity_{name}', lambda p, rows=rows, name=name: plots.posture_grid(
            robot, rows, p, f'{NAMES[name]}: ten far-apart posture indices per target (raw '
            'decoder output; caption: distance error)'))
        step()
    sw = res['sweep']
    rows = [(f'element {d + 1}', e['q_raw'], sw['position'],
             [f'{v:+.2f}: {100 * err:.2f} cm' for v, err in zip(e['values'], e['err_raw'])])
            for d, e in enumerate(sw['elements'])]
    run.figure('element_sweep', lambda p: plots.posture_grid(
        robot, rows, p, 'One index element varied at (-0.25, -0.25, 0.25), others at the '
        'median (raw; caption: value: error)'))
    step()
    hist = {f'SIK {goal}': h['history'] for goal, h in res['histories'].items()}
    hist.update({f'{NAMES[k]}': b.history for k, b in baselines.items()
                 if isinstance(b, ev.Baseline) and b.history})
    if any(hist.values()):
        run.figure('training_curves', lambda p: plots.training_curves(hist, p))
    if res['latent']:
        run.figure('latent_study', lambda p: plots.training_curves(
            {f'latent {r["latent_dim"]}': r['history'] for r in res['latent']}, p))
    step()
    if res['orientation'] is not None:
        rows = [(LETTERS[i], t['q_raw'], t['position'],
                 [f'{100 * e:.1f} cm, {np.degrees(a):.0f}°'
                  for e, a in zip(t['err_raw'], t['angle_raw'])])
                for i, t in enumerate(res['orientation']['targets'])]
        run.figure('orientation', lambda p: plots.posture_grid(
            robot, rows, p, 'Pose goals, 1-d index: five postures per target (raw; caption: '
            'distance error, orientation error)'))
    step()
    ob = res['obstacle']
    if ob is not None and ob.get('goal') is not None:
        run.figure('obstacle', lambda p: plots.obstacle_figure(
            robot, ob['q_first'], ob['q_chosen'], ob['box'], ob['goal'], p,
            (f'first unconstrained solution: clearance {100 * ob["clearance_first"]:+.1f} cm',
             f'chosen with the box: clearance {100 * ob["clearance_chosen"]:+.1f} cm')))
    step()


# -- the report -----------------------------------------------------------------------------------

def report(run: Run, ik: SelectiveIK, baselines: Dict, missing: Dict[str, str],
           argv: Sequence[str]) -> str:
    """The markdown report."""
    lines: List[str] = []
    res = run.results
    mach = res['machine']
    lines += ['# Results: the paper\'s experiments, reproduced', '',
              f'Generated by `sik-eval {" ".join(shlex.quote(a) for a in argv)}` on '
              f'{res["date"]} in {res["elapsed_s"]:.0f} s.', '']
    if run.quick:
        lines += ['> **This is a `--quick` run**: a handful of targets on a few radii. Its '
                  'numbers check that the pipeline works; they are not a measurement.', '']
    lines += [f'**Machine**: {mach["cpu"]}, {mach["cores"]} cores, {mach["platform"]}, Python '
              f'{mach["python"]}, torch {mach["torch"]} with {mach["torch_threads"]} thread(s). '
              f'Load average at the start: {", ".join(map(str, mach["load_average"]))}'
              + (' (other jobs were running: the timings are slower than on an idle machine)'
                 if mach['load_average'][0] > 0.5 else '')
              + '. The paper used an Intel i7-8700 with 64 GB of memory.', '']
    lines += models_section(ik, baselines, missing, res)
    lines += distance_section(run, baselines)
    lines += timing_section(res, baselines)
    lines += diversity_section(run)
    lines += indices_section(run)
    lines += orientation_section(run)
    lines += obstacle_section(run)
    return '\n'.join(lines) + '\n'


def models_section(ik, baselines, missing, res) -> List[str]:
    """Which models were evaluated."""
    lines = ['## Models', '', f'Bundle `{ik.bundle}`:', '']
    for goal, h in res['histories'].items():
        cfg = h['config']
        last = h['history'][-1] if h['history'] else {}
        lines.append(f'- SIK, {goal} goals: latent size {cfg["latent_dim"]}, encoder '
                     f'{list(cfg["encoder"])}, decoder {list(cfg["decoder"])}, trained '
                     f'{h["step"]} steps ({h["elapsed_s"] / 60:.0f} min); last validation '
                     f'distance error {fmt(100 * last.get("val_dist_mean_m", np.nan))} cm '
                     '(decoded from the true posture index).')
    lines += ['', 'Baselines:', '']
    for name in ev.BASELINE_FILES:
        if name in baselines:
            b = baselines[name]
            path = b.bundle if isinstance(b, SelectiveIK) else b.path
            extra = ''
            if name == 'psik' and isinstance(b.models['position'].table, ev.PriorTable):
                extra = ' (no index table given: its candidate indices are 48 fixed draws from ' \
                    'its N(0, I) prior)'
            if isinstance(b, ev.Baseline):
                uni = bool(b.train_config.get('uni_position', False))
                extra = f' ({b.step} steps, uni-position: {"yes" if uni else "no"})'
                if (name in ('fcn_uni', 'anfis')) != uni:
                    extra += ' **— its dataset does not match its role**'
            lines.append(f'- {NAMES[name]}: `{path}`{extra}')
        else:
            lines.append(f'- {NAMES[name]}: {missing.get(name, "not provided")}')
    return lines + ['']


def distance_section(run: Run, baselines: Dict) -> List[str]:
    """Experiment 1."""
    res = run.results
    d = res['distance']
    lines = ['## 1. Distance error over the workspace', '',
             'The distance error is the distance between the target and the tip that the '
             'returned joint angles reach, computed by forward kinematics (the paper\'s '
             'definition). Targets are reachable by construction: the tip positions of joint '
             'angles drawn uniformly within the limits. Variants: **raw 1st** is the '
             'first-ranked solution of `solve(refine=False)`: the decoder output for up to 192 '
             'posture indices from the table, ranked by FK error (self-colliding postures '
             'last), an optimistic reading of a raw decoder; **raw mean** is the mean over the '
             'up to 10 distinct solutions that call returns, closest to the paper\'s protocol '
             'of decoding indices from the table (the paper\'s figure for SIK and PSIK is set '
             'beside it); **refined** is the first solution of `solve()`, damped least squares '
             'on top of the decoder. FCN and ANFIS predict one solution; their angles are '
             'clipped to the limits. The paper trained FCN on the original and on the '
             'uni-position dataset (one row per position), ANFIS on the uni-position one.', '',
             f'### Over the workspace ({len(res["workspace_targets"])} targets)', '']
    rows = []
    for name, variants in d['workspace'].items():
        for v, e in variants.items():
            if v == 'raw_count':
                continue
            paper = ev.PAPER['workspace_cm'][name] if v in ('raw_mean', 'raw') else None
            rows.append([NAMES[name], VARIANTS[v], fmt(mean_cm(e)),
                         fmt(100 * np.median(e)), fmt(paper, 1)])
    lines += table(['model', 'variant', 'mean [cm]', 'median [cm]', 'paper mean [cm]'], rows)
    lines += ['']
    for name, variants in d['workspace'].items():
        key = 'raw_mean' if 'raw_mean' in variants else 'raw'
        what = f'{NAMES[name]} ({VARIANTS[key]}) over the workspace'
        lines.append('- ' + verdict(mean_cm(variants[key]), ev.PAPER['workspace_cm'][name],
                                    'cm', what))
    counts = d['workspace']['sik']['raw_count']
    lines += [f'- SIK raw calls returned {np.mean(counts):.1f} distinct solutions on average '
              '(at most 10 were asked).', '']

    lines += [f'### Per radius ({run.n_targets} targets per radius)', '',
              'Targets lie within 1 cm of a sphere of the given radius around the base origin '
              f'(`panda_link0`): among {run.samples:,} tips of uniform joint samples, those '
              f'within 1 cm of the sphere, {run.n_targets} picked at random. "targets" says how '
              'many there were when fewer than asked. Errors in cm; the paper\'s figures '
              '(Table 2) beside ours. Self-collisions are not excluded (the paper switched them '
              'off too).', '']
    means = radius_means(run)
    header = ['radius [cm]', 'targets']
    cols = []
    for name in ['sik'] + [k for k in ev.BASELINE_FILES if k in baselines]:
        for v in ('raw_first', 'raw_mean', 'refined', 'raw'):
            if v in means[name]:
                header.append(f'{NAMES[name]} {VARIANTS[v]}')
                cols.append(means[name][v])
        header.append(f'{NAMES[name]} paper')
        cols.append(ev.PAPER['radius_cm'][name])
    rows = []
    for i, r in enumerate(run.radii):
        k = ev.RADII.index(r)
        sph = res['spheres'][r]
        avail = sph['available']
        n = str(len(sph['positions']))
        if avail < run.n_targets:
            n += f' (of {run.n_targets}: only {avail} exist)'
        row = [f'{100 * r:.0f}', n]
        for c, header_name in zip(cols, header[2:]):
            row.append(fmt(c[k], 2) if header_name.endswith('paper') else fmt(c[i]))
        rows.append(row)
    avg = ['average', '']
    for c, header_name in zip(cols, header[2:]):
        if header_name.endswith('paper'):
            key = [k for k, v in NAMES.items() if header_name == f'{v} paper'][0]
            avg.append(fmt(ev.PAPER['radius_avg_cm'][key]))
        else:
            avg.append(fmt(np.nanmean(c)))
    rows.append(avg)
    if len(run.radii) < len(ev.RADII):
        lines += [f'Only {len(run.radii)} of the paper\'s {len(ev.RADII)} radii were run: our '
                  'averages cover those, the paper\'s cover all of its radii.', '']
    lines += ['<!-- per-radius table -->'] + table(header, rows) + ['']
    for name in ['sik'] + [k for k in ev.BASELINE_FILES if k in baselines]:
        key = 'raw_mean' if 'raw_mean' in means[name] else 'raw'
        ours = float(np.nanmean(means[name][key]))
        what = f'{NAMES[name]} ({VARIANTS[key]}) averaged over the radii'
        lines.append('- ' + verdict(ours, ev.PAPER['radius_avg_cm'][name], 'cm', what))
    missing = [NAMES[k] for k in ev.BASELINE_FILES if k not in baselines]
    if missing:
        lines.append(f'- Not measured (no model given): {", ".join(missing)}; the paper\'s '
                     'rows are in the figure only for the models we ran.')
    lines += ['', f'![error against radius]({run.figures["error_vs_radius"]})', '']
    return lines


TIMING_ROWS = (
    ('{m}_decode', '{M} decoder forward, one posture index (model only)'),
    ('{m}_raw_1', '{M} raw: `solve(refine=False, num_solutions=1)`'),
    ('{m}_raw_10', '{M} raw: `solve(refine=False, num_solutions=10)`'),
    ('{m}_refined_1', '{M} refined: `solve(num_solutions=1)`'),
    ('{m}_refined_10', '{M} refined: `solve(num_solutions=10)`'),
)


def timing_section(res: Dict, baselines: Dict) -> List[str]:
    """Experiment 2."""
    t = res['timing']
    n = next(iter(t.values()))['calls']
    lines = ['## 2. Computing time', '',
             f'Wall-clock time (`time.perf_counter`) per call over {n} targets uniform in the '
             'workspace, after one warm-up call, one process, torch on 1 thread; the median is '
             'shown. "per solution" divides each call by the solutions it returned. The '
             'paper measured processor time (`time.clock`) of running its models over 100 '
             'targets. A raw `solve` decodes up to 192 posture indices in one batch and checks '
             'them by FK, a refined one 24 (48 for pose goals), '
             'whatever `num_solutions` is. TRAC-IK solves the full pose of the '
             'target (position and orientation, a harder problem), from a random seed, with a '
             '5 ms timeout.', '']
    rows = []
    solvers = ['sik'] + [k for k, v in baselines.items() if isinstance(v, SelectiveIK)]
    for m in solvers:
        for key, label in TIMING_ROWS:
            r = t.get(key.format(m=m))
            if r is None:
                continue
            rows.append([label.format(M=NAMES[m]), fmt(r['median_ms'], 3),
                         fmt(r['solutions_per_call'], 1), fmt(r['per_solution_ms'], 3),
                         fmt(ev.PAPER['time_ms'][m], 2) if key.endswith(('decode', 'raw_1'))
                         else '—'])
    for m, b in baselines.items():
        if isinstance(b, ev.Baseline):
            r = t[m]
            rows.append([f'{NAMES[m]} forward', fmt(r['median_ms'], 3), '1',
                         fmt(r['per_solution_ms'], 3),
                         fmt(ev.PAPER['time_ms'].get(m.replace('_uni', '')), 2)])
    if 'tracik' in t:
        r = t['tracik']
        rows.append([f'TRAC-IK (pose goal; success {100 * r["success"]:.0f} %)',
                     fmt(r['median_ms'], 3), fmt(r['solutions_per_call'], 2),
                     fmt(r['per_solution_ms'], 3), '—'])
    lines += table(['method', 'per call [ms]', 'solutions per call', 'per solution [ms]',
                    'paper [ms]'], rows) + ['']
    lines.append('- ' + verdict(t['sik_decode']['median_ms'], ev.PAPER['time_ms']['sik'], 'ms',
                                'SIK model time for one solution', 3))
    lines.append('- ' + verdict(t['sik_raw_1']['median_ms'], ev.PAPER['time_ms']['sik'], 'ms',
                                'SIK raw solve for one solution (table look-up, 192 decodes, FK '
                                'check, ranking)', 3))
    for m in ('fcn', 'anfis'):
        if m in t:
            lines.append('- ' + verdict(t[m]['median_ms'], ev.PAPER['time_ms'][m], 'ms',
                                        f'{NAMES[m]} forward', 3))
    if res.get('tracik_note'):
        lines.append(f'- {res["tracik_note"]}')
    return lines + ['']


def diversity_section(run: Run) -> List[str]:
    """Experiment 3."""
    lines = ['## 3. Diversity: ten postures per target', '',
             'For each of the paper\'s four targets, ten posture indices far apart from each '
             'other (farthest-point sampling among the indices of the table cells nearest the '
             'target, as the paper picks far-apart indices from its KD-tree and dictionary) are '
             'decoded (raw) and then refined. The variance is the population variance of each '
             'joint over the ten solutions in deg²: the paper\'s Table 3 prints no unit, but its '
             'values fit only deg² (joint 5\'s 335 would be an impossible standard deviation in '
             'degrees for a ±166° joint, and an impossible variance in rad²).', '']
    for name, recs in run.results['diversity'].items():
        paper_var = ev.PAPER['variance_deg2'][name]
        paper_err = ev.PAPER['diversity_cm'][name]
        rows = []
        for i, r in enumerate(recs):
            tgt = LETTERS[i]
            rows.append([tgt, 'ours raw'] + [fmt(v) for v in r['var_raw']])
            rows.append([tgt, 'ours refined'] + [fmt(v) for v in r['var_refined']])
            rows.append([tgt, 'paper'] + [fmt(v) for v in paper_var[i]])
        lines += [f'### {NAMES[name]}: per-joint variance [deg²] (paper Table 3)', '']
        lines += table(['target', ''] + [f'joint {j + 1}' for j in range(7)], rows) + ['']
        rows = []
        for i, r in enumerate(recs):
            pos = '(' + ', '.join(f'{v:g}' for v in r['position']) + ')'
            k = len(r['err_raw'])
            pad = [''] * (10 - k)
            rows.append([pos, 'ours raw'] + [fmt(100 * e) for e in r['err_raw']] + pad
                        + [fmt(mean_cm(r['err_raw']))])
            rows.append(['', 'ours refined'] + [fmt(100 * e) for e in r['err_refined']] + pad
                        + [fmt(mean_cm(r['err_refined']))])
            rows.append(['', 'paper'] + [fmt(v) for v in paper_err[i]]
                        + [fmt(np.mean(paper_err[i]))])
        lines += [f'### {NAMES[name]}: distance errors [cm] (paper Table 4)', '']
        lines += table(['goal [m]', ''] + [f'No. {j + 1}' for j in range(10)] + ['avg'], rows)
        ours = float(np.mean([mean_cm(r['err_raw']) for r in recs]))
        paper = float(np.mean(paper_err))
        distinct = ', '.join(f'{LETTERS[i]}: {r["distinct_raw"]}/{len(r["err_raw"])} raw, '
                             f'{r["distinct_refined"]} refined' for i, r in enumerate(recs))
        lines += ['', '- ' + verdict(ours, paper, 'cm', f'{NAMES[name]} raw error of the ten '
                                     'postures, mean over the four targets'),
                  f'- Distinct postures (at least {0.5} rad apart over joints 1-6): {distinct}.',
                  '', f'![{name} postures]({run.figures[f"diversity_{name}"]})', '']
    return lines


def indices_section(run: Run) -> List[str]:
    """Experiment 4."""
    res = run.results
    lines = ['## 4. Posture indices', '', '### Latent size (1 to 7)', '']
    if res['latent'] is None:
        lines += ['Not run: this is a training study (one model per latent size). Train '
                  '`latent_<d>.pt` for d = 1..7 (`sik-train --latent-dim d --export '
                  'DIR/latent_d.pt`) and pass `--latent-study DIR`. The paper: sizes below 3 '
                  'fail to fit (their loss stops decreasing early); 3 and more reach comparable '
                  'errors, larger ones converge faster.', '']
    elif not res['latent']:
        lines += [f'Not run: no `latent_<d>.pt` in `{run.args.latent_study}`.', '']
    else:
        rows = [[r['latent_dim'], r['step'], fmt(r['final_loss'], 4),
                 fmt(None if r['val_dist_mean_m'] is None else 100 * r['val_dist_mean_m'])]
                for r in res['latent']]
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
        lines += ['', f'![latent study]({run.figures["latent_study"]})', '']
    if 'training_curves' in run.figures:
        lines += ['Training curves of the evaluated models (from their checkpoints):', '',
                  f'![training curves]({run.figures["training_curves"]})', '']
    sw = res['sweep']
    lines += ['### One element at a time at (-0.25, -0.25, 0.25) (paper Table 5)', '',
              f'The other elements stay at the median of the {sw["pool_size"]} table indices '
              'near the target; the varied element takes six evenly spaced values from the '
              'smallest to the largest of those indices. Errors in cm.', '']
    rows = []
    for d, e in enumerate(sw['elements']):
        paper = ev.PAPER['sweep_cm'][d] if d < len(ev.PAPER['sweep_cm']) else [None] * 6
        rows.append([f'element {d + 1}', 'value'] + [fmt(v) for v in e['values']] + [''])
        rows.append(['', 'ours raw'] + [fmt(100 * v) for v in e['err_raw']]
                    + [fmt(mean_cm(e['err_raw']))])
        rows.append(['', 'ours refined'] + [fmt(100 * v) for v in e['err_refined']]
                    + [fmt(mean_cm(e['err_refined']))])
        rows.append(['', 'paper'] + [fmt(v) for v in paper]
                    + [fmt(None if paper[0] is None else np.mean(paper))])
    lines += table(['element', ''] + [f'{k + 1}' for k in range(6)] + ['avg'], rows)
    ours = float(np.mean([mean_cm(e['err_raw']) for e in sw['elements']]))
    lines += ['', '- ' + verdict(ours, float(np.mean(ev.PAPER['sweep_cm'])), 'cm',
                                 'raw error over the sweep'), '',
              f'![element sweep]({run.figures["element_sweep"]})', '']
    return lines


def orientation_section(run: Run) -> List[str]:
    """Experiment 5."""
    o = run.results['orientation']
    lines = ['## 5. Orientation as goal', '']
    if o is None:
        return lines + ['Not run: the bundle has no pose model.', '']
    paper = ev.PAPER['orientation']
    lines += ['Four reachable poses (tips of seeded uniform joint samples); for each, five '
              'posture indices of the pose model (1-d) at the 0, 25, 50, 75 and 100 % '
              'quantiles of the table indices near the target position, decoded (raw) and '
              'refined. Cosine similarity of orientation: the mean over the three axes of the '
              'tip frame of the cosine between the target axis and the reached one, '
              '(1 + 2 cos θ) / 3 for a rotation error θ. (The paper does not define its cosine; '
              'its 0.9983 read as cos θ of one axis is the "about 3 degrees" it states, read as '
              'our mean over axes it is 4.1°.)', '']
    rows = []
    for i, t in enumerate(o['targets']):
        pos = '(' + ', '.join(f'{v:.3f}' for v in t['position']) + ')'
        rows.append([LETTERS[i], pos, fmt(mean_cm(t['err_raw'])), fmt(np.mean(t['cos_raw']), 4),
                     fmt(np.degrees(np.mean(t['angle_raw'])), 1), fmt(mean_cm(t['err_refined'])),
                     fmt(np.mean(t['cos_refined']), 4),
                     fmt(np.degrees(np.mean(t['angle_refined'])), 1)])
    rows.append(['mean', '', fmt(100 * o['err_raw']), fmt(o['cos_raw'], 4),
                 fmt(np.degrees(o['angle_raw']), 1), fmt(100 * o['err_refined']),
                 fmt(o['cos_refined'], 4), fmt(np.degrees(o['angle_refined']), 1)])
    rows.append(['paper', '', fmt(paper['distance_cm']), fmt(paper['cosine'], 4), '≈3', '—',
                 '—', '—'])
    lines += table(['target', 'position [m]', 'raw error [cm]', 'raw cosine', 'raw angle [°]',
                    'refined error [cm]', 'refined cosine', 'refined angle [°]'], rows)
    lines += ['', '- ' + verdict(100 * o['err_raw'], paper['distance_cm'], 'cm',
                                 'raw distance error with orientation held'),
              '- ' + verdict(1 - o['cos_raw'], 1 - paper['cosine'], '', 'raw orientation, as '
                             '1 − cosine similarity', 4), '']
    if 'orientation' in run.figures:
        lines += [f'![orientation]({run.figures["orientation"]})', '']
    return lines


def obstacle_section(run: Run) -> List[str]:
    """Experiment 6."""
    ob = run.results['obstacle']
    lines = ['## 6. Obstacle avoidance (Algorithm 2)', '']
    if ob is None:
        return lines + ['Not run: the bundle has no position model.', '']
    if ob.get('goal') is None:
        return lines + [f'Not run: {ob["reason"]}.', '']
    b = ob['box']
    goal = ', '.join(f'{v:g}' for v in ob['goal'])
    how = ('found by Algorithm 2 (posture-index adjustment): none of the unconstrained '
           'solutions' if ob['from_adjustment'] else 'one of the unconstrained solutions, '
           'ranked first once collisions count')
    ok = ob['converged'] and ob['clearance_chosen'] > 0
    lines += [f'Goal ({goal}) m. The first-ranked unconstrained solution is found; then a box '
              f'{" × ".join(f"{100 * v:.0f}" for v in b.dimensions)} cm (depth along the '
              'base-goal line × width × height) is stood on the table (z = 0) between the robot '
              'and the goal, facing the goal: slid from near the goal towards the base (lowest '
              'height first) until that posture hits it, with the goal at least 5 cm outside '
              f'(the posture\'s clearance: {100 * ob["clearance_first"]:+.1f} cm; '
              f'{ob["unconstrained_colliding"]} of the {ob["unconstrained_total"]} distinct '
              'unconstrained solutions hit it). We check the goal posture only: no motion is '
              'planned from a start point, unlike the paper\'s demonstration. '
              '`solve(goal, obstacles=[box])` ranks collision-free exact solutions first and runs '
              'Algorithm 2 (posture-index adjustment) when none of its candidates is free. '
              'Clearances are signed distances between the robot\'s collision geometry and the '
              'box (negative: penetration).', '',
              f'- Chosen solution: clearance {100 * ob["clearance_chosen"]:+.1f} cm, distance '
              f'error {1000 * ob["error_chosen"]:.3f} mm, '
              f'{"exact" if ob["converged"] else "not within tolerance"}; {how}; '
              f'{1000 * ob["elapsed_s"]:.0f} ms.',
              '- ' + ('It clears the box where the first unconstrained solution does not.' if ok
                      else '**It does not clear the box: Algorithm 2 failed in this case.**'),
              '', f'![obstacle]({run.figures["obstacle"]})', '']
    return lines


# -- entry point ----------------------------------------------------------------------------------

def main(argv: Optional[List[str]] = None) -> int:
    """Entry point of sik-eval."""
    argv = argv_or_default(argv)
    args = build_parser().parse_args(argv)

    def body() -> int:
        if args.targets is not None and args.targets < 1:
            raise InvalidArgument(f'--targets must be at least 1; got {args.targets}')
        if args.samples is not None and args.samples < 1000:
            raise InvalidArgument(f'--samples must be at least 1000; got {args.samples}')
        if args.threads < 1:
            raise InvalidArgument(f'--threads must be at least 1; got {args.threads}')
        for flag, folder in (('--baselines', args.baselines),
                             ('--latent-study', args.latent_study)):
            if folder is not None and not Path(folder).is_dir():
                raise InvalidArgument(f'{flag} {folder}: not a directory')
        torch.set_num_threads(args.threads)
        start = datetime.datetime.now()
        run = Run(args)
        ik = SelectiveIK.load(args.bundle)
        if 'position' not in ik.goals:
            raise InvalidArgument(f'bundle {ik.bundle} has no position model; the experiments '
                                  'need one')
        baselines, missing = ev.load_baselines(args.baselines, ik.robot)
        run.out.mkdir(parents=True, exist_ok=True)
        run.results['machine'] = ev.machine_info()
        with tqdm(total=1, disable=args.quiet, mininterval=1.0, file=sys.stderr) as bar:
            run_experiments(run, ik, baselines, bar)
        run.results['date'] = start.strftime('%Y-%m-%d %H:%M')
        run.results['elapsed_s'] = (datetime.datetime.now() - start).total_seconds()
        write_text_atomic(run.out / 'results.md', report(run, ik, baselines, missing, argv))
        write_text_atomic(run.out / 'results.json', json.dumps(to_jsonable(
            summary(run, baselines)), indent=1) + '\n')
        print(f'wrote {run.out / "results.md"}, {run.out / "results.json"} and '
              f'{len(run.figures)} figures in {run.fig_dir}')
        return 0
    return run_cli('sik-eval', body)


def summary(run: Run, baselines: Dict) -> Dict:
    """The machine-readable results: settings, targets and per-target errors [m]."""
    res = run.results
    d = res['distance']
    return {
        'machine': res['machine'], 'date': res['date'], 'quick': run.quick,
        'targets_per_radius': run.n_targets, 'samples': run.samples,
        'workspace': {'targets': res['workspace_targets'], 'errors_m': d['workspace']},
        'radius': {str(r): {'targets': res['spheres'][r]['positions'],
                            'available': res['spheres'][r]['available'],
                            'errors_m': {m: {v: per[i] for v, per in variants.items()}
                                         for m, variants in d['radius'].items()}}
                   for i, r in enumerate(run.radii)},
        'timing_ms': res['timing'],
        'diversity': {m: [{k: r[k] for k in ('position', 'err_raw', 'err_refined', 'var_raw',
                                             'var_refined')} for r in recs]
                      for m, recs in res['diversity'].items()},
        'sweep': {'median': res['sweep']['median'],
                  'elements': [{k: e[k] for k in ('values', 'err_raw', 'err_refined')}
                               for e in res['sweep']['elements']]},
        'orientation': None if res['orientation'] is None else {
            k: v for k, v in res['orientation'].items() if k != 'targets'},
        'obstacle': None if res['obstacle'] is None else {
            k: v for k, v in res['obstacle'].items() if not k.startswith('q_')},
        'latent': None if res['latent'] is None else [
            {k: v for k, v in r.items() if k != 'history'} for r in res['latent']],
        'figures': run.figures,
    }


if __name__ == '__main__':
    raise SystemExit(main())
