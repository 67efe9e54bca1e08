"""Write sik_node's parameter table into docs/interfaces.md from ``sik_ros.ros.params.SPECS``.

The table lies between ``<!-- begin: parameters -->`` and ``<!-- end: parameters -->``; with
``--check`` nothing is written and the exit status says whether it is up to date.

    python scripts/params_table.py [--check]
"""

import argparse
from pathlib import Path
import sys

from sik_ros.ros.params import markdown_table

DOC = Path(__file__).resolve().parents[1] / 'docs' / 'interfaces.md'
BEGIN, END = '<!-- begin: parameters -->\n', '<!-- end: parameters -->'


def rendered(text: str) -> str:
    """``text`` with its parameter table made anew."""
    head, sep, rest = text.partition(BEGIN)
    _, sep2, tail = rest.partition(END)
    if not sep or not sep2:
        raise SystemExit(f'params_table: {DOC} has no {BEGIN.strip()} ... {END} block')
    return head + BEGIN + markdown_table() + END + tail


def main() -> int:
    """Rewrite (or check) the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--check', action='store_true', help='only say whether it is current')
    args = parser.parse_args()
    text = DOC.read_text()
    new = rendered(text)
    if args.check:
        if new != text:
            print(f'params_table: {DOC} is stale (run python scripts/params_table.py)',
                  file=sys.stderr)
            return 1
        return 0
    DOC.write_text(new)
    return 0


if __name__ == '__main__':
    sys.exit(main())
