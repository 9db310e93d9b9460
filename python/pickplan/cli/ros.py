"""``pickplan ros serve | call``: the ROS 2 node (``pickplan.ros``; needs the ``ros`` extra).

  pickplan ros serve --robot panda [--transport shm] [--ros-args -p cameras:=[cam0] -p cam0.pose:=[...]]
  pickplan ros call [--point X Y Z] [--out timed.json]      plan once, print the status, save the trajectory
  pickplan ros call --place X0 Y0 Z0 X1 Y1 Z1               pick and place in that box (base frame)
  pickplan ros replay --observation obs.npz                 an observation as cameras + joint states (no robot)

The ROS modules are imported when a command runs, so the CLI works without the extra; a missing
extra is a one-line error naming it (exit code 2).
"""

from __future__ import annotations

import argparse
import importlib
import os

from pickplan.cli.exit_codes import ExitCode
from pickplan.cli.robots import ROBOT_HELP
from pickplan.core.errors import InputError
from pickplan.ros.extra import configure_transport, require_ros

TRANSPORT_HELP = "default: ROS's (UDP); shm: shared memory only, one machine (both ends must use it)"


def _ros(module: str):
    """``pickplan.ros.<module>``, imported when a command runs: it needs the optional ros extra."""
    require_ros()
    return importlib.import_module(f"pickplan.ros.{module}")


def add_ros_commands(subparsers) -> None:
    ros = subparsers.add_parser(
        "ros", help="the ROS 2 node: plan picks from depth cameras (pip install 'pickplan[ros]')"
    )
    sub = ros.add_subparsers(dest="ros_command", required=True)
    serve = sub.add_parser(
        "serve",
        help="start the node (Ctrl-C stops it); ROS parameters follow --ros-args (-p NAME:=VALUE, --params-file FILE)",
    )
    serve.add_argument("--robot", default="panda", help=ROBOT_HELP)
    serve.add_argument("--transport", default="default", choices=("default", "shm"), help=TRANSPORT_HELP)
    serve.set_defaults(handler=run_serve)
    call = sub.add_parser("call", help="ask a running node to plan; prints its status (exit 1: no plan)")
    call.add_argument(
        "--point",
        type=float,
        nargs=3,
        default=None,
        metavar=("X", "Y", "Z"),
        help="target: the object nearest this point (base frame, m); default: the node's current target",
    )
    call.add_argument(
        "--place",
        type=float,
        nargs=6,
        default=None,
        metavar=("X0", "Y0", "Z0", "X1", "Y1", "Z1"),
        help="pick and place: put the object in this box (base frame, m; its floor on a support)",
    )
    call.add_argument(
        "--orientation",
        default=None,
        choices=("upright", "stable"),
        help="with --place: upright (as it stood; the node's default) or any stable resting pose",
    )
    call.add_argument("--server", default="/pickplan", help="the node's name (default /pickplan)")
    call.add_argument("--transport", default="default", choices=("default", "shm"), help=TRANSPORT_HELP)
    call.add_argument("--timeout", type=float, default=120.0, help="seconds to wait for the node and its answer")
    call.add_argument("--out", default=None, help="save the trajectory as a timed trajectory (.json or .npz)")
    call.set_defaults(handler=run_call)
    replay = sub.add_parser(
        "replay",
        help="publish an observation (.npz) as depth cameras and the robot at its start, "
        "to try the node without a robot; prints the node's camera parameters",
    )
    replay.add_argument("--observation", required=True, help="observation .npz (pickplan observe)")
    replay.add_argument("--robot", default="panda", help=ROBOT_HELP)
    replay.add_argument("--encoding", default="32FC1", choices=("32FC1", "16UC1"), help="depth encoding")
    replay.add_argument("--rate", type=float, default=5.0, help="frames per second")
    replay.add_argument("--transport", default="default", choices=("default", "shm"), help=TRANSPORT_HELP)
    replay.set_defaults(handler=run_replay)


def run_serve(args: argparse.Namespace) -> int:
    configure_transport(args.transport, os.environ)
    return _ros("node").run(args.robot, ["pickplan"] + list(args.ros_args))


def run_call(args: argparse.Namespace) -> int:
    configure_transport(args.transport, os.environ)
    client_mod = _ros("client")
    with client_mod.PickClient(args.server) as client:
        if not client.wait_for_server(args.timeout):
            raise InputError(f"no pickplan node answers at {args.server} within {args.timeout} s", field="--server")
        if args.place is not None or args.orientation is not None:
            reply = client.pick_and_place(args.point, args.place, args.orientation, timeout=args.timeout)
        else:
            reply = client.plan(args.point, timeout=args.timeout)
    print(reply.message)
    for name, t0, t1 in reply.segments:
        print(f"  {name:<9} {t0:7.3f} - {t1:7.3f} s")
    if reply.success and args.out and reply.trajectory is not None:
        msg = reply.trajectory
        _ros("convert").timed_trajectory(msg, list(msg.joint_names)).save(args.out)
        print(f"wrote {args.out}: {len(msg.points)} points of {', '.join(msg.joint_names)}")
    return ExitCode.OK if reply.success else ExitCode.NO_PLAN


def run_replay(args: argparse.Namespace) -> int:
    from pickplan.core import robots
    from pickplan.core.observation import Observation

    if not args.rate > 0:
        raise InputError(f"expected frames per second > 0, got {args.rate}", field="--rate")
    observation = Observation.load(args.observation)
    robot = robots.load_robot(args.robot)
    configure_transport(args.transport, os.environ)
    client_mod, replay_mod = _ros("client"), _ros("replay")
    with client_mod.PickClient(name="pickplan_replay") as client:
        replay = replay_mod.ObservationReplay(
            client.node, observation, robot, robot.ready_configuration, [args.encoding] * observation.views
        )
        print(
            "start the node with: pickplan ros serve --robot",
            args.robot,
            "--ros-args",
            " ".join(a if a == "-p" else f"'{a}'" for a in replay.node_arguments()),
            flush=True,
        )
        client.node.create_timer(1.0 / args.rate, replay.publish)
        try:
            client.spin(float("inf"))
        except KeyboardInterrupt:
            pass
    return ExitCode.OK
