"""Writes omg_reference.npz: OMG plans made by the planner as it was before issue 24's speed work
(main at 50b7e25: every other change of session 10 merged, issue 24 not yet; first made at 072e124 before the any-object goal set changed goal sets), which test_omg_equivalence.py compares the current planner against.

    PYTHONPATH=/work/main/python /work/main/.venv/bin/python tests/data/make_omg_reference.py

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


if __name__ == "__main__":
    main()
