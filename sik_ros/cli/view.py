"""``sik-view``: the ranked solutions for a target you drag, in the browser (no ROS needed)."""

import argparse
import threading
from typing import List, Optional

from sik_ros.cli import argv_or_default, Parser, run_cli
from sik_ros.errors import InvalidArgument


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of sik-view."""
    p = Parser(prog='sik-view', description='Serve a browser page showing the arm at the '
               'ranked solutions for a target you drag: the postures side by side or one by '
               'one with their errors, clearance and score, obstacles, a Cartesian path.')
    src = p.add_mutually_exclusive_group()
    src.add_argument('--robot', default=None,
                     help='a bundled robot (default: panda)')
    src.add_argument('--bundle', help='a bundle directory (from sik-build or sik-index)')
    p.add_argument('--host', default='127.0.0.1',
                   help='address to serve on (default: 127.0.0.1; 0.0.0.0 for every interface)')
    p.add_argument('--port', type=int, default=8080, help='TCP port (default: 8080)')
    return p


def main(argv: Optional[List[str]] = None) -> int:
    """Entry point of sik-view: serves until Ctrl-C."""
    args = build_parser().parse_args(argv_or_default(argv))
    if not 0 < args.port < 65536:
        build_parser().error(f'--port {args.port}: must be 1-65535')

    def body() -> int:
        from sik_ros.solver import SelectiveIK
        from sik_ros.viewer.app import Viewer
        ik = SelectiveIK.load(args.bundle or args.robot or 'panda')
        try:
            viewer = Viewer(ik, args.host, args.port)
        except OSError as exc:
            raise InvalidArgument(f'cannot serve on {args.host}:{args.port}: '
                                  f'{exc.strerror or exc}') from exc
        print(f'sik-view: {ik.bundle} at http://{args.host}:{viewer.server.get_port()} '
              f'(Ctrl-C to stop)', flush=True)
        try:
            threading.Event().wait()
        except KeyboardInterrupt:      # Ctrl-C or SIGTERM: the way a server stops
            pass
        finally:
            viewer.server.stop()
        return 0
    return run_cli('sik-view', body)


if __name__ == '__main__':
    raise SystemExit(main())
