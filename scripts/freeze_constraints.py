"""Print requirements/constraints.txt for the venv this runs in: every pip-installed package, ==.

Usage: .venv/bin/python scripts/freeze_constraints.py > requirements/constraints.txt

Leaves out sik_ros itself and the distributions that the ROS wheels register inside their own
files (rclpy, std_msgs, ...: pip did not install them, and PyPI has no such wheels), and drops
local version labels (torch 2.13.0+cpu is pinned as 2.13.0, which pip resolves to the CPU build
that lies on the machines' disk).
"""

import importlib.metadata
import re

HEADER = """\
# Every Python distribution in the set-up venv, pinned exactly (a pip constraints file).
# Regenerate after changing requirements/main.txt: see docs/design.md, "Set-up".
# torch is the CPU build: on these machines `torch==2.13.0` takes 2.13.0+cpu from the local disk.
"""


def main() -> None:
    """Print the constraints file."""
    pins = {}
    for dist in importlib.metadata.distributions():
        if (dist.read_text('INSTALLER') or '').strip() != 'pip':
            continue
        name = re.sub(r'[-_.]+', '-', dist.metadata['Name']).lower()
        if name == 'sik-ros':
            continue
        pins[name] = dist.version.split('+', 1)[0]
    print(HEADER + ''.join(f'{name}=={pins[name]}\n' for name in sorted(pins)), end='')


if __name__ == '__main__':
    main()
