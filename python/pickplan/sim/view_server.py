"""meshcat's live server bound to one address: loopback (127.0.0.1) unless the user asks for another.

meshcat's own server (``meshcat.servers.zmqserver``) listens with its web server on every interface
(0.0.0.0 and [::]) whatever URL it prints, so anyone on the network could open the view. This runs
the same bridge with the web server bound to ``host`` only and its command port (ZMQ) always on
loopback: only this machine sends drawing commands.

Run as ``python -m pickplan.sim.view_server --host HOST`` by ``start_server``; it prints
``zmq_url=...`` and ``web_url=...`` as meshcat's server does.
"""

from __future__ import annotations

import argparse
import ipaddress
import subprocess
import sys
from typing import Tuple

from meshcat.servers.zmqserver import ZMQWebSocketBridge, match_web_url, match_zmq_url

LOOPBACK = "127.0.0.1"


def is_loopback(host: str) -> bool:
    """True for 127.0.0.0/8, ::1 and "localhost"."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def url_host(host: str) -> str:
    """``host`` as a URL writes it (IPv6 addresses in brackets)."""
    return f"[{host}]" if ":" in host else host


class _Bridge(ZMQWebSocketBridge):
    """meshcat's bridge with its web server listening on ``web_host`` only."""

    def __init__(self, web_host: str):
        self._web_host = web_host
        super().__init__(host=LOOPBACK)  # the ZMQ command port: this machine only
        self.web_url = f"http://{url_host(web_host)}:{self.fileserver_port}/static/"

    def make_app(self):
        app = super().make_app()
        listen = app.listen
        app.listen = lambda port, **kwargs: listen(port, address=self._web_host, **kwargs)
        return app


def start_server(host: str = LOOPBACK) -> Tuple[subprocess.Popen, str, str]:
    """(the server process, its ZMQ URL, its web URL); the process runs until killed."""
    proc = subprocess.Popen(
        [sys.executable, "-u", "-m", "pickplan.sim.view_server", "--host", host],
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        start_new_session=True,
    )
    line = ""
    while "zmq_url" not in line:
        line = proc.stdout.readline().strip().decode("utf-8")
        if proc.poll() is not None:
            raise OSError(f"the viewer's server did not start on {host} (exit code {proc.returncode})")
    zmq_url = match_zmq_url(line)
    web_url = match_web_url(proc.stdout.readline().strip().decode("utf-8"))
    return proc, zmq_url, web_url


def main() -> None:
    parser = argparse.ArgumentParser(description="meshcat's server with its web server on one address")
    parser.add_argument("--host", default=LOOPBACK)
    bridge = _Bridge(parser.parse_args().host)
    # the protocol to start_server, which reads these two lines from the pipe (not output for a person)
    sys.stdout.write(f"zmq_url={bridge.zmq_url}\nweb_url={bridge.web_url}\n")
    sys.stdout.flush()
    try:
        bridge.run()
    except KeyboardInterrupt:
        pass


if __name__ == "__main__":
    main()
