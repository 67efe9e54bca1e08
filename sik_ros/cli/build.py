"""``sik-build``: from an arm (example-robot-data name or URDF) to a served bundle, resumable."""

import argparse
import json
from pathlib import Path
import time
from typing import Dict, List, Optional

from sik_ros.cli import argv_or_default, Parser, run_cli
from sik_ros.defaults import BUILD_BATCH, BuildConfig
from sik_ros.kinematics.description import is_xacro_file, parse_xacro_args, write_xacro_urdf


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of sik-build."""
    d = BuildConfig()
    p = Parser(
        prog='sik-build', description='Collect data, train the position and pose models, '
        'index them, bundle them and check the bundle, in one resumable command (rerun it '
        'after an interruption to continue).')
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument('--robot', help='example-robot-data robot name (e.g. ur5, xarm7)')
    src.add_argument('--urdf', help='URDF file of the arm; a .xacro file is expanded by xacro '
                     'first, into <out>.urdf (the bundle names that file)')
    p.add_argument('--xacro-arg', action='append', default=[], metavar='NAME:=VALUE',
                   help='a xacro argument (repeat for several); runs xacro on --urdf')
    p.add_argument('--base', help='base frame (default: the parent link of the first joint)')
    p.add_argument('--tip', help='tip frame (default: the end of the longest chain, tool0/'
                   'tcp/ee frames preferred)')
    p.add_argument('--out', required=True, help='bundle directory to create')
    p.add_argument('--work', help='folder for the dataset and training runs (default: '
                   '<out>.build)')
    p.add_argument('--time', type=float, default=d.time,
                   help=f'total time budget [s] (default: {d.time:g})')
    p.add_argument('--device', choices=('cpu', 'cuda'), default=d.device,
                   help='where the models train (cuda: a GPU, every batch drawn afresh there)')
    p.add_argument('--sampler', choices=('uniform', 'grid'), default=d.sampler,
                   help='uniform samples, or the Algorithm 1 grid at the finest interval '
                   'under --rows')
    p.add_argument('--rows', type=int, default=d.rows,
                   help=f'dataset rows (uniform) or row budget (grid) (default: {d.rows:,})')
    p.add_argument('--preset', default=d.preset, help='layer widths: tiny, small, default, '
                   'paper')
    p.add_argument('--batch-size', type=int,
                   help='samples per training step (default: '
                   f'{BUILD_BATCH["cpu"]:,} on the CPU, {BUILD_BATCH["cuda"]:,} on a GPU)')
    p.add_argument('--check-targets', type=int, default=d.check_targets,
                   help='targets per goal kind of the final self-check')
    p.add_argument('--seed', type=int, default=d.seed)
    p.add_argument('--cores', type=int, choices=(1, 2), default=d.cores,
                   help='training processes at once: 2, the position and pose models side by '
                   'side; 1, one after the other (a build beside other work)')
    p.add_argument('--quiet', action='store_true', help='no progress bars')
    p.add_argument('--background', action='store_true',
                   help='a node\'s background build: the lowest priority (nice 19), one core, '
                   'stopped with the process that started it')
    return p


def main(argv: Optional[List[str]] = None) -> int:
    """Entry point of sik-build."""
    parser = build_parser()
    args = parser.parse_args(argv_or_default(argv))
    if args.xacro_arg and not args.urdf:
        parser.error('--xacro-arg needs --urdf')
    if args.background:
        from sik_ros.serving.learner import in_background
        in_background()

    def body() -> int:
        from sik_ros.bundles.build import Builder
        from sik_ros.bundles.cache import cache_root
        from sik_ros.kinematics.arm_description import chain_key
        from sik_ros.kinematics.robots import load_robot, package_dirs
        urdf = args.urdf
        if urdf is not None and (is_xacro_file(urdf) or args.xacro_arg):
            urdf = str(write_xacro_urdf(Path(urdf), Path(args.out.rstrip('/\\') + '.urdf'),
                                        parse_xacro_args(args.xacro_arg),
                                        package_dirs(Path(urdf))))
            print(f'xacro: {args.urdf} -> {urdf}')
        robot = load_robot(args.robot or 'panda', urdf, args.base, args.tip)
        periodic = [n for n, p in zip(robot.joint_names, robot.periodic) if p]
        print(f'robot {robot.name}: {robot.dof} joints {robot.joint_names}, base '
              f'{robot.base_frame}, tip {robot.tip_frame}; periodic: {periodic or "none"}; '
              f'cache key {chain_key(robot)} (sik_node serves the bundle copied to '
              f'{cache_root() / chain_key(robot) / "bundle"})')
        cfg = BuildConfig(args.time, args.sampler, args.rows, args.preset, args.device,
                          args.batch_size or BUILD_BATCH[args.device], args.check_targets,
                          args.seed, args.cores)
        report = Builder(robot, args.out, cfg, self_check, args.work,
                         bars=not args.quiet).run()
        print(json.dumps({'bundle': args.out, 'self_check': report}))
        return 0
    return run_cli('sik-build', body, 'the bundle was not written; its work folder stays '
                   '(run the same command to resume)')


def self_check(out: Path, robot, cfg: BuildConfig, say) -> Dict:
    """``sik-build``'s last stage: random reachable targets per goal kind solved by the bundle.

    Returns, per goal kind: targets, success, distinct exact solutions (median, p10) of 16
    asked, and the median time per call [ms].
    """
    import numpy as np
    from sik_ros.bundles.build_training import GOALS
    from sik_ros.solver import SelectiveIK
    ik = SelectiveIK.load(out)
    rng = np.random.default_rng(cfg.seed + 1)
    q = rng.uniform(robot.lower, robot.upper, (cfg.check_targets, robot.dof))
    report = {}
    for goal in GOALS:
        ok, distinct, times = 0, [], []
        for qi in q:
            p, quat = ik.fk(qi)
            t0 = time.perf_counter()
            res = ik.solve(p, quat if goal == 'pose' else None, num_solutions=16)
            times.append(time.perf_counter() - t0)
            ok += res.success
            distinct.append(sum(s.converged for s in res.solutions))
        report[goal] = {'targets': len(q), 'success': ok / len(q),
                        'distinct_median': float(np.median(distinct)),
                        'distinct_p10': float(np.percentile(distinct, 10)),
                        'time_median_ms': 1e3 * float(np.median(times))}
        r = report[goal]
        say(f'self-check, {goal} goals: success {100 * r["success"]:.1f} % of {len(q)}, '
            f'distinct exact solutions median {r["distinct_median"]:.0f} (p10 '
            f'{r["distinct_p10"]:.0f}) of 16, {r["time_median_ms"]:.1f} ms per call')
    return report


if __name__ == '__main__':
    raise SystemExit(main())
