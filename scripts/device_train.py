#!/usr/bin/env python3
"""Run a group of the device recipe: each run a ``sik-train --chain``, its checkpoint to --out.

The recipe (``scripts/device/recipe.json``) names the chain file, the runs (each one's
sik-train options and budget [s]) and the groups that fit one command of the GPU machine. Each
run trains on rows generated on the device (no Pinocchio there), its schedule fitted to its
budget (``--fit-schedule``), in a work folder (``--runs``); a run whose folder already holds a
checkpoint resumes it, and ``--resume-from`` seeds the folders with checkpoints brought back
from an earlier session. Each run's checkpoint (``last.pt``, resumable, under 16 MiB) is copied
to ``--out/<run>.pt``; ``--out/summary.json`` holds each run's figures, steps, samples, time
and device, and ``--out/log.txt`` the runs' output.

On the GPU machine (the ``device`` tool's ``run``, in the repository root)::

    PYTHONUNBUFFERED=1 python3 scripts/device_train.py --group sik --out "$OUT"

Here, the same path on the CPU with a tiny budget (what the tests run)::

    python scripts/device_train.py --group sik --device cpu --tiny --out /tmp/dev --runs /tmp/r
"""

import argparse
import json
import os
from pathlib import Path
import shutil
import subprocess
import sys
import time
from typing import Dict, List

ROOT = Path(__file__).resolve().parents[1]
#: Largest file the device tool brings back [bytes], and how many files.
MAX_FILE = 16 * 1024 * 1024
MAX_FILES = 8


def options(args: Dict) -> List[str]:
    """sik-train options from a recipe's ``{"--name": value}`` (true: a flag; false: left out)."""
    out = []
    for name, value in args.items():
        if value is True:
            out.append(name)
        elif value is not False and value is not None:
            out += [name, str(value)]
    return out


def plan(recipe: Dict, names: List[str], tiny: bool, budget: float) -> List[Dict]:
    """Each run's name, options and budget [s]; refuses a plan over the command's limit."""
    runs = []
    for name in names:
        if name not in recipe['runs']:
            raise SystemExit(f'device_train: no run {name!r} in the recipe '
                             f'({", ".join(recipe["runs"])})')
        run = recipe['runs'][name]
        args = dict(run['args'])
        seconds = float(budget or run['budget_s'])
        if tiny:
            args.update(recipe['tiny']['args'])
            seconds = float(budget or recipe['tiny']['budget_s'])
        runs.append({'name': name, 'args': args, 'budget_s': seconds})
    total = sum(r['budget_s'] + recipe['overhead_s'] for r in runs)
    if total > recipe['limit_s']:
        raise SystemExit(f'device_train: {len(runs)} runs need about {total:.0f} s, over the '
                         f'{recipe["limit_s"]} s a command may take: fewer runs or --budget')
    if len(runs) + 2 > MAX_FILES:
        raise SystemExit(f'device_train: {len(runs)} runs: more files than the {MAX_FILES} the '
                         f'device tool brings back')
    return runs


def train(run: Dict, chain: Path, device: str, runs: Path, resume_from: Path, python: str,
          log) -> Dict:
    """One run: seed its folder, start or resume sik-train, and its summary."""
    folder = runs / run['name']
    folder.mkdir(parents=True, exist_ok=True)
    last = folder / 'last.pt'
    brought = resume_from / f'{run["name"]}.pt' if resume_from else None
    if not last.exists() and brought is not None and brought.is_file():
        shutil.copyfile(brought, last)
    cmd = [python, '-m', 'sik_ros.cli.train', '--chain', str(chain), '--out', str(folder),
           '--device', device, '--max-time', f'{run["budget_s"]:g}', '--quiet']
    cmd += ['--resume'] if last.exists() else options(run['args']) + ['--fit-schedule']
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        [str(ROOT)] + [p for p in os.environ.get('PYTHONPATH', '').split(os.pathsep) if p]))
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True,
                          timeout=run['budget_s'] + 300)
    wall = time.perf_counter() - t0
    log.write(f'== {run["name"]}: {" ".join(cmd)}\n{proc.stderr}{proc.stdout}\n')
    log.flush()
    lines = [s for s in proc.stdout.splitlines() if s.startswith('{')]
    result = json.loads(lines[-1]) if proc.returncode == 0 and lines else {}
    summary = {'name': run['name'], 'rc': proc.returncode, 'wall_s': round(wall, 1),
               'command': cmd[1:], **{k: v for k, v in result.items() if k != 'rank'}}
    if last.exists():
        summary.update(checkpoint_summary(last))
    if proc.returncode != 0:
        summary['error'] = proc.stderr.strip().splitlines()[-1:] or ['(no output)']
    return summary


def checkpoint_summary(path: Path) -> Dict:
    """A checkpoint's size [bytes] and where, how long and on how many samples it trained."""
    sys.path.insert(0, str(ROOT))
    from sik_ros.learning.checkpoints import load_checkpoint
    from sik_ros.learning.provenance import trained_summary
    ckpt = load_checkpoint(path)
    return {'checkpoint_bytes': path.stat().st_size, 'trained': trained_summary(ckpt),
            'schedule_steps': int(ckpt['train_config']['steps'])}


def main() -> int:
    """Entry point."""
    p = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    p.add_argument('--recipe', default=str(ROOT / 'scripts/device/recipe.json'))
    p.add_argument('--group', help='a group of the recipe (sik, baselines)')
    p.add_argument('--run', action='append', default=[], help='a run of the recipe (repeat)')
    p.add_argument('--device', default='cuda', choices=('cuda', 'cpu'))
    p.add_argument('--out', default=os.environ.get('OUT'),
                   help='where the checkpoints and the summary go (default: $OUT)')
    p.add_argument('--runs', default='/tmp/sik_device_runs',
                   help='work folder of the runs (resumed from when it holds them)')
    p.add_argument('--resume-from', help='a folder of <run>.pt checkpoints brought back '
                   'earlier: each run without a checkpoint in --runs resumes from its own')
    p.add_argument('--budget', type=float, help='seconds per run instead of the recipe\'s')
    p.add_argument('--tiny', action='store_true', help='the recipe\'s tiny options (a CPU '
                   'test of the path)')
    args = p.parse_args()
    if not args.out:
        p.error('--out is needed (or $OUT)')
    recipe = json.loads(Path(args.recipe).read_text())
    names = list(recipe['groups'].get(args.group, [])) if args.group else []
    if args.group and not names:
        p.error(f'no group {args.group!r} in the recipe ({", ".join(recipe["groups"])})')
    names += [n for n in args.run if n not in names]
    if not names:
        p.error('give --group or --run')
    runs = plan(recipe, names, args.tiny, args.budget)
    out, work = Path(args.out), Path(args.runs)
    out.mkdir(parents=True, exist_ok=True)
    chain = ROOT / recipe['chain']
    resume_from = Path(args.resume_from) if args.resume_from else None
    summaries = []
    with open(out / 'log.txt', 'a') as log:
        for run in runs:
            s = train(run, chain, args.device, work, resume_from, sys.executable, log)
            last = work / run['name'] / 'last.pt'
            if last.exists() and last.stat().st_size < MAX_FILE:
                shutil.copyfile(last, out / f'{run["name"]}.pt')
            elif last.exists():
                s['error'] = [f'checkpoint of {last.stat().st_size:,} bytes: over the '
                              f'{MAX_FILE:,} the device tool brings back; kept in {last}']
            summaries.append(s)
            keys = ('name', 'rc', 'wall_s', 'step', 'val_dist_mean_m', 'val_orient_mean_deg',
                    'checkpoint_bytes')
            print(json.dumps({k: s.get(k) for k in keys}), flush=True)
    tmp = out / '.summary.json.tmp'
    tmp.write_text(json.dumps({'device': args.device, 'runs': summaries}, indent=1) + '\n')
    os.replace(tmp, out / 'summary.json')
    return 0 if all(s['rc'] == 0 and 'error' not in s for s in summaries) else 1


if __name__ == '__main__':
    raise SystemExit(main())
