"""Write the benchmark tables of docs/benchmarks.md and the README from docs/results/*.json.

Each benchmark script's ``--json`` file holds its figures, command, date, commit and machine
(``bench/report.py``). This script replaces the text between the markers
``<!-- begin: NAME -->`` and ``<!-- end: NAME -->`` with the table of benchmark ``NAME``
(files ``docs/results/NAME.json`` and ``docs/results/NAME-*.json``), each followed by the
command that regenerates it and where and when it was measured. The README's marker ``summary``
gets one table of today's figures beside the peers, drawn from several benchmarks.

    python bench/render.py           # rewrite the tables
    python bench/render.py --check   # exit 1 when a table differs from its JSON
"""

import argparse
import json
import math
from pathlib import Path
import re
import sys
from typing import Callable, Dict, List, Optional

REPO = Path(__file__).resolve().parents[1]
RESULTS = REPO / 'docs' / 'results'
DOCS = (REPO / 'docs' / 'benchmarks.md', REPO / 'README.md')
BLOCK = re.compile(r'(<!-- begin: ([\w-]+) -->\n)(.*?)(<!-- end: \2 -->)', re.S)
NA = '—'


# formatting ---------------------------------------------------------------------------------

def num(value: Optional[float], digits: int = 2, unit: str = '') -> str:
    """A number with ``digits`` decimals and a unit, or a dash when missing."""
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return NA
    return f'{value:,.{digits}f}{unit}'


def pct(fraction: Optional[float], digits: int = 1) -> str:
    """A fraction as a percentage."""
    return NA if fraction is None else f'{100 * fraction:.{digits}f} %'


def cm(metres: Optional[float], digits: int = 2) -> str:
    """Metres shown in centimetres."""
    return NA if metres is None else f'{100 * metres:.{digits}f} cm'


def deg(radians: Optional[float]) -> str:
    """Radians shown in degrees."""
    return NA if radians is None else f'{math.degrees(radians):.1f}°'


def table(header: List[str], rows: List[List[str]]) -> str:
    """A Markdown table."""
    lines = ['| ' + ' | '.join(header) + ' |', '|' + '---|' * len(header)]
    lines += ['| ' + ' | '.join(str(c) for c in row) + ' |' for row in rows]
    return '\n'.join(lines)


def load_note(data: dict) -> str:
    """The 1-minute load average at a benchmark's start and end, or nothing when unknown.

    Above the machine's cores, the note says so: every time is then inflated, and the peers
    (TRAC-IK's budget is wall time; DLS runs longer per call than ours) lose more than we do.
    """
    avg = data['machine'].get('load_average') or {}
    if avg.get('start') is None or avg.get('end') is None:
        return ''
    note = f'load average {avg["start"]:.1f} at the start, {avg["end"]:.1f} at the end'
    if max(avg['start'], avg['end']) > data['machine']['cores']:
        note += (': **a busy machine**, times inflated and ratios to the peers not comparable '
                 'with a quiet run\'s')
    return note


def machine(data: dict, with_load: bool = True) -> str:
    """The machine of a result file, in one phrase."""
    m = data['machine']
    libs = m.get('libraries', {})
    parts = [f'Python {m["python"]}'] + [f'{name} {libs[key]}' for key, name in (
        ('numpy', 'NumPy'), ('torch', 'torch'), ('pin', 'Pinocchio'), ('numba', 'numba'))
        if key in libs]
    busy = f' ({load_note(data)})' if with_load and load_note(data) else ''
    return (f'{m["cpu"]}, {m["cores"]} cores, {m["memory_gb"]:.0f} GB{busy}, {m["os"]}; '
            + ', '.join(parts))


def provenance(data: dict) -> str:
    """How to regenerate a result, and when, at which commit and where it was measured."""
    dirty = ' with uncommitted changes' if data.get('dirty') else ''
    return (f'`{data["command"]}`  \n'
            f'Measured {data["date"][:10]} at commit `{data["commit"]}`{dirty} on '
            f'{machine(data)}. Raw output: `docs/results/{data["file"]}.txt`.')


# one renderer per benchmark -----------------------------------------------------------------

def render_collect(data: dict) -> str:
    """bench/collect.py: wall time and peak memory of sik-collect."""
    r = data['results']
    rows = [[str(i), num(run['wall_s'], 1), num(run['peak_rss_mb'], 0)]
            for i, run in enumerate(r['runs'], 1)]
    rows.append(['**median**', f'**{num(r["wall_median_s"], 1)}**',
                 f'**{num(r["peak_rss_median_mb"], 0)}**'])
    return (f'The Panda at {r["interval_deg"]:g}° ({r["rows"]:,} rows), each run a fresh '
            f'process:\n\n' + table(['run', 'wall [s]', 'peak RSS [MB]'], rows))


def _peer(goal: dict, name: str) -> Optional[dict]:
    return next((p for p in goal.get('peers', []) if p['name'].startswith(name)), None)


def render_solve(data: dict) -> str:
    """bench/solve.py: the Panda's multi-solution solves beside the peers."""
    r = data['results']
    pos, pose = r.get('position', {}), r.get('pose', {})
    dls, trac_ref = _peer(pos, 'DLS'), _peer(pos, 'TRAC-IK')
    trac = _peer(pose, 'TRAC-IK')

    def peer_cells(p: Optional[dict]) -> List[str]:
        if p is None:
            return [NA, NA]
        return [f'{num(p["time_median_ms"])} ms (reached it on {pct(p["reached"])})',
                f'**{num(p["ratio_median"], 3)}** (p90 {num(p["ratio_p90"], 3)}; where '
                f'reached {num(p["ratio_median_reached"], 3)})']

    def both(key: Callable[[dict], str]) -> List[str]:
        return [key(pos) if pos else NA, key(pose) if pose else NA]

    dp, tp = peer_cells(dls), peer_cells(trac)
    rows = [
        ['targets'] + both(lambda g: f'{g["targets"]:,}'),
        ['success (at least one exact solution)'] + both(lambda g: pct(g['success'])),
        ['distinct exact solutions per call, median (p10), of 16'] + both(
            lambda g: f'{g["distinct_median"]:.0f} ({g["distinct_p10"]:.0f})'),
        ['time per call, median / p95'] + both(
            lambda g: f'{num(g["time_median_ms"])} / {num(g["time_p95_ms"])} ms'),
        ['peer', 'DLS on Pinocchio Jacobians', 'TRAC-IK'],
        ['peer: time to as many distinct solutions from random seeds, median', dp[0], tp[0]],
        ['ratio ours / peer, median of the per-target ratios', dp[1], tp[1]],
    ]
    if trac_ref:
        rows.append(['reference: TRAC-IK on the full pose, time to as many, median',
                     f'{num(trac_ref["time_median_ms"])} ms, ratio '
                     f'{num(trac_ref["ratio_median"], 3)}', NA])
    rows += [
        ['raw (`refine=False`): mean error of the 10 returned solutions (the best-ranked)',
         f'{cm(pos.get("raw_mean_m"))} ({cm(pos.get("raw_best_m"))})' if pos else NA,
         f'{cm(pose.get("raw_mean_m"))}, {deg(pose.get("raw_orientation_mean_rad"))} '
         f'({cm(pose.get("raw_best_m"))})' if pose else NA],
        ['raw: every candidate of a refined call decoded at the goal, no selection',
         cm(pos.get('candidates_mean_m')) if pos else NA,
         f'{cm(pose.get("candidates_mean_m"))}, '
         f'{deg(pose.get("candidates_orientation_mean_rad"))}' if pose else NA],
        ["where refinement starts: the table's decoded postures (position) and the oriented "
         'postures (pose), no selection',
         cm(pos.get('cached_postures_mean_m')) if pos else NA,
         f'{cm(pose.get("oriented_mean_m"))}, {deg(pose.get("oriented_orientation_mean_rad"))}'
         if pose and pose.get('oriented_mean_m') is not None else NA],
    ]
    out = (f'{r["targets"]:,} targets uniform in joint space (seed {r["seed"]}), bundle '
           f'`{r["bundle"]}`, 16 solutions asked; peers called from random seeds until they '
           f'have as many distinct exact solutions as ours (at most {r["max_attempts"]} '
           f'attempts).\n\n' + table(['', 'position goals', 'pose goals'], rows))
    single = r.get('single')
    if single:
        t, ratio, ok = single['time_median_ms'], single['ratio_median'], single['success']
        out += ('\n\nA single pose solution (`num_solutions=1`), the three calls in turn per '
                'target, TRAC-IK from a random seed:\n\n' + table(
                    ['', 'time per call (median)', 'ratio to TRAC-IK (median)', 'success'],
                    [['ours', f'{num(t["ours"], 3)} ms', num(ratio['ours']), pct(ok['ours'])],
                     ['ours, seeded', f'{num(t["ours seeded"], 3)} ms',
                      num(ratio['ours seeded']), pct(ok['ours seeded'])],
                     ['TRAC-IK', f'{num(t["trac-ik"], 3)} ms', '1', pct(ok['trac-ik'])]]))
    obs = r.get('obstacle')
    if obs:
        out += (f'\n\nObstacle case: target {obs["target"]}, a '
                f'{" × ".join(f"{100 * s:.0f}" for s in obs["box_size"])} cm box at the '
                f"elbow of the best unconstrained solution (clearance "
                f'{obs["clearance_unconstrained_m"]:+.3f} m). With the box given: '
                f'{obs["solutions"]} solutions, {obs["exact_free"]} exact and collision-free, '
                f'the best {100 * obs["clearance_m"]:.1f} cm clear with '
                f'{1e3 * obs["error_m"]:.3f} mm error, in {obs["time_ms"]:.1f} ms.')
    return out


def render_ab(data: dict) -> str:
    """bench/solve_ab.py: a paired A/B between checkouts."""
    r = data['results']
    first = r['checkouts'][0]['name']
    rows = [[f'{c["name"]} (peer)' if 'commit' not in c else
             f'{c["name"]} (`{c["commit"]}`{", changed" if c["dirty"] else ""})',
             pct(c['success']), num(c['distinct_mean']), num(c['branches_mean']),
             f'{num(c["time_median_ms"])} ms', f'**{num(c["ratio_median"], 3)}**']
            for c in r['checkouts']]
    busy = f', {r["busy_ms"]:g} ms of other work before each call' if r['busy_ms'] else ''
    return (f'{r["targets"]} {r["goal"]} targets of `{r["bundle"]}` (seed {r["seed"]}), '
            f'{r["num"]} solutions{", seeded" if r["seeded"] else ""}{busy}; A B A B:\n\n'
            + table(['checkout', 'success', 'distinct (mean)', 'branches (mean)',
                     'time per call (median)', f'ratio to {first} (median)'], rows))


def render_arms(data: dict) -> str:
    """bench/arms.py: sik-build bundles of several arms beside the peers."""
    r = data['results']
    rows = []
    for a in r['arms']:
        for goal, peer in (('position', 'DLS'), ('pose', 'TRAC-IK')):
            f = a[goal]
            br = NA
            if f.get('branches_mean') is not None:
                br = (f'{num(f["branches_mean"])} / {num(f["peer_branches_mean"])}; '
                      f'{num(f["free_branches_mean"])} / {num(f["peer_free_branches_mean"])}; '
                      f'{pct(f["free_branches_at_least_peer"], 0)}')
            rows.append([a['arm'], str(a['dof']), num(a['bundle_mb'], 1), goal,
                         pct(f['success']),
                         f'{f["distinct_median"]:.0f} ({f["distinct_p10"]:.0f})',
                         f'{num(f["time_median_ms"])} ms',
                         f'**{num(f["ratio_median"], 3)}** {peer} ({pct(f["peer_reached"], 0)})',
                         br])
    trained = []
    for a in r['arms']:
        t = a.get('training') or {}
        if t:
            trained.append(f'{a["arm"]}: ' + ', '.join(
                f'{goal} model {m["steps"]:,} steps in {m["train_s"] / 60:.0f} min, validation '
                f'{cm(m["val_dist_m"], 1)}' for goal, m in sorted(t.items())))
    note = ('\n\nThe models (steps of training, validation distance error decoded from the true '
            'index): ' + '; '.join(trained) + '.') if trained else ''
    return (f'{r["targets"]} targets uniform in joint space per goal kind (seed {r["seed"]}); '
            f'peers from random seeds until as many distinct solutions as ours (at most '
            f'{r["max_attempts"]} attempts).\n\n' + table(
                ['arm', 'joints', 'bundle [MB]', 'goal', 'success', 'distinct median (p10)',
                 'time/call', 'ratio ours / peer (peer reached)',
                 'branches ours / TRAC-IK (mean; free of self-collision; ours ≥ peer)'], rows)
            + note)


def render_paths(data: dict) -> str:
    """bench/paths.py: Cartesian paths beside seeded peers."""
    r = data['results']
    rows = [[g['goal'], '≥ 30 cm' if g['long'] else '< 30 cm', str(g['paths']),
             pct(g['success']), g['peer'], pct(g['peer_success']),
             f'{num(g["time_median_ms"], 1)} / {num(g["peer_time_median_ms"], 1)} ms',
             f'**{num(g["ratio_median"])}**', num(g['ratio_total']),
             f'{num(g["travel_median_rad"])} / {num(g["peer_travel_median_rad"])} rad']
            for g in r['groups']]
    overall = '; '.join(f'{o["goal"]} paths {pct(o["success"])} against '
                        f'{pct(o["peer_success"])}' for o in r['overall'])
    obs = r['obstacle']
    return (f'{r["paths"]} Panda paths (seed {r["seed"]}): lines and arcs of 10-60 cm, 20-60 '
            f'waypoints, every other one with the tool orientation held; each from a random '
            f'current state; success: every waypoint exact and no joint step above '
            f'{r["step_rad"]} rad.\n\n' + table(
                ['paths', 'length', 'n', 'ours', 'peer', 'peer', 'time ours / peer (median)',
                 'ratio (median)', 'ratio of the totals',
                 'travel ours / peer where both succeed (median)'], rows)
            + f'\n\nOverall: {overall}. Obstacle case: a {100 * obs["box_size"]:.0f} cm box at '
            f'the elbow of the best unconstrained path (clearance '
            f'{obs["clearance_unconstrained_m"]:+.3f} m); with it: '
            f'{"success" if obs["success"] else "no path"}, clearance '
            f'{num(obs["clearance_m"], 3)} m, {obs["time_ms"]:.0f} ms.')


def render_paths_ab(data: dict) -> str:
    """bench/paths_ab.py: a paired A/B of solve_path between checkouts."""
    r = data['results']
    first = r['checkouts'][0]['name']
    rows = [[f'{c["name"]} (`{c["commit"]}`)', c['goal'], str(c['paths']), pct(c['success']),
             f'{num(c["time_median_ms"], 1)} ms', f'**{num(c["ratio_median"], 3)}**',
             f'{num(c["travel_median_rad"], 3)} rad', num(c['travel_ratio_mean'], 3),
             f'{num(c["max_step_median_rad"], 3)} rad'] for c in r['checkouts']]
    return (f'{r["paths"]} paths of `{r["bundle"]}` (seed {r["seed"]}), A B A B:\n\n'
            + table(['checkout', 'goal', 'paths', 'success', 'time per path (median)',
                     f'ratio to {first} (median)', 'travel (median)',
                     f'travel path by path to {first} (mean ratio)', 'max step (median)'],
                    rows))


def render_service(files: List[dict]) -> str:
    """bench/service.py: the node over loopback DDS, one column per run."""
    def p(d: Optional[dict]) -> str:
        if not d:
            return NA
        if 'p90_ms' not in d:  # a run from before p90 was recorded
            return f'{num(d["p50_ms"])} / {NA} / {num(d["p99_ms"])} ms'
        return f'{num(d["p50_ms"])} / {num(d["p90_ms"])} / {num(d["p99_ms"])} ms'

    def ratio(r: dict) -> str:
        x = r.get('ratio')
        return NA if not x else f'**{num(x["p50"])}** / {num(x["p90"])}'

    def message_ratio(r: dict) -> str:
        x = r.get('message_ratio')
        return NA if not x else f'{num(x["p50"])} / {num(x["p90"])}'

    def rate(r: dict, clients: int) -> str:
        cells = r.get('throughput', {}).get(str(clients))
        if cells:
            return ' / '.join(NA if key not in cells else f'{cells[key]:.0f}'
                              for key in ('sik', 'message', 'floor')) + ' requests/s'
        if clients == r['clients']:  # a run from before the empty service was measured
            return f'{r["throughput_rps"]:.0f} / {NA} requests/s'
        return NA

    def cpu(r: dict, clients: int) -> str:
        cells = r.get('cpu_ms_per_answer', {}).get(str(clients))
        if not cells:
            return NA
        return ' / '.join(f'{num(cells[key]["server"])} + {num(cells[key]["client"])}'
                          for key in ('sik', 'message', 'floor')) + ' ms'

    cols = []
    for data in files:
        r = data['results']
        procs = [x.split(':=')[1] for x in r['params'] if x.startswith('solver_processes')]
        cols.append((f'{r["goals"]} goals' + (f', `solver_processes: {procs[0]}`'
                                              if procs else ''), r))
    many = max(r['clients'] for _, r in cols)
    spec = [('sequential requests', lambda r: f'{r["requests"]:,}'),
            ('round trip p50 / p90 / p99', lambda r: p(r['round_trip'])),
            ('… of position goals', lambda r: p(r.get('round_trip_position'))),
            ('… of pose goals', lambda r: p(r.get('round_trip_pose'))),
            ('empty service round trip p50 / p90 / p99 (same run, A B A B)',
             lambda r: p(r.get('floor_round_trip'))),
            ('round trip ÷ empty service, p50 / p90', ratio),
            ('16-solution answer without a solve (message service, same run) p50 / p90 / p99',
             lambda r: p(r.get('message_round_trip'))),
            ('… ÷ empty service, p50 / p90', message_ratio),
            ('solver in the node p50 / p90 / p99', lambda r: p(r['solver_in_node'])),
            ('ROS overhead (round trip − solver) p50 / p90 / p99', lambda r: p(r['overhead'])),
            ('solver alone in the benchmark process p50 / p90 / p99',
             lambda r: p(r['solver_alone'])),
            ('throughput, 1 client: node / message / empty service', lambda r: rate(r, 1)),
            (f'throughput, {many} clients: node / message / empty service',
             lambda r: rate(r, many)),
            (f'processor time per answer, {many} clients, server + clients: node / message / '
             'empty service', lambda r: cpu(r, many)),
            ('node RSS growth (requests)',
             lambda r: f'{r["rss_growth_mb"]:+.1f} MB ({r["requests_total"]:,})'),
            ('SUCCESS answers', lambda r: pct(r['success']))]
    rows = [[name] + [fn(r) for _, r in cols] for name, fn in spec]
    return ('16 ranked refined solutions per request, goals at FK of random configurations, '
            'sequential round trips from a background-spun `SolveIKClient`, each followed by '
            'a call of the empty service and of the message service, then concurrent clients '
            '(phases of the node and of the two floors in turn):\n\n'
            + table([''] + [c for c, _ in cols], rows))


def render_service_probe(data: dict) -> str:
    """bench/service_probe.py: three client loops against one node."""
    r = data['results']
    names = {'spin_call': '`rclpy.spin_until_future_complete(node, future)`',
             'executor loop': '`executor.spin_until_future_complete(future)`',
             'SolveIKClient': '`SolveIKClient` (executor spun in a background thread)'}
    rows = [[names.get(x['loop'], x['loop']),
             f'{num(x["round_trip_p50_ms"])} / {num(x["round_trip_p99_ms"])} ms',
             f'{num(x["solver_p50_ms"])} ms', f'{num(x["overhead_p50_ms"])} ms',
             f'{num(x["client_cpu_ms"])} ms'] for x in r['loops']]
    return (f'{r["requests"]} position goals per loop, one node:\n\n'
            + table(['client loop', 'round trip p50 / p99', 'solver p50', 'overhead p50',
                     'client CPU per request'], rows))


#: SolveIK's error codes by value (sik_interfaces/srv/SolveIK.srv).
CODES = {'1': 'SUCCESS', '-1': 'NO_SOLUTION', '-2': 'INVALID_GOAL', '-3': 'INVALID_FRAME',
         '-4': 'INVALID_SEED', '-5': 'TIMEOUT', '-6': 'ROBOT_MISMATCH', '-99': 'INTERNAL_ERROR'}


def render_soak(data: dict) -> str:
    """bench/soak.py: many clients, mixed requests and parameter churn."""
    r = data['results']
    rows = [[str(i), f'{x["answered"]:,}', str(x['lost']),
             ', '.join(f'{CODES.get(k, k)} {v:,}' for k, v in
                       sorted(x['codes'].items(), key=lambda kv: -kv[1])),
             f'{x["rate_rps"]:.0f}', f'{num(x["p50_ms"], 1)} / {num(x["p99_ms"], 1)} / '
             f'{num(x["max_ms"], 0)} ms', f'{x["rss_growth_mb"]:+.1f} MB',
             f'{x["rss_growth_connected_mb"]:+.1f} MB'] for i, x in enumerate(r['rounds'], 1)]
    return (f'{r["requests"]:,} requests from {r["clients"]} clients (each its own DDS '
            f'participant), position and pose goals, 20 % with obstacles, 30 % seeded, a '
            f'`position_tolerance` change every {r["churn"]} requests, request timeout '
            f'{r["timeout_s"]} s, `solver_processes: {r["processes"]}`; node RSS '
            f'{r["rss_start_mb"]:.0f} MB after its warm-up:\n\n'
            + table(['round', 'answered', 'lost', 'codes', 'requests/s',
                     'round trip p50 / p99 / max', 'RSS growth since the warm-up',
                     'since every client was connected'], rows))


def render_sweep(data: dict) -> str:
    """bench/sweep.py: tiny sik-builds of example-robot-data arms."""
    r = data['results']
    rows = []
    for a in r['arms']:
        if 'error' in a:
            rows.append([a['arm'], f'failed: {a["error"][:120]}'] + [''] * 7)
            continue
        c = a['check']
        rows.append([a['arm'], f'{a["dof"]} ({a["periodic"]})', f'{a["base"]} → {a["tip"]}',
                     num(a['build_s'], 0), num(a['bundle_mb'], 1),
                     f'{pct(c["position"]["success"], 0)}, '
                     f'{c["position"]["distinct_median"]:.0f}',
                     f'{pct(c["pose"]["success"], 0)}, {c["pose"]["distinct_median"]:.0f}',
                     (f'{num(a["ours_mean"])} / {num(a["peer_mean"])}' if 'ours_mean' in a
                      else NA),
                     pct(a['at_least_peer'], 0) if 'at_least_peer' in a else NA])
    return (f'`sik-build --time {r["time_s"]:g} --rows {r["rows"]:,} --preset tiny` per arm; '
            f'self-check on {r["targets"]} targets per goal kind; pose branches (distinct '
            f'solutions with every angle wrapped to one turn) of ours against TRAC-IK from '
            f'{r["attempts"]} random seeds, on {r["targets"]} targets (arms of six joints or '
            f'fewer):\n\n' + table(
                ['arm', 'joints (periodic)', 'base → tip (inferred)', 'build [s]',
                 'bundle [MB]', 'self-check position: success, distinct median',
                 'pose: success, distinct median', 'pose branches ours / TRAC-IK (mean)',
                 'ours ≥ TRAC-IK'], rows))


def render_train_step(data: dict) -> str:
    """bench/train_step.py: training throughput."""
    r = data['results']
    rows = [[str(x['batch']), str(x['threads']), f'{x["float32"]:,.0f}',
             f'{x["bfloat16"]:,.0f}'] for x in r['rows']]
    return (f'One training step (data, forward, backward, Adam), `{r["preset"]}` preset '
            f'(encoder {r["encoder"]}, decoder {r["decoder"]}), {r["goal"]} goals, samples/s:'
            f'\n\n' + table(['batch', 'threads', 'float32', 'bfloat16 autocast'], rows))


def render_tracik_protocol(data: dict) -> str:
    """bench/tracik_protocol.py: one pose solution from the mid-limits seed, 5 ms budget."""
    r = data['results']
    rows = [[name, pct(r[name]['success']), num(r[name]['mean_ms']), num(r[name]['median_ms']),
             num(r[name]['p99_ms'])] for name in ('sik_ros', 'TRAC-IK')]
    return (table(['solver', 'success', 'mean [ms]', 'median [ms]', 'p99 [ms]'], rows)
            + f'\n\nMean time ratio sik_ros / TRAC-IK: **{num(r["mean_ratio"])}**.')


# the README's one table ---------------------------------------------------------------------

def render_ablation(data: dict) -> str:
    """bench/ablation.py: the solver's starts from one source at a time, per arm and goal."""
    r = data['results']
    rows = []
    for arm, goals in r['arms'].items():
        for goal, sources in goals.items():
            for source, f in sources.items():
                rows.append([arm, goal, source, pct(f['success']),
                             f'{num(f["distinct_mean"], 1)}', num(f['branches_mean'], 1),
                             f'{num(f["ms_median"])} ({num(f["ms_mean"])})'])
    a = r['args']
    return (f'{a["targets"]} targets uniform in joint space per arm and goal kind (seed '
            f'{a["seed"]}), {a["starts"]} starts from each source, {a["num"]} solutions asked:'
            f'\n\n' + table(['arm', 'goal', 'starts from', 'success', 'distinct (mean)',
                             'branches (mean)', 'ms per call, median (mean)'], rows))


def render_summary(results: Dict[str, List[dict]]) -> Optional[str]:
    """Today's headline figures beside the peers, from several benchmarks (None without)."""
    rows, sources = [], []
    solve = results.get('solve', [None])[0]
    if solve:
        r = solve['results']
        pos, pose = r['position'], r['pose']
        dls, trac = _peer(pos, 'DLS'), _peer(pose, 'TRAC-IK')
        n = f'{r["targets"]:,} targets'
        rows += [
            [f'Panda, position goals ({n}): success; distinct exact of 16, median (p10)',
             f'{pct(pos["success"])}; {pos["distinct_median"]:.0f} ({pos["distinct_p10"]:.0f})',
             NA, NA],
            ['Panda, position goals: time per call (16 solutions) / peer to as many',
             f'{num(pos["time_median_ms"])} ms', f'DLS {num(dls["time_median_ms"])} ms',
             f'**{num(dls["ratio_median"], 3)}**'],
            [f'Panda, pose goals ({n}): success; distinct exact of 16, median (p10)',
             f'{pct(pose["success"])}; {pose["distinct_median"]:.0f} '
             f'({pose["distinct_p10"]:.0f})', NA, NA],
            ['Panda, pose goals: time per call (16 solutions) / peer to as many',
             f'{num(pose["time_median_ms"])} ms', f'TRAC-IK {num(trac["time_median_ms"])} ms',
             f'**{num(trac["ratio_median"], 3)}**'],
        ]
        if r.get('single'):
            s = r['single']
            rows.append(['Panda, one pose solution (`num_solutions=1`)',
                         f'{num(s["time_median_ms"]["ours"])} ms',
                         f'TRAC-IK {num(s["time_median_ms"]["trac-ik"])} ms',
                         num(s['ratio_median']['ours'])])
        rows.append(['Panda, raw (`refine=False`): 10 best of up to 192 decoded table indices '
                     'ranked by FK error (pose: their indices adjusted by Algorithm 2), mean '
                     'error (position; pose)',
                     f'{cm(pos["raw_mean_m"])}; {cm(pose["raw_mean_m"])}, '
                     f'{deg(pose["raw_orientation_mean_rad"])}', NA, NA])
        sources.append(solve)
    arms = results.get('arms', [None])[0]
    if arms:
        for a in arms['results']['arms']:
            if a['arm'] == 'panda':
                continue
            f, g = a['pose'], a['position']
            rows.append([f'{a["arm"]} ({a["dof"]} joints, {arms["results"]["targets"]} targets): '
                         f'pose / position goals, time per call',
                         f'{num(f["time_median_ms"])} / {num(g["time_median_ms"])} ms',
                         'TRAC-IK / DLS to as many',
                         f'**{num(f["ratio_median"], 3)}** / **{num(g["ratio_median"], 3)}**'])
        sources.append(arms)
    paths = results.get('paths', [None])[0]
    if paths:
        for o in paths['results']['overall']:
            sel = [g for g in paths['results']['groups'] if g['goal'] == o['goal']]
            ratios = [g['ratio_median'] for g in sel]
            peer = sel[0]['peer'] if sel else ''
            rows.append([f'Panda {o["goal"]} paths ({o["paths"]}): whole-path success; time '
                         f'per path',
                         pct(o['success']), f'{peer} {pct(o["peer_success"])}',
                         f'{num(min(ratios))}-{num(max(ratios))}'])
        sources.append(paths)
    protocol = results.get('tracik_protocol', [None])[0]
    if protocol:
        r = protocol['results']
        ours, peer = r['sik_ros'], r['TRAC-IK']
        rows.append(['Panda, TRAC-IK\'s protocol (random reachable poses, mid-limits seed, 5 ms): '
                     'success; mean time', f'{pct(ours["success"])}; {num(ours["mean_ms"])} ms',
                     f'TRAC-IK {pct(peer["success"])}; {num(peer["mean_ms"])} ms',
                     f'**{num(r["mean_ratio"])}**'])
        sources.append(protocol)
    service = next((d for d in results.get('service', []) if d['file'] == 'service'), None)
    if service:
        s = service['results']
        floor = s.get('floor_round_trip')
        rows.append([f'`sik_node` over ROS 2, {s["goals"]} goals: round trip p50 / p99; '
                     f'throughput with {s["clients"]} clients',
                     f'{num(s["round_trip"]["p50_ms"])} / {num(s["round_trip"]["p99_ms"])} ms; '
                     f'{s["throughput_rps"]:.0f} requests/s',
                     NA if not floor else f'empty rclpy service {num(floor["p50_ms"])} / '
                     f'{num(floor["p99_ms"])} ms; '
                     f'{s["throughput"][str(s["clients"])]["floor"]:.0f} requests/s',
                     NA if not floor else f'**{num(s["ratio"]["p50"])}** (p50)'])
        sources.append(service)
    first = results.get('first_answer', [None])[0]
    if first:
        arms = first['results']['arms']
        exact = [a['first_exact_s'] for a in arms if a.get('first_exact_s') is not None]
        again = [a['restart_exact_s'] for a in arms if a.get('restart_exact_s') is not None]
        pose = [a['table']['pose']['success'] for a in arms if a.get('table')]
        loaded = [a['table_restart_exact_s'] for a in arms
                  if a.get('table_restart_exact_s') is not None]
        if exact and again and pose:
            cached = f'{num(min(loaded), 1)}-{num(max(loaded), 1)} s (table cached); ' \
                if loaded else ''
            rows.append([f'Any arm from `robot_description` ({len(arms)} arms, no bundle): '
                         f'first exact answer; after a restart ('
                         + ('table cached; ' if loaded else '')
                         + 'learned model cached); pose success before the model',
                         f'{num(min(exact), 1)}-{num(max(exact), 1)} s; {cached}'
                         f'{num(min(again), 1)}-{num(max(again), 1)} s; '
                         f'{pct(min(pose))}-{pct(max(pose))}', NA, NA])
            sources.append(first)
    stream = next((d for d in results.get('stream', []) if d['file'] == 'stream'), None)
    if stream:
        rows.append(_stream_summary(stream['results']['rows']))
        sources.append(stream)
    if not sources:
        return None

    def short(d: dict) -> str:
        avg = d['machine'].get('load_average') or {}
        if avg.get('start') is None or avg.get('end') is None:
            return ''
        return f' (load average {avg["start"]:.1f} → {avg["end"]:.1f})'

    # the machines in order of first use, each with the results measured on it
    machines: Dict[str, List[dict]] = {}
    for d in sources:
        machines.setdefault(machine(d, with_load=False), []).append(d)
    where = '; '.join(
        f'on {name}: ' + '; '.join(f'`{d["command"].split()[1]}` on {d["date"][:10]} at commit '
                                   f'`{d["commit"]}`{short(d)}' for d in runs)
        for name, runs in machines.items())
    busy = [d for d in sources if 'busy machine' in load_note(d)]
    return (table(['', 'sik_ros', 'peer, same run', 'time ratio ours / peer'], rows)
            + f'\n\nMeasured {where}.'
            + (' **A busy machine** (load average above its cores): times inflated, ratios to '
               'the peers not comparable with a quiet run\'s.' if busy else '')
            + ' Each row\'s command and the full tables: '
            '[docs/benchmarks.md](docs/benchmarks.md).')


def _stream_summary(rows: List[dict]) -> List[str]:
    """The summary's row of the goal streams: pose goals at 500 and 1,000 Hz."""
    pose = {r['rate']: r for r in rows if r.get('kind') == 'pose' and 'rate' in r}
    cells = [f'{rate:,.0f} Hz {num(pose[rate]["staleness_p50"])} / '
             f'{num(pose[rate]["staleness_p99"])} ms' for rate in (500, 1000) if rate in pose]
    disorder = sum(r['out_of_order'] for r in pose.values())
    stamped = all(r['unstamped'] == 0 for r in pose.values())
    return ['`sik_node` pose goal stream on `~/goal`: newest answer p50 / p99 after its goal; '
            'order', '; '.join(cells) + f'; {disorder} out of order'
            + ('' if stamped else ' (some answers without their stamp)'), NA, NA]


def render_families(data: dict) -> str:
    """bench/families.py: posture families covered, against the reference and TRAC-IK."""
    r = data['results']
    rows = []
    p = r.get('panda')

    def labels(x: dict) -> str:
        return (f'{pct(x["label_agreement"])} ({pct(x["label_split"])} split, '
                f'{pct(x["label_merged"])} joined)')
    if p:
        d, o, ns = p['default'], p['off'], p['near_singular']
        ref = (f'frankik and a held-joint sweep over joint 7 ({d["q7_samples"]} values), '
               f'verified paths; {d["poses_with_reference"]} poses, {len(p["seeds"])} seeds')
        rows.append(['Panda (7), default (family search)', ref, num(d['known_mean'], 2),
                     f'**{pct(d["coverage"])}**',
                     f'{pct(d["all_families"], 0)} ({d["poses_all"]})',
                     f'{pct(d["peer_coverage"])} (same time)', labels(d),
                     f'{num(d["time_median_ms"])} ms ({num(p["time_ratio_median"], 2)}x)'])
        rows.append(['Panda, `family_search` off', 'the same poses, each solved both ways in '
                     'turn', num(o['known_mean'], 2), f'**{pct(o["coverage"])}**',
                     f'{pct(o["all_families"], 0)} ({o["poses_all"]})', NA, labels(o),
                     f'{num(o["time_median_ms"])} ms'])
        rows.append(['Panda, default, near-singular poses only',
                     f'{ns["default"]["poses_with_reference"]} of the poses above',
                     num(ns['default']['known_mean'], 2),
                     f'**{pct(ns["default"]["coverage"])}**',
                     f'{pct(ns["default"]["all_families"], 0)} '
                     f'({ns["default"]["poses_all"]})', NA, labels(ns['default']), NA])
    arms = r.get('arms') or ([r['arm']] if r.get('arm') else [])
    for a in arms:
        seeds = f', seeds {a["seeds"]}' if 'seeds' in a else ''
        rows.append([f'{a["arm"]} ({a["dof"]})', f'ours ∪ {a["restarts"]} TRAC-IK restarts, '
                     f'{a["poses"]} poses{seeds}', num(a['known_mean'], 2),
                     f'**{pct(a["coverage"])}**',
                     f'{pct(a["all_branches"], 0)}'
                     + (f' ({a["poses_all"]})' if 'poses_all' in a else ''), NA,
                     f'{pct(a["labels_consistent"], 0)} of poses',
                     f'{num(a["time_median_ms"])} ms'])
        rows.append([f'{a["arm"]}, free of self-collision', 'the same',
                     num(a['known_free_mean'], 2),
                     f'**{pct(a["coverage_free"])}**', pct(a['all_free_branches'], 0), NA, NA,
                     NA])
    note = ''
    for a in arms:
        if 'per_seed' not in a:
            continue
        per = ', '.join(f'{v} (seed {k})' for k, v in a['per_seed'].items())
        note += (f'\n\n{a["arm"]}: every branch on {per} of the poses counted.')
        for c in a['continuum']:
            note += (f' Set apart, a pose of seed {c["seed"]} drawn {c["sigma_min"]:.1e} from a '
                     f'singularity (the least singular value), where the exact solutions form '
                     f'a continuum: ours {c["ours"]} and TRAC-IK\'s restarts {c["known"]} '
                     f'points on it 0.1 rad apart.')
    if p:
        per_seed = '; '.join(
            f'seed {k}: {pct(v["default"]["coverage"])}, every family on '
            f'{v["default"]["poses_all"]}/{v["default"]["poses_with_reference"]} '
            f'(off: {pct(v["off"]["coverage"])}, {v["off"]["poses_all"]})'
            for k, v in p['seeds'].items())
        note += (f'\n\nPanda per seed (default, with `family_search` off in brackets): '
                 f'{per_seed}. {p["near_singular_poses"]} poses of each seed are near a '
                 f'singularity (the least singular values of 2,000 uniform draws). '
                 f'{num(d["beyond_mean"], 2)} of our 16 solutions per pose lie on no family of '
                 f'the reference; the first answers came from as many reference families as '
                 f'the answer covers on {pct(d["first_k"], 0)} of the poses; the reference took '
                 f'{num(d["sweep_median_ms"] / 1e3, 1)} s per pose.')
    x = r.get('redundant')
    if x:
        d, o = x['default'], x['off']
        note += (f'\n\n{x["arm"]} ({x["dof"]} joints, no analytic reference; {x["poses"]} '
                 f'poses, each solved both ways in turn): success {pct(d["success"])} and '
                 f'{pct(o["success"])}, exact solutions median {num(d["exact_median"], 0)} and '
                 f'{num(o["exact_median"], 0)}, families found per pose '
                 f'{num(d["families_mean"], 2)} with the search and {num(o["families_mean"], 2)} '
                 f'without, {num(d["time_median_ms"])} against {num(o["time_median_ms"])} ms a '
                 f'call ({num(x["time_ratio_median"], 2)}x, paired); the default labels against '
                 f'the curves traced within the limits: {x["label_split"]} of '
                 f'{x["label_pairs"]} pairs split, {x["label_joined"]} joined.')
    return ('16 solutions asked per pose (FK of configurations drawn within the '
            'limits); a family counts as found when one of our exact solutions lies on it.\n\n'
            + table(['arm', 'families known from', 'known (mean)', 'ours found',
                     'poses with all', 'TRAC-IK found', 'our labels agree', 'time/call'], rows)
            + note)


def render_stream(data: dict) -> str:
    """``bench/stream.py``: goal streams on the wire, and ``~/solve_ik`` during one."""
    r = data['results']
    rows, calls = [], []
    for row in r['rows']:
        if 'rate' not in row:
            calls.append(row)
            continue
        rows.append([row['kind'], f'{row["rate"]:,.0f} Hz', pct(row['answered']),
                     f'{num(row["latency_p50"])} / {num(row["latency_p99"])}',
                     f'{num(row["staleness_p50"])} / {num(row["staleness_p99"])}',
                     num(row['last_answer']), str(row['out_of_order']),
                     f'{row["stamped"]:,} / {row["answers"]:,}',
                     f'{row["timeout"]} / {row["joint_jump"]}', str(row['flips']),
                     f'{row["invalid"]} / {row["checked"]:,}',
                     f'{row["replaced_reported"]:,}', f'{row["node_cpu"]:.0f} %'])
    text = table(['goals', 'rate', 'goals answered', 'own answer p50 / p99 [ms]',
                  'newest answer staleness p50 / p99 [ms]', 'last answer after last goal [ms]',
                  'out of order', 'answers with their goal\'s stamp', 'TIMEOUT / JOINT_JUMP',
                  'posture flips', 'invalid (FK) / checked', 'replaced', 'node CPU'], rows)
    if calls:
        text += '\n\n' + table(
            ['goals', '`~/solve_ik` p50 alone [ms]', 'during a 1 kHz stream [ms]'],
            [[c['kind'], num(c['service_alone_p50']), num(c['service_during_1khz_p50'])]
             for c in calls])
    if r.get('busy'):
        text += '\n\nWith one core kept busy by another process throughout (`--busy`).'
    return text


def render_executors(data: dict) -> str:
    """``bench/executors.py``: three rclpy executors serving a slow subscription and a service."""
    r = data['results']
    rows = [[row['executor'], f'{row["idle_cpu"]:.1f} %',
             f'{num(row["service_p50"])} / {num(row["service_p99"])}',
             f'{row["stream_done"]} / {row["stream_sent"]}',
             f'{num(row["stream_delay_p50"], 1)} / {num(row["stream_delay_p99"], 1)}',
             num(row['handovers_per_goal'], 1), num(row['service_during_p50'])]
            for row in r['rows']]
    return (table(['executor', 'idle CPU', 'service p50 / p99 [ms]',
                   f'callbacks run / goals sent (100 Hz, {r["work_ms"]:g} ms each)',
                   'callback delay p50 / p99 [ms]', 'hand-overs per goal',
                   'service p50 during the stream [ms]'], rows))


def render_service_ab(data: dict) -> str:
    """``bench/service_ab.py``: the node's round trip, paired between two checkouts."""
    r = data['results']
    a, b = r['names']
    commits = data.get('checkouts', {})
    rows = [[f'{n} (`{commits.get(n, {}).get("commit", "?")}`)',
             f'{num(r["rows"][n]["p50_ms"])} / {num(r["rows"][n]["p99_ms"])}',
             str(r['rows'][n]['requests'])] for n in (a, b)]
    return (table(['checkout', 'round trip p50 / p99 [ms]', 'requests'], rows)
            + f'\n\n{b} / {a}, median of the paired per-request ratios: **{num(r["ratio"], 3)}**')


def render_first_answer(data: dict) -> str:
    """``bench/first_answer.py``: an arm from robot_description, from start to its answers."""
    r = data['results']
    if r['settings'].get('table_only'):
        return _render_table_starts(r)
    with_starts = any(a.get('table_first_exact_s') is not None for a in r['arms'])
    rows = []
    for a in r['arms']:
        t, lrn = a.get('table') or {}, a.get('learned') or {}
        cost = a.get('training_cost') or {}

        def phase(f: dict) -> str:
            if not f:
                return NA
            return (f'{pct(f["success"])}; {f["distinct_median"]:.0f} '
                    f'({f["distinct_p10"]:.0f}); {num(f["time_median_ms"])} ms')

        starts = [] if not with_starts else [
            num(a.get('table_first_exact_s')), num(a.get('table_restart_exact_s')),
            pct(((a.get('table_restart') or {}).get('pose') or {}).get('success', 0.0))]
        rows.append([f'{a["arm"]} ({a["joints"]})'] + starts + [
                     num(a.get('first_exact_s')),
                     phase(t.get('pose')), phase(t.get('position')),
                     num(a.get('learned_s'), 0), phase(lrn.get('pose')),
                     phase(lrn.get('position')),
                     num(a.get('restart_learned_s')), num(a.get('restart_exact_s')),
                     NA if not cost else f'{num(cost["running_p50_ms"])} / '
                     f'{num(cost["paused_p50_ms"])} ({num(cost["ratio"])}x)'])
    st = r['settings']
    return (f'Each arm started with only `robot_description`, `base_frame` and `tip_frame` and '
            f'an empty cache; the background build given {st["learning_time_s"]:.0f} s and '
            f'{st["learning_rows"]:,} configurations; {st["targets"]} targets per phase (FK of '
            f'random configurations, seed {st["seed"]}), 16 solutions asked over ROS. Times '
            "from the node's start; a phase's cells: success; distinct exact solutions, "
            f'median (p10); round trip, median.'
            + (' *Table only*: the node with `learning` off on a cache of its own, started '
               '(its table swept and cached) and restarted (the table loaded from the cache; '
               'pose success of the restarted node).' if with_starts else '') + '\n\n'
            + table(['arm (joints)'] + (['table only: first exact [s]',
                                         'table only: restart exact [s]',
                                         'table only: restart pose success']
                                        if with_starts else []) + [
                     'first exact [s]', 'table: pose', 'table: position',
                     'learned [s]', 'learned: pose', 'learned: position',
                     'restart: learned served [s]', 'restart: first exact [s]',
                     '`~/solve_ik` p50 while it trains / paused [ms]'], rows))


def _render_table_starts(r: dict) -> str:
    """``bench/first_answer.py --table-only``: the table of configurations started, restarted."""
    rows = []
    for a in r['arms']:
        tr = a.get('table_restart') or {}

        def phase(f: dict) -> str:
            if not f:
                return NA
            return (f'{pct(f["success"])}; {f["distinct_median"]:.0f} '
                    f'({f["distinct_p10"]:.0f}); {num(f["time_median_ms"])} ms')

        rows.append([f'{a["arm"]} ({a["joints"]})', num(a.get('table_first_exact_s')),
                     a.get('table_start_table') or NA, num(a.get('table_restart_exact_s')),
                     a.get('table_restart_table') or NA, phase(tr.get('pose')),
                     phase(tr.get('position'))])
    st = r['settings']
    return (f'Table only (`--table-only`): each arm started with only `robot_description`, '
            f'`base_frame`, `tip_frame` and `learning` off, on an empty cache (its table of '
            f'configurations swept and cached), then restarted on that cache; {st["targets"]} '
            f'targets (FK of random configurations, seed {st["seed"]}) asked of the restarted '
            f'node, 16 solutions each over ROS. Times from the node\'s start to its first '
            f"exact pose answer; the table as the node's log says it came (built or loaded); a "
            f"phase's cells: success; distinct exact solutions, median (p10); round trip, "
            f'median.\n\n'
            + table(['arm (joints)', 'first start: first exact [s]', 'its table',
                     'restart: first exact [s]', 'its table', 'restart: pose',
                     'restart: position'], rows))


def render_moveit_ik(data: dict) -> str:
    """``bench/moveit_ik.py``: /compute_ik beside ~/solve_ik (one solution) and the floor."""
    r = data['results']
    labels = (('solve_ik', '`~/solve_ik`, 1 solution'), ('compute_ik', '`/compute_ik`'),
              ('floor', 'empty `Trigger` service'))
    cols = ('p50_ms', 'p90_ms', 'p99_ms')
    rows = [[label, ' / '.join(num(r['round_trip'][key][p]) for p in cols),
             f'{r["success"][key]} / {r["requests"]}' if key in r['success'] else '']
            for key, label in labels]
    return (table(['service', 'round trip p50 / p90 / p99 [ms]', 'SUCCESS'], rows)
            + f'\n\n`/compute_ik` / `~/solve_ik`: p50 ratio **{num(r["ratio_p50"])}**, median '
            f'of the per-goal ratios **{num(r["paired_ratio_median"])}** (avoid_collisions '
            f'{str(r["avoid_collisions"]).lower()})')


def render_batch_service(data: dict) -> str:
    """``bench/batch_service.py``: one ~/solve_ik_batch against as many ~/solve_ik calls."""
    r = data['results']
    labels = (('batch', f'one `~/solve_ik_batch` of {r["targets"]} targets'),
              ('calls', f'{r["targets"]} `~/solve_ik` calls, one after the other'))
    rows = []
    for key, label in labels:
        d, c = r[key], r['checks'][key]
        rows.append([label, f'{num(d["throughput_median"], 0)} ({num(d["throughput_total"], 0)})',
                     num(d['ms_per_target_median']),
                     f'{c["success"]} / {r["targets"] * r["repeats"]}',
                     f'{c["exact_by_fk"]} / {c["marked_exact"]}'])
    ratio = r['ratio']
    node = ', '.join(f'`{p}`' for p in r.get('params', [])) or 'the default parameters'
    return (f'{r["targets"]} {r["goals"]} goals per round, {r["solutions"]} solutions asked, '
            f'{r["repeats"]} rounds (A B A B); the node with {node}:\n\n'
            + table(['', 'throughput, median round (total) [targets/s]',
                     'time per target, median [ms]', 'SUCCESS',
                     'solutions within tolerance by FK / as reported'], rows)
            + f'\n\nbatch / calls, median of the rounds\' throughput ratios: '
            f'**{num(ratio["median"])}** (range {num(ratio["min"])}-{num(ratio["max"])})')


def render_cluster(data: dict) -> str:
    """``bench/cluster.py``: a reach map on 1 and 2 workers, local processes and Ray actors."""
    r = data['results']
    rows = [[f'{"local processes" if run["kind"] == "processes" else "Ray actors"}',
             str(run['workers']), num(run['seconds']), num(run['goals_per_s'], 0),
             (f'{num(run["cluster_start_s"])} s / {num(run["first_map_s"])} s'
              if 'cluster_start_s' in run else '')]
            for run in r['runs']]
    speedups = ', '.join(f'{label} **{num(r[key])}**' for key, label in
                         (('processes_speedup_2_over_1', 'local processes'),
                          ('ray_speedup_2_over_1', 'Ray actors')) if key in r)
    return (f'The Panda map at {r["voxel"]} m and {r["orientations"]} orientations: '
            f'{r["voxels"]} voxels, {r["goals"]} pose goals ({pct(r["reached"])} reached), '
            f'{r["num_solutions"]} solutions asked, no timeout:\n\n'
            + table(['workers on', 'workers', 'map [s] (median)', 'pose goals/s',
                     'cluster start / first map with the actors loading'], rows)
            + f'\n\n2 workers over 1: {speedups}; every map the same, goal for goal: '
            f'**{"yes" if r["same_maps"] else "no"}**')


RENDER: Dict[str, Callable] = {
    'collect': render_collect, 'solve': render_solve, 'solve_ab': render_ab,
    'arms': render_arms, 'paths': render_paths, 'paths_ab': render_paths_ab,
    'service_probe': render_service_probe, 'soak': render_soak, 'sweep': render_sweep,
    'train_step': render_train_step, 'tracik_protocol': render_tracik_protocol,
    'ablation': render_ablation, 'families': render_families, 'stream': render_stream,
    'executors': render_executors, 'service_ab': render_service_ab,
    'first_answer': render_first_answer, 'moveit_ik': render_moveit_ik,
    'batch_service': render_batch_service, 'cluster': render_cluster}


def load() -> Dict[str, List[dict]]:
    """Every result file under docs/results, grouped by benchmark (``NAME.json`` first)."""
    out: Dict[str, List[dict]] = {}
    for path in sorted(RESULTS.glob('*.json')):
        data = json.loads(path.read_text())
        data['file'] = path.stem
        out.setdefault(data['benchmark'], []).append(data)
    for files in out.values():  # the plain NAME.json first, then its variants by name
        files.sort(key=lambda d: (d['file'] != d['benchmark'], d['file']))
    return out


def block(name: str, results: Dict[str, List[dict]]) -> Optional[str]:
    """The generated text of marker ``name``, or None when it has no results."""
    if name == 'summary':
        return render_summary(results)
    files = results.get(name)
    if not files:
        return None
    if name == 'service':
        return render_service(files) + '\n\n' + '\n\n'.join(provenance(d) for d in files)
    return '\n\n'.join(RENDER[name](d) + '\n\n' + provenance(d) for d in files)


def render_text(text: str, results: Dict[str, List[dict]]) -> str:
    """``text`` with every marked block replaced by its table (left alone without results)."""
    def replace(m: re.Match) -> str:
        body = block(m.group(2), results)
        return m.group(0) if body is None else f'{m.group(1)}{body}\n{m.group(4)}'
    return BLOCK.sub(replace, text)


def main(argv: Optional[List[str]] = None) -> int:
    """Rewrite the tables, or check them with ``--check``."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--check', action='store_true',
                        help='change nothing; exit 1 when a table differs from its JSON')
    args = parser.parse_args(argv)
    results = load()
    stale = []
    for doc in DOCS:
        text = doc.read_text()
        new = render_text(text, results)
        if new != text:
            stale.append(doc.relative_to(REPO))
            if not args.check:
                doc.write_text(new)
    if args.check and stale:
        print('tables differ from docs/results/*.json: ' + ', '.join(map(str, stale))
              + ' (run python bench/render.py)', file=sys.stderr)
        return 1
    for doc in stale:
        print(f'rewrote the tables of {doc}')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
