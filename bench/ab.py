"""Paired A/B between checkouts: one worker process each, the same items answered in turn.

Used by ``bench/solve_ab.py`` and ``bench/paths_ab.py``: each starts its own script once per
checkout with ``--worker``; a worker prints ``ready``, then answers every item number read from
stdin with one JSON line. Item by item the workers take turns, the order flipping every item
(A B, B A, ...), so the machine's drift falls on both alike.
"""

import json
import os
import subprocess
import sys
from typing import Dict, List, Sequence


def answers_in_turn(script: str, checkouts: Sequence[str], worker_args: Sequence[str],
                    count: int) -> Dict[str, List[dict]]:
    """Every checkout's answers to items ``0..count-1``, in the order of ``checkouts``.

    Args:
        script: the benchmark script to start as a worker (``__file__``).
        checkouts: ``NAME=DIR`` specs; the worker gets ``DIR`` first, then ``worker_args``.
        worker_args: the rest of the worker's ``--worker`` arguments.
        count: items to hand out.
    """
    procs = []
    for spec in checkouts:
        name, _, root = spec.partition('=')
        p = subprocess.Popen([sys.executable, script, 'x', '--worker', os.path.abspath(root),
                              *worker_args],
                             stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
        if p.stdout.readline().strip() != 'ready':
            sys.exit(f'worker {name} did not start')
        procs.append((name, p))
    answers = {name: [] for name, _ in procs}
    for k in range(count):
        for name, p in (procs if k % 2 == 0 else procs[::-1]):
            p.stdin.write(f'{k}\n')
            p.stdin.flush()
            answers[name].append(json.loads(p.stdout.readline()))
    for _, p in procs:
        p.stdin.close()
        p.wait()
    return answers
