"""``pickplan view DIR``: a 3D view of a plan folder (``plan.json`` + ``scene.json``, as written by
``pickplan demo`` or ``pickplan plan --out``). Without ``--html`` it starts meshcat's server on this
machine, listening on loopback only (``--host ADDRESS`` for another, with a warning: anyone who can
reach it sees the view), prints its URL and runs until Ctrl-C; ``--html FILE`` writes a
self-contained page instead.

Wired into ``pickplan.cli.main`` through ``add_view_commands``.
"""

from __future__ import annotations

import argparse
import ipaddress
import socket
import sys

from pickplan.core.errors import InputError
from pickplan.sim.view import ViewSettings, view_folder
from pickplan.sim.view_page import serve, write_html
from pickplan.sim.view_server import LOOPBACK, is_loopback


def add_view_commands(subparsers) -> None:
    """Add ``view`` to a ``pickplan`` argparse sub-parser set."""
    p = subparsers.add_parser("view", help="3D view of a plan folder (live viewer, or --html for a page)")
    p.add_argument("folder", help="folder with plan.json and scene.json (pickplan demo / plan --out)")
    p.add_argument(
        "--html",
        default=None,
        metavar="FILE",
        help="write a self-contained page (opens from the file, no server or network) and exit",
    )
    p.add_argument("--open", action="store_true", help="also open the viewer in the default browser")
    p.add_argument(
        "--host",
        default=LOOPBACK,
        metavar="ADDRESS",
        help="address the live viewer listens on (default 127.0.0.1: this machine only; another "
        "address lets anyone who can reach it open the view)",
    )
    p.add_argument(
        "--seconds-per-waypoint",
        type=float,
        default=ViewSettings.seconds_per_waypoint,
        help="pace of the robot's motion in the view (plan.json has no timing)",
    )
    p.set_defaults(handler=run_view)


def run_view(args: argparse.Namespace) -> int:
    if not args.seconds_per_waypoint > 0:
        raise ValueError(f"--seconds-per-waypoint must be positive, got {args.seconds_per_waypoint}")
    view = view_folder(args.folder, ViewSettings(seconds_per_waypoint=args.seconds_per_waypoint))
    if args.html:
        path = write_html(view, args.html)
        print(f"wrote {path} ({len(view.commands)} drawing commands, {view.duration:.1f} s of motion)")
        if args.open:
            import webbrowser  # only when asked: a browser is no part of writing the page

            webbrowser.open(f"file://{path}", new=2)
        return 0
    check_host(args.host)
    if not is_loopback(args.host):
        print(
            f"WARNING: the viewer listens on {args.host}, not only on this machine: anyone who can reach "
            f"{args.host} can open the view (no password)",
            file=sys.stderr,
        )
    serve(view, open_browser=args.open, host=args.host)
    return 0


def check_host(host: str) -> None:
    """InputError naming ``--host`` unless it is an IP address (or localhost) this machine can listen on."""
    try:
        family = socket.AF_INET6 if host != "localhost" and ipaddress.ip_address(host).version == 6 else socket.AF_INET
    except ValueError:
        raise InputError(f"expected an IP address such as 127.0.0.1 or ::1, got {host!r}", field="--host") from None
    try:
        with socket.socket(family, socket.SOCK_STREAM) as s:
            s.bind((host, 0))
    except OSError as exc:
        raise InputError(f"cannot listen on {host} ({exc.strerror})", field="--host") from None
