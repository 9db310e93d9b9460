"""`pickplan metamodel build|compare`.

    pickplan metamodel build --part mesh.stl --density 800 --quick --out /tmp/mm   (a user's closed mesh)

    python -m pickplan.pickup.cli metamodel build --quick --out /tmp/mm
    python -m pickplan.pickup.cli metamodel compare --quick --out /tmp/mm

build writes <out>/metamodel_<part>.json (GSBs with their samples, probability grids and
surfaces for the low / medium / high uncertainty levels) and <out>/<part>_rho.md.
compare reuses those files when present (else builds), simulates extensive sampling and
writes <out>/<part>_comparison.{md,csv,json} and <out>/<part>_comparison.png. Its
reference poses come from --reference-seed (default 0), not from the build's --seed.
"""

from __future__ import annotations

import argparse
import os
import sys
from dataclasses import replace
from typing import Optional

import numpy as np

from pickplan.cli.exit_codes import run_command
from pickplan.core.errors import InputError
from pickplan.core.io import write_text
from pickplan.cli.output import add_verbosity_options, configure_logging, level_of
from pickplan.pickup.metamodel.active import RhoModel
from pickplan.pickup.metamodel.mesh_part import part_from_mesh
from pickplan.pickup.metamodel.build import build_metamodel
from pickplan.pickup.metamodel.model import BuildConfig, MetaModel
from pickplan.pickup.metamodel.parts import PARTS
from pickplan.pickup.metamodel.compare import compare, plot_comparison, summarize, write_results

DEFAULT_OUT = os.path.join("results", "metamodel")


def _common(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--parts", nargs="+", default=sorted(PARTS), choices=sorted(PARTS), help="parts to model (default: all)"
    )
    p.add_argument("--quick", action="store_true", help="CI mode: 2x2 speed grid, small budgets")
    p.add_argument("--out", default=DEFAULT_OUT, help=f"output directory (default {DEFAULT_OUT})")
    p.add_argument("--seed", type=int, default=0, help="seed of the meta-model build")
    p.add_argument("--workers", type=int, default=1, help="simulation worker processes")
    p.add_argument("--ray", action="store_true", help="run simulations on Ray (needs ray)")
    p.add_argument("--budget", type=int, default=None, help="simulations per boundary (default 300, quick 80)")
    p.add_argument(
        "--rho-model",
        choices=[m.value for m in RhoModel],
        default=RhoModel.gp.value,
        help="rho per boundary: GP classification of the samples (default) or the calibrated SVM success depth",
    )
    p.add_argument(
        "--no-lapse",
        action="store_true",
        help="GP rho: do not cap each pose's probability at 1 - the part's lapse rate (the failures no pose explains)",
    )


def add_metamodel_commands(subparsers, help: Optional[str] = None) -> argparse.ArgumentParser:
    """Register `metamodel build` and `metamodel compare` on an argparse subparsers object."""
    mm = subparsers.add_parser("metamodel", help=help)
    sub = mm.add_subparsers(dest="metamodel_command", required=True)
    b = sub.add_parser("build", help="learn the GSBs and fit rho_sigma(S_g, S_c)")
    _common(b)
    b.add_argument(
        "--part",
        default=None,
        metavar="MESH",
        help="a closed mesh (STL, OBJ, ...; metres) to model instead of the built-in parts",
    )
    b.add_argument("--mass", type=float, default=None, help="the mesh part's mass (kg)")
    b.add_argument("--density", type=float, default=None, help="... or its density (kg/m^3)")
    b.add_argument("--friction", type=float, default=0.6, help="the mesh part's lateral friction")
    b.add_argument("--smoke", action="store_true", help="tests: the smallest build that runs every step (rough rho)")
    b.set_defaults(func=cmd_build)
    c = sub.add_parser("compare", help="compare with extensive sampling (Fig. 3, table)")
    _common(c)
    c.add_argument(
        "--samples", type=int, default=None, help="direct simulations per pair and level (default 2000, quick 100)"
    )
    c.add_argument("--rebuild", action="store_true", help="rebuild even if a model file exists")
    c.add_argument("--cache", default=None, help="directory caching the extensive-sampling labels (reruns are free)")
    c.add_argument(
        "--reference-seed",
        type=int,
        default=0,
        help="seed of the extensive-sampling poses (default 0), independent of "
        "--seed: models built with different seeds are measured against the "
        "same references, which a --cache directory then reuses",
    )
    c.set_defaults(func=cmd_compare)
    return mm


def _config(args) -> BuildConfig:
    cfg = BuildConfig.smoke() if getattr(args, "smoke", False) else BuildConfig.quick() if args.quick else BuildConfig()
    if args.budget is not None:
        cfg = replace(cfg, active=replace(cfg.active, budget=args.budget))
    return replace(cfg, rho_model=args.rho_model, lapse_ceiling=not args.no_lapse)


def model_path(out: str, part: str) -> str:
    return os.path.join(out, f"metamodel_{part}.json")


def rho_markdown(mm: MetaModel) -> str:
    lines = [f"rho for {mm.part_name}: rows S_g, columns S_c (grid Monte-Carlo / surface)", ""]
    sims = [bm.n_simulations for bm in mm.boundaries.values()]
    bms = [bm for _, bm in sorted(mm.boundaries.items())]
    lines.append(
        f"simulations per boundary: mean {np.mean(sims):.0f}, max {max(sims)}, "
        f"converged {sum(bm.converged for bm in bms)}/{len(bms)}; "
        f"D_FT / width: " + ", ".join(f"{bm.d_ft:.3f}/{bm.width:.3f}" for bm in bms)
    )
    if mm.lapse > 0:
        lines.append(
            f"lapse (failures no pose explains; each pose's probability is capped at 1 - lapse): {mm.lapse:.2%}"
        )
    for lv in mm.levels:
        lines += [
            "",
            f"### {lv.name}: sigma_r = {lv.sigma_r * 1000:.0f} mm, sigma_phi = {np.degrees(lv.sigma_phi):.0f} deg",
            "",
            "| S_g \\ S_c | " + " | ".join(f"{s:.2f}" for s in mm.sc_grid) + " |",
            "|---" * (len(mm.sc_grid) + 1) + "|",
        ]
        surf = mm.surfaces[lv.name]
        for i, sg in enumerate(mm.sg_grid):
            cells = [f"{mm.rho_grids[lv.name][i, j]:.3f} / {surf(sg, sc):.3f}" for j, sc in enumerate(mm.sc_grid)]
            lines.append(f"| {sg:.2f} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def _build_one(args, part) -> MetaModel:
    """Builds and writes the meta-model of a part (a built-in name or a Part)."""
    mm = build_metamodel(
        part, _config(args), seed=args.seed, workers=args.workers, use_ray=args.ray, progress=not args.quiet
    )
    mm.save(model_path(args.out, mm.part_name))
    write_text(os.path.join(args.out, f"{mm.part_name}_rho.md"), rho_markdown(mm))
    print(f"wrote {model_path(args.out, mm.part_name)}")
    return mm


def cmd_build(args) -> int:
    if args.part is None and (args.mass is not None or args.density is not None):
        raise InputError("--mass and --density describe a mesh part: give --part MESH", field="--mass/--density")
    parts = [part_from_mesh(args.part, args.mass, args.density, args.friction)] if args.part else args.parts
    os.makedirs(args.out, exist_ok=True)
    for part in parts:
        _build_one(args, part)
    return 0


def cmd_compare(args) -> int:

    os.makedirs(args.out, exist_ok=True)
    n = args.samples if args.samples is not None else (100 if args.quick else 2000)
    for part in args.parts:
        path = model_path(args.out, part)
        mm = MetaModel.load(path) if os.path.exists(path) and not args.rebuild else _build_one(args, part)
        rows = compare(
            mm,
            n_samples=n,
            seed=args.reference_seed,
            workers=args.workers,
            use_ray=args.ray,
            progress=not args.quiet,
            cache_dir=args.cache,
        )
        paths = write_results(rows, args.out, part, reference_seed=args.reference_seed)
        print(f"wrote {paths['md']}")
        try:
            png = plot_comparison(rows, os.path.join(args.out, f"{part}_comparison.png"), title=part)
            print(f"wrote {png}")
        except ImportError:
            print("matplotlib not installed: skipped the plot", file=sys.stderr)
        for lv, s in summarize(rows).items():
            print(
                f"{part} {lv}: mean |active-ext| {s['mean_abs_error_active']:.3f}, "
                f"worst under {s['max_under_active']:+.3f}, "
                f"max over {s['max_over_active']:+.3f}; surface mean |err| "
                f"{s['mean_abs_error_surface']:.3f}, max over {s['max_over_surface']:+.3f}"
            )
    return 0


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="pickplan")
    sub = parser.add_subparsers(dest="command", required=True)
    add_metamodel_commands(sub)
    add_verbosity_options(parser)
    args = parser.parse_args(argv)
    configure_logging(level_of(args))
    return run_command(args.command, args.func, args)


if __name__ == "__main__":
    sys.exit(main())
