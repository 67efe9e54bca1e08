"""``sik-index``: build the posture-index table of a trained model from a dataset."""

import argparse
import time
from typing import List, Optional

from sik_ros.cli import argv_or_default, Parser, run_cli
from sik_ros.defaults import SEARCH_SEED_TABLE_ROWS, SEED_TABLE_ROWS, TableConfig
from sik_ros.errors import ArtifactExists, InvalidArgument


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of sik-index."""
    p = Parser(prog='sik-index', description='Encode a dataset with a trained '
               'SIK/PSIK model and keep the distinct posture indices per cell.')
    p.add_argument('--model', required=True, help='model or checkpoint (.pt) from sik-train')
    p.add_argument('--dataset', required=True, help='dataset directory (sik-collect --out)')
    p.add_argument('--out', required=True, help='output table (.npz)')
    p.add_argument('--cell', type=float, default=TableConfig.cell, help='cell edge [m]')
    p.add_argument('--dedup', type=float, default=TableConfig.dedup,
                   help='indices closer than this per element are duplicates')
    p.add_argument('--max-per-cell', type=int, default=TableConfig.max_per_cell)
    p.add_argument('--max-tip-error', type=float, default=TableConfig.max_tip_error,
                   help='mark the indices whose decoded tip comes within this of the goal at '
                   'their cell centre and one cell away along each axis [m]: the look-up by '
                   'position gives only those (each cell has its best marked; recorded in the '
                   'manifest; position-goal models with --postures); 0: none marked (default)')
    p.add_argument('--orientations', action=argparse.BooleanOptionalAction, default=True,
                   help='keep each index\'s tip orientation (8 bits per element), so pose goals '
                   'can choose indices by orientation (default: on)')
    p.add_argument('--postures', action=argparse.BooleanOptionalAction, default=None,
                   help='keep each index decoded at its cell centre (8 bits per joint), so the '
                   'solver refines from them without decoding (default: on for position-goal '
                   'models; pose-goal models cannot)')
    p.add_argument('--bundle', help='also add model and table to this bundle directory')
    p.add_argument('--seeds', type=int,
                   help='with --bundle and a pose-goal model of an arm of seven joints or '
                   'fewer: configurations of the seed table written into the bundle, where its '
                   f'pose solutions start (default: {SEED_TABLE_ROWS:,} for six joints or '
                   f'fewer, {SEARCH_SEED_TABLE_ROWS:,} for seven; 0: none new, a seed table the '
                   'bundle has stays); ignored otherwise')
    p.add_argument('--force', action='store_true', help='replace an existing --out')
    p.add_argument('--quiet', action='store_true', help='no progress bar')
    return p


def main(argv: Optional[List[str]] = None) -> int:
    """Entry point of sik-index."""
    args = build_parser().parse_args(argv_or_default(argv))

    def body() -> int:
        from pathlib import Path

        from tqdm import tqdm

        from sik_ros.bundles.bundle import add_to_bundle, bundle_files
        from sik_ros.kinematics.robots import robot_from_manifest
        from sik_ros.learning.checkpoints import load_checkpoint
        from sik_ros.learning.indexing import build_table
        from sik_ros.tables.dataset import Dataset
        from sik_ros.tables.seed_table import default_rows, SeedTable
        out = Path(args.out)
        if out.exists() and not args.force:
            raise ArtifactExists(f'{out} already exists (use --force to replace it)')
        if out.suffix != '.npz':
            raise InvalidArgument(f'--out must end in .npz; got {out}')
        if args.seeds is not None and args.seeds < 0:
            raise InvalidArgument(f'--seeds must be >= 0; got {args.seeds}')
        cfg = TableConfig(args.cell, args.dedup, args.max_per_cell, args.max_tip_error)
        ckpt = load_checkpoint(args.model)
        robot = robot_from_manifest(ckpt['robot'], f'model {args.model}')
        ds = Dataset.load(args.dataset, robot)
        t0 = time.perf_counter()
        with tqdm(total=len(ds), unit='rows', unit_scale=True, disable=args.quiet,
                  desc='encode') as bar:
            table = build_table(ckpt, robot, ds, cfg, args.orientations, args.postures,
                                progress=bar.update)
        table.save(out)
        realised = table.manifest.get('realised')
        marked = f', {realised["entries"]} of them realised' if realised else ''
        print(f'{table.manifest["cells"]} cells, {table.manifest["entries"]} indices{marked} '
              f'({out.stat().st_size / 1e6:.2f} MB) in {time.perf_counter() - t0:.1f} s')
        if args.bundle:
            rows = default_rows(robot)
            rows = rows if rows is None or args.seeds is None else args.seeds
            seeds = None
            if table.manifest['goal'] == 'pose' and rows:
                st = SeedTable.build(robot, ds, rows)
                Path(args.bundle).mkdir(parents=True, exist_ok=True)
                seeds = st.save(Path(args.bundle) / bundle_files('pose')['seeds'])
                print(f'seed table: {len(st):,} configurations ({seeds.stat().st_size / 1e6:.2f} '
                      f'MB)')
            add_to_bundle(Path(args.bundle), robot.manifest(), table.manifest['goal'],
                          Path(args.model), out, seeds)
            print(f'added to bundle {args.bundle}')
        return 0
    return run_cli('sik-index', body)


if __name__ == '__main__':
    raise SystemExit(main())
