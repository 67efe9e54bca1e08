r"""From robot_description to exact answers: sik_node on arms it has never seen, then restarted.

For each arm (an example-robot-data URDF, or a tree of two UR5 arms with one arm's frames), a
node is started with only ``robot_description``, ``base_frame`` and ``tip_frame`` (and an empty
cache folder) and timed over ROS 2 from its start to:

- ``first exact``: the first SUCCESS answer to a reachable pose goal (polled every 20 ms, an
  unanswered call sent again after 0.1 s);
- ``learned``: the learned model built (the background build given ``--learning-time``
  seconds and ``--learning-rows`` configurations) and judged against the table on the same
  targets: swapped in, or the table kept where the model answered worse;
- on a restart with the same cache: ``restart exact`` (the first SUCCESS answer) and
  ``restart learned`` (the node's log says it serves the learned bundle, from its start);
- first, on a cache of its own with ``learning`` off: ``table first exact`` (the table of
  configurations built and cached) and ``table restart exact`` (a restart, the table loaded
  from the cache; the node's log says whether it was loaded or built), then the table phase's
  targets asked of the restarted node (``table_restart``). ``--table-only`` measures this
  part alone.

In each phase (the table of configurations, the learned model) the same targets (FK of random
configurations, seeded) are asked over ROS, 16 solutions each, pose and position goals:
success, distinct exact solutions (median, p10) and round-trip time (median). While the model
trains, ``~/solve_ik``'s p50 is compared with the build running and paused (SIGSTOP on its
process group), block by block (A B A B), on one-solution pose goals: the build's cost to the
service.

    python bench/first_answer.py --arms panda,ur5,xarm7,kinova,so100,z1,ur10,baxter,tree \
        --json docs/results/first_answer.json

``ur10`` (six joints) and ``baxter`` (the left arm of a two-arm robot) are not among
``bench/arms.py``'s arms; ``tree`` is two UR5s on a turning torso, served its left arm.
"""

import argparse
import json
import os
from pathlib import Path
import signal
import subprocess
import sys
import tempfile
import time

os.environ.setdefault('OMP_NUM_THREADS', '1')

import numpy as np  # noqa: E402
import rclpy  # noqa: E402
import yaml  # noqa: E402

from sik_ros.kinematics.robots import KNOWN_FRAMES, load_robot  # noqa: E402
from sik_ros.ros import launch  # noqa: E402
from sik_ros.ros.client import pose_request, SolveIKClient  # noqa: E402
from sik_ros.solver.scores import distinct_mask  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / 'test'))
from report import add_json_argument, write_json  # noqa: E402,I100 (bench/report.py)

from arm_urdfs import erd_share, erd_text, two_arm_text  # noqa: E402,I100,I202 (test/)

#: Frames of the arms whose own choice is not the inferred one (else inferred as sik-build does):
#: Baxter's left arm (a real two-arm tree), and the left arm of two UR5s on one torso.
FRAMES = dict(KNOWN_FRAMES, tree=('left_base_link', 'left_tool0'),
              baxter=('left_arm_mount', 'left_wrist'))


def arm_source(name: str):
    """The description text, the frames and a Robot of the chain, for an arm name."""
    if name == 'tree':
        text = two_arm_text()
        with tempfile.NamedTemporaryFile('w', suffix='.urdf', delete=False) as f:
            f.write(text)
        robot = load_robot('', f.name, *FRAMES['tree'])
        return text, FRAMES['tree'], robot
    robot = load_robot(name, None, *FRAMES.get(name, (None, None)))
    return erd_text(name), (robot.base_frame, robot.tip_frame), robot


def start(args, env, text, frames, cache, log, learning=True):
    """The node, with a parameter file of only the arm's parameters."""
    values = {'robot_description': text, 'base_frame': frames[0], 'tip_frame': frames[1],
              'cache_dir': str(cache), 'learning_time': args.learning_time,
              'learning_rows': args.learning_rows, 'learning': learning}
    params = Path(cache).parent / f'params_{time.monotonic_ns()}.yaml'
    params.write_text(yaml.safe_dump({'/**': {'ros__parameters': values}}))
    return subprocess.Popen([sys.executable, '-m', 'sik_ros.ros.run', '--ros-args',
                             '--params-file', str(params)], env=env, stdout=log,
                            stderr=subprocess.STDOUT)


def first_exact(client, goals, started, timeout=120.0, names=None):
    """Seconds from ``started`` to the first SUCCESS answer (None: none came).

    ``names``: the arm's joints, which the answer must name (not another node's arm).

    The goals are asked in turn, one every 20 ms once the service is up: the first exact
    answer to any of them counts (a goal the model misses does not hold the figure).
    """
    k = 0
    while time.monotonic() - started < timeout:
        if not client.wait_for_service(0.02):
            continue
        # resent after 0.1 s: a reply dropped while the new service's reply writer is not yet
        # matched (sik_ros.ros.client) would otherwise add the client's 2 s resend to the figure
        answer = client.call(pose_request(*goals[k % len(goals)], max_solutions=1), timeout=5.0,
                             attempt=0.1)
        if answer is not None and answer.error_code == 1 and (
                names is None or list(answer.solutions[0].joint_state.name) == names):
            return time.monotonic() - started
        k += 1
        time.sleep(0.02)
    return None


def phase(client, robot, targets):
    """Success, distinct exact solutions and round-trip times of 16-solution calls, per goal."""
    out = {}
    for kind in ('pose', 'position'):
        ok, distinct, times = 0, [], []
        for p, quat in targets:
            t0 = time.perf_counter()
            answer = client.call(pose_request(p, quat if kind == 'pose' else None, 16),
                                 timeout=10.0)
            times.append(time.perf_counter() - t0)
            good = answer is not None and answer.error_code == 1
            ok += good
            q = np.array([s.joint_state.position for s in answer.solutions]) if good else []
            distinct.append(int(distinct_mask(q, 0.5, False).sum()) if len(q) else 0)
        out[kind] = {'targets': len(targets), 'success': ok / len(targets),
                     'distinct_median': float(np.median(distinct)),
                     'distinct_p10': float(np.percentile(distinct, 10)),
                     'time_median_ms': 1e3 * float(np.median(times))}
    return out


def build_pid(cache):
    """The background build's process (its group's leader), or None."""
    for progress in Path(cache).rglob('build/progress.json'):
        try:
            pid = int(json.loads(progress.read_text())['pid'])
            os.kill(pid, 0)
            return pid
        except (OSError, ValueError, KeyError):
            return None
    return None


def training_cost(client, targets, cache, blocks=6, per_block=15):
    """p50 [ms] of one-solution pose calls with the build running and paused, A B A B.

    Measured once the build trains (its progress says ``train``), in the build's longest stage.
    """
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and not any(
            '"train"' in p.read_text() for p in Path(cache).rglob('build/progress.json')):
        time.sleep(0.2)
    running, paused = [], []
    for b in range(2 * blocks):
        pid = build_pid(cache)
        if pid is None:
            break
        stop = b % 2 == 1
        if stop:
            os.killpg(pid, signal.SIGSTOP)
        try:
            for p, quat in targets[:per_block]:
                t0 = time.perf_counter()
                client.call(pose_request(p, quat, 1), timeout=10.0)
                (paused if stop else running).append(time.perf_counter() - t0)
        finally:
            if stop:
                os.killpg(pid, signal.SIGCONT)
    if not running or not paused:
        return None
    r, s = 1e3 * float(np.median(running)), 1e3 * float(np.median(paused))
    return {'running_p50_ms': r, 'paused_p50_ms': s, 'ratio': r / s, 'calls': len(running)}


def log_seconds(log: Path, words: str, started_wall: float):
    """Seconds from the start to the node's first log line holding ``words`` (None if none)."""
    for line in log.read_text(errors='replace').splitlines():
        if words in line and line.startswith('[INFO] ['):
            return float(line.split('[')[2].split(']')[0]) - started_wall
    return None


def table_starts(args, name, env, folder, text, frames, robot, targets, row):
    """First start and restart with learning off, on a cache of their own (see the module)."""
    cache = folder / name / 'table_cache'
    cache.mkdir(parents=True)
    for key, tag in (('table_first_exact_s', 'table_start'),
                     ('table_restart_exact_s', 'table_restart')):
        if not rclpy.ok():
            rclpy.init()
        log = folder / name / f'{tag}.log'
        with SolveIKClient() as client, open(log, 'wb') as out:
            started = time.monotonic()
            proc = start(args, env, text, frames, cache, out, learning=False)
            try:
                row[key] = first_exact(client, targets, started, names=robot.joint_names)
                if tag == 'table_restart':
                    row['table_restart'] = phase(client, robot, targets)
            finally:
                launch.stop_node(proc)
        said = log.read_text(errors='replace')
        row[f'{tag}_table'] = ('loaded' if 'table of configurations: loaded' in said else
                               'built' if 'table of configurations:' in said else None)


def bench_arm(args, name, env, folder):
    """One arm's figures (see the module)."""
    text, frames, robot = arm_source(name)
    cache = folder / name / 'cache'
    cache.mkdir(parents=True)
    rng = np.random.default_rng(args.seed)
    q = rng.uniform(robot.lower, robot.upper, (args.targets, robot.dof))
    targets = [tuple(map(tuple, robot.fk(qi))) for qi in q]
    log = folder / name / 'node.log'
    row = {'arm': name, 'joints': robot.dof, 'frames': list(frames)}
    table_starts(args, name, env, folder, text, frames, robot, targets, row)
    if args.table_only:
        return row
    with SolveIKClient() as client, open(log, 'wb') as out:
        started = time.monotonic()
        proc = start(args, env, text, frames, cache, out)
        try:
            row['first_exact_s'] = first_exact(client, targets, started,
                                               names=robot.joint_names)
            row['table'] = phase(client, robot, targets)
            row['training_cost'] = training_cost(client, targets, cache)
            deadline = started + args.learning_time * 3 + 120
            words = ('learned model swapped in', 'kept the table')
            while time.monotonic() < deadline and not any(
                    w in log.read_text(errors='replace') for w in words):
                time.sleep(0.5)
            said = log.read_text(errors='replace')
            if any(w in said for w in words):
                row['learned_s'] = time.monotonic() - started
                row['swapped_in'] = words[0] in said
                row['learned'] = phase(client, robot, targets)
        finally:
            launch.stop_node(proc)
    restart_log = folder / name / 'restart.log'
    if not rclpy.ok():  # a signal to this process's group reached rclpy's handler
        print(f'{name}: rclpy was shut down; initialised again', file=sys.stderr)
        rclpy.init()
    with SolveIKClient() as client, open(restart_log, 'wb') as out:
        wall, started = time.time(), time.monotonic()
        proc = start(args, env, text, frames, cache, out)
        try:
            row['restart_exact_s'] = first_exact(client, targets, started,
                                                 names=robot.joint_names)
        finally:
            launch.stop_node(proc)
    row['restart_learned_s'] = log_seconds(restart_log, 'from its learned bundle', wall)
    return row


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--arms', default='panda,ur5,xarm7,kinova,so100,z1,ur10,baxter,tree')
    parser.add_argument('--targets', type=int, default=50)
    parser.add_argument('--learning-time', type=float, default=120.0)
    parser.add_argument('--learning-rows', type=int, default=300_000)
    parser.add_argument('--seed', type=int, default=11)
    parser.add_argument('--table-only', action='store_true',
                        help='only the starts with learning off (the table cached, restarted)')
    add_json_argument(parser)
    args = parser.parse_args()
    env = dict(launch.ros_env(), ROS_PACKAGE_PATH=erd_share())
    os.environ['ROS_PACKAGE_PATH'] = env['ROS_PACKAGE_PATH']
    rclpy.init()
    rows = []
    with tempfile.TemporaryDirectory(prefix='sik_first_answer_') as tmp:
        for name in args.arms.split(','):
            if not rclpy.ok():
                rclpy.init()
            row = bench_arm(args, name, env, Path(tmp))
            rows.append(row)
            print(json.dumps(row), flush=True)
    rclpy.try_shutdown()
    print('| arm | joints | table: first exact [s] | table: restart exact [s] (table) | '
          'restart: pose success |')
    for r in rows:
        tr = (r.get('table_restart') or {}).get('pose', {})
        print(f'| {r["arm"]} | {r["joints"]} | {r.get("table_first_exact_s") or float("nan"):.2f}'
              f' | {r.get("table_restart_exact_s") or float("nan"):.2f} '
              f'({r.get("table_restart_table")}) | {100 * tr.get("success", 0):.0f} % |')
    learned = [] if args.table_only else rows  # the learning's table: none measured
    print('| arm | joints | first exact [s] | learned [s] | restart exact [s] | restart '
          'learned [s] | pose: success, distinct (p10), ms table / learned | p50 while '
          'training / paused [ms] |')
    for r in learned:
        t, lrn, c = r.get('table', {}).get('pose', {}), r.get('learned', {}).get('pose', {}), \
            r.get('training_cost') or {}
        print(f'| {r["arm"]} | {r["joints"]} | {r.get("first_exact_s") or float("nan"):.2f} | '
              f'{r.get("learned_s") or float("nan"):.0f} | '
              f'{r.get("restart_exact_s") or float("nan"):.2f} | '
              f'{r.get("restart_learned_s") or float("nan"):.2f} | '
              f'{100 * t.get("success", 0):.0f} %, {t.get("distinct_median", 0):.0f} '
              f'({t.get("distinct_p10", 0):.0f}), {t.get("time_median_ms", 0):.2f} / '
              f'{100 * lrn.get("success", 0):.0f} %, {lrn.get("distinct_median", 0):.0f} '
              f'({lrn.get("distinct_p10", 0):.0f}), {lrn.get("time_median_ms", 0):.2f} | '
              f'{c.get("running_p50_ms", float("nan")):.2f} / '
              f'{c.get("paused_p50_ms", float("nan")):.2f} |')
    write_json(args.json, 'first_answer', {'arms': rows, 'settings': {
        'learning_time_s': args.learning_time, 'learning_rows': args.learning_rows,
        'targets': args.targets, 'seed': args.seed, 'table_only': args.table_only}})


if __name__ == '__main__':
    main()
