"""Writes omg_reference.npz: OMG plans made by the planner as it was before issue 24's speed work
(main at 50b7e25: every other change of session 10 merged, issue 24 not yet; first made at 072e124 before the any-object goal set changed goal sets), which test_omg_equivalence.py compares the current planner against.

    PYTHONPATH=/work/main/python /work/main/.venv/bin/python tests/data/make_omg_reference.py

Session 20 moved the Panda's finger pads to the one derivation every gripper uses (C-Space ISF pulls
them onto the object); ``--rebase`` replanned the stored scenes and grasps with the test's settings: every
goal set, status, grasp and iteration count stayed as recorded; trajectories moved by at most 4.8e-3 rad
(ISF's refined grasp); in s4full ISF's refinement of the chosen grasp no longer pays, so the grasp's own
goal (2) is followed instead of its refined copy (10), the trajectory within 3.6e-6 rad of the old one.

Built-in-object scenes (seeds 1-4; two run all 50 iterations without pre-termination), their antipodal grasps (40, seed 0), MD selection
with ISF, paper settings otherwise. Stored per scene: the scene JSON, the grasps, the goal set,
the trajectory, the chosen goal and grasp, the goals chosen per iteration and the status.
"""

import json
import os

import numpy as np

from pickplan.omg import grasps as grasps_mod
from pickplan.omg import planner as omg
from pickplan.sim import scenes

CASES = ((1, True), (2, True), (3, True), (2, False), (4, False))  # (scene seed, pre-terminate)


def main():
    out = {}
    for seed, pre_terminate in CASES:
        settings = omg.OMGSettings(pre_terminate=pre_terminate)
        scene = scenes.generate_scene(seed)
        planner = omg.OMGPlanner(None, scene, settings)
        grasps = grasps_mod.grasp_set(planner.world().target_model, "antipodal", 40, seed=0).poses
        r = planner.plan(grasps=grasps)
        p = f"s{seed}{'' if pre_terminate else 'full'}_"
        out[p + "scene"] = np.array(json.dumps(scene.to_dict()))
        out[p + "grasps"] = grasps
        out[p + "goal_set"] = r.goal_set
        out[p + "trajectory"] = r.trajectory
        out[p + "goals_chosen"] = np.asarray(r.history["goal"], dtype=int)
        out[p + "scalars"] = np.array([r.grasp_index, r.goal_source, r.iterations, int(r.refined)])
        out[p + "status"] = np.array(str(r.status.value))
        print(seed, r.status, r.iterations, r.grasp_index, len(r.goal_set))
    np.savez_compressed(os.path.join(os.path.dirname(os.path.abspath(__file__)), "omg_reference.npz"), **out)


def rebase():
    """Replan the stored scenes and grasps as the test does; the goal sets and statuses must stay, the rest is stored."""
    import sys

    sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "python"))
    from test_omg_equivalence import CASES as TEST_CASES
    from test_omg_equivalence import REFERENCE, plan_case

    with np.load(REFERENCE, allow_pickle=False) as z:
        out = {k: z[k] for k in z.files}
    for prefix, pre_terminate in TEST_CASES:
        p = prefix + "_"
        r = plan_case(out, p, pre_terminate, cache=None)
        assert np.array_equal(r.goal_set, out[p + "goal_set"]) and str(r.status.value) == str(out[p + "status"])
        scalars = np.array([r.grasp_index, r.goal_source, r.iterations, int(r.refined)])
        print(
            prefix,
            "trajectory moved by",
            float(np.abs(r.trajectory - out[p + "trajectory"]).max()),
            "| goals chosen",
            "unchanged"
            if np.array_equal(r.history["goal"], out[p + "goals_chosen"])
            else f"{out[p + 'goals_chosen'][-1]} -> {r.history['goal'][-1]}",
            "| grasp, source, iterations, refined",
            out[p + "scalars"].tolist(),
            "->",
            scalars.tolist(),
        )
        out[p + "trajectory"], out[p + "scalars"] = r.trajectory, scalars
        out[p + "goals_chosen"] = np.asarray(r.history["goal"], dtype=int)
    np.savez_compressed(REFERENCE, **out)


if __name__ == "__main__":
    import sys

    rebase() if "--rebase" in sys.argv[1:] else main()
