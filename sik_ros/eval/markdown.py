"""Markdown helpers of the report: numbers, tables and verdicts against the paper."""

from typing import List, Optional, Sequence

import numpy as np


def fmt(v: Optional[float], nd: int = 2) -> str:
    """A number for a table with ``nd`` decimals; a dash for missing or NaN."""
    if v is None:
        return '—'
    v = float(v)
    return '—' if not np.isfinite(v) else f'{v:.{nd}f}'


def table(header: Sequence[str], rows: Sequence[Sequence]) -> List[str]:
    """A markdown table, as lines."""
    lines = ['| ' + ' | '.join(str(h) for h in header) + ' |',
             '|' + '|'.join('---' for _ in header) + '|']
    lines += ['| ' + ' | '.join(str(c) for c in r) + ' |' for r in rows]
    return lines


#: Relative margin within which a figure above the paper's counts as on a par with it.
PAR = 0.05


def verdict(ours: Optional[float], paper: float, unit: str, what: str, nd: int = 2) -> str:
    """A plain sentence: ours against the paper's figure, lower is better."""
    if ours is None or not np.isfinite(ours):
        return f'{what}: not measured.'
    unit = f' {unit}' if unit else ''
    figures = f'({fmt(ours, nd)}{unit} against {fmt(paper, nd)}{unit})'
    if ours > paper * (1 + PAR):
        return f'**{what}: ours is worse than the paper** {figures}.'
    if ours > paper:
        return f'{what}: ours is on a par with the paper, within {PAR:.0%} {figures}.'
    return f'{what}: ours is as good or better {figures}.'


# -- the report -----------------------------------------------------------------------------------
