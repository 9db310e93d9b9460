"""Scene-generation and object-loading timings for bench/README.md.

    .venv/bin/python bench/bench_scenes.py [--scenes 20] [--ycb ../shared/data/ycb] [--markdown]

Each figure is wall time on this machine, one process, one thread of PyBullet. Object loading is
timed on fresh (uncached) records; scene generation is timed with the library already loaded, as
``pickplan scenes`` sees it after its first scene.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time

import numpy as np

from pickplan.core import objects
from pickplan.core import objects_builtin
from pickplan.sim import scenes
from pickplan.sim import scene_sets


def _timed(fn, *args):
    t = time.perf_counter()
    out = fn(*args)
    return out, time.perf_counter() - t


def bench_objects_builtin():
    rows = []
    for name in sorted(objects_builtin.BUILTIN_SPECS):
        (mesh, parts, spec), t_build = _timed(objects_builtin.build, name)
        (_, com, _), t_mass = _timed(objects.mass_properties, mesh, spec.mass)
        _, t_rest = _timed(objects.compute_resting_poses, mesh, com)
        rows.append((name, len(mesh.faces), len(parts), t_build, t_mass, t_rest))
    return rows


def bench_objects_ycb(root):
    import trimesh

    rows = []
    for name in sorted(d for d in os.listdir(root) if os.path.isfile(os.path.join(root, d, "mesh.stl"))):
        mesh, t_load = _timed(trimesh.load, os.path.join(root, name, "mesh.stl"), "stl")
        (_, com, _), t_mass = _timed(objects.mass_properties, mesh, objects.KNOWN_MASSES.get(name))
        _, t_rest = _timed(objects.compute_resting_poses, mesh, com)
        parts, t_parts = _timed(objects.read_obj_parts, os.path.join(root, name, "collision.obj"))
        rows.append((name, len(mesh.faces), len(parts), t_load + t_parts, t_mass, t_rest))
    return rows


def bench_scenes(lib, n, seed=0):
    for name in lib.names:  # load outside the timing
        lib.get(name)
    times, counts = [], []
    for s in scene_sets.scene_seeds(seed, n):
        scene, t = _timed(scenes.generate_scene, s, lib)
        times.append(t)
        counts.append(len(scene.objects))
    return times, counts


def _object_table(title, rows):
    out = [
        f"**{title}**",
        "",
        "| object | faces | convex parts | mesh + parts (ms) | mass props (ms) | resting poses (ms) |",
        "|---|---|---|---|---|---|",
    ]
    for name, faces, parts, t_build, t_mass, t_rest in rows:
        out.append(f"| {name} | {faces} | {parts} | {t_build * 1e3:.1f} | {t_mass * 1e3:.1f} | {t_rest * 1e3:.1f} |")
    tot = np.sum([[r[3], r[4], r[5]] for r in rows], axis=0) * 1e3
    out.append(f"| **all {len(rows)}** | | | {tot[0]:.0f} | {tot[1]:.0f} | {tot[2]:.0f} |")
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scenes", type=int, default=20, help="scenes per object set")
    ap.add_argument("--ycb", default=os.path.join(os.path.dirname(__file__), "..", "..", "shared", "data", "ycb"))
    args = ap.parse_args(argv)
    ycb = os.path.abspath(args.ycb)
    have_ycb = os.path.isdir(ycb)

    lines = _object_table("built-in objects (procedural)", bench_objects_builtin())
    if have_ycb:
        lines += [""] + _object_table(f"YCB objects ({ycb})", bench_objects_ycb(ycb))
    lines += [
        "",
        "| object set | scenes | objects per scene (mean) | s per scene (mean) | median | worst |",
        "|---|---|---|---|---|---|",
    ]
    sets = [("built-in", objects.library("builtin"))] + ([("YCB", objects.library(ycb))] if have_ycb else [])
    for label, lib in sets:
        times, counts = bench_scenes(lib, args.scenes)
        lines.append(
            f"| {label} | {len(times)} | {np.mean(counts):.1f} | {np.mean(times):.3f} | "
            f"{statistics.median(times):.3f} | {max(times):.3f} |"
        )
    if not have_ycb:
        lines.append(f"\n(YCB rows skipped: no folder at {ycb})")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
