"""The 3D view of one plan as a person sees it: plan a generated scene, write the self-contained page
(``pickplan view --html``) and take a headless-Chromium screenshot of it (software WebGL, network off).

    .venv/bin/python bench/view_screenshot.py --seed 1 --out bench/view.png

Prints the page's size and the time to build and to render it; keeps the page beside the picture
with ``--keep-page``.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
import warnings

from pickplan.core.io import write_json
from pickplan.omg.plan_file import plan_record
from pickplan.omg.planner import OMGPlanner, OMGSettings
from pickplan.sim.scenes import generate_scene
from pickplan.sim.view import view_folder
from pickplan.sim.view_page import screenshot, write_html


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=1, help="scene seed (built-in objects)")
    parser.add_argument("--out", default="bench/view.png")
    parser.add_argument("--keep-page", action="store_true", help="also keep the page (OUT with .html)")
    parser.add_argument("--moment", type=float, default=None, help="seconds into the motion (default: start)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = os.path.join(tmp, f"scene_{args.seed}")  # the page's title names the folder
        os.makedirs(folder)
        scene = generate_scene(args.seed)
        planner = OMGPlanner(None, scene, OMGSettings(grasp_kind="antipodal"))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            result = planner.plan()
        scene.save(os.path.join(folder, "scene.json"))
        write_json(os.path.join(folder, "plan.json"), plan_record(result, planner.world()))
        t0 = time.perf_counter()
        view = view_folder(folder)
        page = os.path.splitext(args.out)[0] + ".html" if args.keep_page else os.path.join(folder, "view.html")
        write_html(view, page)
        t1 = time.perf_counter()
        screenshot(page, args.out, moment=args.moment)
        t2 = time.perf_counter()
        print(
            f"scene {args.seed}: {result.status}; page {os.path.getsize(page) / 1e6:.2f} MB "
            f"({len(view.commands)} commands, {view.duration:.1f} s of motion) built in {t1 - t0:.1f} s; "
            f"screenshot {args.out} in {t2 - t1:.1f} s"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
