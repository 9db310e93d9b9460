"""``pickplan observe``: render depth observations of a scene from cameras around the table."""

from __future__ import annotations

import argparse

from pickplan.cli.exit_codes import OutputKind
from pickplan.sim.observe import CameraRig, render_observation
from pickplan.sim.scenes import Scene


def add_observe_commands(subparsers) -> None:
    p = subparsers.add_parser("observe", help="render depth images of a scene (an observation .npz for planning)")
    p.add_argument("--scene", required=True, help="scene JSON")
    p.add_argument("--views", type=int, default=3, help=f"cameras (1 to {len(CameraRig().azimuths_deg)})")
    p.add_argument("--noise", type=float, default=0.0, help="depth noise sigma in metres (e.g. 0.002)")
    p.add_argument("--seed", type=int, default=0, help="seed of the depth noise")
    p.add_argument("--out", required=True, help="observation file (.npz)")
    p.set_defaults(handler=run_observe, out_kind=OutputKind.file)


def run_observe(args: argparse.Namespace) -> int:
    obs = render_observation(Scene.load(args.scene), views=args.views, noise=args.noise, seed=args.seed)
    obs.save(args.out)
    valid = (obs.depth > 0).mean()
    print(
        f"wrote {args.out}: {obs.views} view(s) of {obs.depth.shape[2]} x {obs.depth.shape[1]}, "
        f"{100 * valid:.0f} % pixels with depth, target in {int(obs.target_mask.sum())} pixels"
    )
    return 0
