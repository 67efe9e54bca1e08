"""Takes docs/figures/viewer.png: sik-view on the bundled Panda, photographed by headless Chromium.

Needs Debian's chromium (apt-get install -y chromium). Starts ``sik-view --robot panda``, opens
the page in headless Chromium driven over the DevTools protocol, waits for the scene in real
time (Chromium's --virtual-time-budget would age the page's websocket), closes the
software-rendering notice, and saves a PNG.

Usage: .venv/bin/python scripts/screenshot_viewer.py [--out docs/figures/viewer.png]
"""

import argparse
import base64
import json
import os
from pathlib import Path
import shutil
import subprocess
import sys
import tempfile
import time
import urllib.request

from websockets.sync.client import connect

FLAGS = ['--headless', '--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run',
         '--disable-background-networking', '--disable-component-update', '--disable-sync',
         '--enable-unsafe-swiftshader', '--hide-scrollbars', '--remote-debugging-port=0']
CLOSE_NOTICES = ("document.querySelectorAll('.mantine-Notification-root button')"
                 ".forEach(b => b.click())")


def wait_for(predicate, timeout: float, what: str):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        value = predicate()
        if value:
            return value
        time.sleep(0.5)
    sys.exit(f'screenshot_viewer: timed out waiting for {what}')


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--out', default='docs/figures/viewer.png')
    parser.add_argument('--port', type=int, default=8091)
    parser.add_argument('--size', default='1600,1000')
    parser.add_argument('--wait', type=float, default=20.0, help='rendering time [s]')
    args = parser.parse_args()
    chromium = shutil.which('chromium')
    if chromium is None:
        sys.exit('chromium not found (apt-get install -y chromium)')
    log = tempfile.NamedTemporaryFile('w+', suffix='.log')
    viewer = subprocess.Popen([sys.executable, '-m', 'sik_ros.cli.view', '--robot', 'panda',
                               '--port', str(args.port)], stdout=log, stderr=subprocess.STDOUT)
    profile = tempfile.mkdtemp()
    browser = None
    try:
        wait_for(lambda: 'Ctrl-C to stop' in Path(log.name).read_text(), 300, 'sik-view')
        browser = subprocess.Popen([chromium, *FLAGS, f'--user-data-dir={profile}',
                                    f'--window-size={args.size}', 'about:blank'],
                                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        port_file = Path(profile, 'DevToolsActivePort')
        wait_for(port_file.is_file, 60, 'Chromium')
        devtools = int(port_file.read_text().split()[0])
        with urllib.request.urlopen(f'http://127.0.0.1:{devtools}/json/list') as r:
            page = [t for t in json.load(r) if t['type'] == 'page'][0]
        with connect(page['webSocketDebuggerUrl'], max_size=None) as ws:
            ids = iter(range(1, 1000))

            def call(method: str, **params):
                msg_id = next(ids)
                ws.send(json.dumps({'id': msg_id, 'method': method, 'params': params}))
                while True:
                    reply = json.loads(ws.recv())
                    if reply.get('id') == msg_id:
                        return reply.get('result', {})
            width, height = (int(v) for v in args.size.split(','))
            call('Emulation.setDeviceMetricsOverride', width=width, height=height,
                 deviceScaleFactor=1, mobile=False)
            call('Page.navigate', url=f'http://127.0.0.1:{args.port}/')
            time.sleep(args.wait)
            call('Runtime.evaluate', expression=CLOSE_NOTICES)
            time.sleep(1.0)
            shot = call('Page.captureScreenshot', format='png')
        out = Path(args.out)
        tmp = out.with_name(out.name + '.tmp')
        tmp.write_bytes(base64.b64decode(shot['data']))
        os.replace(tmp, out)
        print(f'wrote {out}')
    finally:
        for proc in (browser, viewer):
            if proc is not None:
                proc.terminate()
                proc.wait(30)
        shutil.rmtree(profile, ignore_errors=True)


if __name__ == '__main__':
    main()
