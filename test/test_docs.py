"""The docs speak of the product, and their benchmark tables are the JSON results' own."""

from pathlib import Path
import re
import subprocess
import sys

import pytest

REPO = Path(__file__).resolve().parents[1]
DOCS = [REPO / 'README.md', REPO / 'CHANGELOG.md', *sorted((REPO / 'docs').glob('*.md'))]
#: Words of a lab notebook, not of a product's docs: rounds of work, a private tracker's
#: numbers, the absolute paths of the machine something was measured on.
NOTEBOOK = re.compile(r'\b(first|second|third|fourth|fifth|sixth|seventh|eighth|ninth|tenth|'
                      r'eleventh|twelfth) session\b|\bsessions?\b|\bissues? #?\d+|/work/|'
                      r'/home/|/tmp/pytest', re.I)


def test_docs_name_no_rounds_issues_or_machine_paths():
    """README, CHANGELOG and docs/ name no work rounds, issue numbers or absolute paths."""
    found = [f'{doc.relative_to(REPO)}:{n}: {line.strip()[:100]}'
             for doc in DOCS for n, line in enumerate(doc.read_text().splitlines(), 1)
             if NOTEBOOK.search(line)]
    assert not found, 'notebook words in the docs:\n' + '\n'.join(found)


@pytest.mark.e2e
def test_benchmark_tables_match_their_json():
    """Every rendered table equals what bench/render.py makes of docs/results/*.json."""
    run = subprocess.run([sys.executable, str(REPO / 'bench' / 'render.py'), '--check'],
                         cwd=REPO, capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, run.stderr + run.stdout
