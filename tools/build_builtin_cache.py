"""Regenerate the cache entries pickplan ships (assets/cache: the built-in objects' default grasp sets
for the shipped robots' grippers, with their SHA-256 in manifest.json). Run by `make builtin-cache`;
pickplan must be installed (`make install`). Commit the result.

    python tools/build_builtin_cache.py [--objects 005_tomato_soup_can,...] [--workers 2]
"""

from __future__ import annotations

import argparse
import logging
import os
import sys
import time

from pickplan.omg import shipped


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--out",
        default=os.path.join(os.path.dirname(__file__), "..", "assets", "cache"),
        help="the shipped cache folder (default: the source tree's assets/cache)",
    )
    parser.add_argument("--objects", default="", help="comma-separated built-in objects to redo (default: all)")
    parser.add_argument("--workers", type=int, default=1)
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    names = [n for n in args.objects.split(",") if n] or None
    started = time.perf_counter()
    entries = shipped.build(os.path.abspath(args.out), names, workers=args.workers, progress=True)
    print(f"{len(entries)} entries in {os.path.abspath(args.out)} ({time.perf_counter() - started:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
