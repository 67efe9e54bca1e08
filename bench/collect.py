"""Benchmark sik-collect on the Panda's 30-degree grid: wall time and peak memory, median of 3.

Each run is a fresh process (``sik-collect --robot panda --interval 30``) measured with
``/usr/bin/time``-style accounting from ``resource.getrusage`` of the child.

    python bench/collect.py [--runs 3] [--interval 30] [--json PATH]
"""

import argparse
import os
import platform
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

from report import add_json_argument, write_json  # noqa: I100 (bench/report.py)


def one_run(interval: float, out: str) -> tuple:
    """Wall time [s] and peak RSS [MB] of one sik-collect process."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    t0 = time.perf_counter()
    subprocess.run([sys.executable, '-m', 'sik_ros.cli.collect', '--robot', 'panda',
                    '--interval', str(interval), '--out', out, '--quiet', '--force'],
                   check=True, stdout=subprocess.DEVNULL)
    wall = time.perf_counter() - t0
    peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    return wall, max(peak, before) / 1024.0


def main() -> None:
    """Entry point."""
    p = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    p.add_argument('--runs', type=int, default=3)
    p.add_argument('--interval', type=float, default=30.0)
    add_json_argument(p)
    args = p.parse_args()
    tmp = tempfile.mkdtemp(prefix='sik-bench-collect-')
    try:
        results = [one_run(args.interval, os.path.join(tmp, 'ds')) for _ in range(args.runs)]
        from sik_ros.tables.dataset import Dataset
        rows = len(Dataset.load(os.path.join(tmp, 'ds')))
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    walls = [w for w, _ in results]
    peaks = [m for _, m in results]
    print(f'# bench/collect.py: {platform.machine()}, {os.cpu_count()} cores, Python '
          f'{platform.python_version()}')
    print(f'Panda grid at {args.interval:g} deg: {rows} rows')
    print('| run | wall [s] | peak RSS [MB] |')
    print('|---|---|---|')
    for i, (w, m) in enumerate(results, 1):
        print(f'| {i} | {w:.1f} | {m:.0f} |')
    print(f'| median | {statistics.median(walls):.1f} | {statistics.median(peaks):.0f} |')
    write_json(args.json, 'collect', {
        'interval_deg': args.interval, 'rows': rows,
        'runs': [{'wall_s': w, 'peak_rss_mb': m} for w, m in results],
        'wall_median_s': statistics.median(walls), 'peak_rss_median_mb': statistics.median(peaks)})
    print(f'target: <= 30 s and <= 3072 MB -> '
          f'{"met" if statistics.median(walls) <= 30 and max(peaks) <= 3072 else "NOT met"}')


if __name__ == '__main__':
    main()
