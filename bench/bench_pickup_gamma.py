"""Success probability vs gamma (bench/PICKUP.md, "Success probability vs gamma"): case 1 of Sec. VI
solved by the successive refinement for several thresholds gamma on the stand-in surface
`synthetic_rho` at sigma = 7 mm / 10 deg; prints a Markdown table (rho, S_g, T, wall and CPU time).

    .venv/bin/python bench/bench_pickup_gamma.py [--m 6] [--case 1] [--gammas 0.9,0.94,...]   # after make install
"""

import argparse
import os

from pickplan.pickup.nlp import cases
from pickplan.pickup.nlp import planner


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--case", type=int, default=1)
    ap.add_argument("--m", type=int, default=6, help="samples per interval")
    ap.add_argument("--gammas", default="0.90,0.94,0.96,0.98,0.99")
    a = ap.parse_args()
    robot = planner.mobile_ur5()
    st = planner.PlannerSettings(samples_per_interval=a.m)
    print(f"load average {os.getloadavg()[0]:.1f}")
    print("| gamma | status | rho(S_g, S_c) | S_g (m/s) | T (s) | solve wall / CPU (s) | direct track chosen |")
    print("|---|---|---|---|---|---|---|")
    for g in (float(v) for v in a.gammas.split(",")):
        pb = cases.make_problem(robot, a.case, sigma="medium", gamma=g)
        p = planner.plan(robot, pb, st)
        ok = p.success
        rho = f"{pb.rho.value(p.S_g, p.S_c):.3f}" if ok else "-"
        status = p.status if ok else f"{p.status} (stage {p.stages_completed + 1}; the last good stage is returned)"
        print(
            f"| {g:.2f} | {status} | {rho} | {p.S_g:.3f} | {p.T:.2f} | {p.total_seconds:.2f} / {p.total_cpu_seconds:.2f} | "
            f"{'yes' if p.direct_chosen else 'no'} |"
            if ok
            else f"| {g:.2f} | {status} | - | - | - | {p.total_seconds:.2f} / {p.total_cpu_seconds:.2f} | - |"
        )


if __name__ == "__main__":
    main()
