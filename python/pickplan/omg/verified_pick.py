"""A pick whose grasp held when lifted in physics: what a pick and place carries (``PickPlaceSettings.verify_pick``).

The grasp quality is computed on the object's mesh; the physics may see another model (a pitcher's 2 mm
lip, filled solid in its collision model) and C-Space ISF may move a grasp after it was judged. So the
grasp a plan ends at, as planned (refined or not), is lifted in PyBullet, the open hand coming in from
the goal set's standoff (``grasps.verify.lift_grasps``, each verdict cached on disk); while it falls, the
pick is planned again without it. One lift per pick when the first grasp holds: the goal set keeps all its
grasps (lifting each of them first cost seconds and cut the set the regrasp draws from). A pick that fails
its success test runs once more from a sampled start (``planner.sampled_retry``), on a tabletop too.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Callable, Optional, Tuple

import numpy as np

from pickplan.omg.goals import GoalSet
from pickplan.omg.grasps.verify import LiftVerdict, VerifySettings
from pickplan.omg.planner import PlanResult, PlanStatus, retries_sampled, sampled_retry


def verified_pick(
    planner, start, grasps, verify: Optional[VerifySettings], fell: set, clock: Callable[[], float]
) -> Tuple[PlanResult, Optional[GoalSet]]:
    """``planner.plan_with_goals(start, grasps=grasps)``, its grasp lifted in PyBullet (``verify``; None, or a
    world without the target's model: no lift) and planned again without each grasp that falls, at most
    ``verify.budget`` plans; a plan among them that misses its success test (the goals left are farther:
    a plan not smooth) is set aside with its grasp in the same way. ``fell`` receives the goal set's grasps
    (indices) that fell; the plan's
    ``grasp_index`` is into the goal set's grasps. Every plan's grasp fell: ``no_goals``, its reason saying so.
    ``timings``: the plans' ``total`` summed, and ``lift_verify`` (the lifts' seconds, 0 when cached)."""
    pick, goals = planner.plan_with_goals(start, grasps=grasps)
    world = planner.world()
    if not pick.success and not retries_sampled(world) and goals is not None and len(goals):
        # once more from a sampled start, as the planner does among furniture: a carry is worth the extra plan
        t = clock()
        retry = sampled_retry(planner.settings, world, pick.trajectory[0], goals, pick.timings, pick)
        retry.limits, retry.goal_reasons = pick.limits, pick.goal_reasons
        retry.timings["total"] = pick.timings.get("total", 0.0) + clock() - t
        pick = retry
    if verify is None or not pick.success or not hasattr(world, "lift_grasps"):
        return pick, goals
    verify = replace(verify, lift=replace(verify.lift, approach=planner.settings.goals.standoff))
    planned, lifting = pick.timings.get("total", 0.0), 0.0
    failing: set = set()  # grasps whose plan, after a grasp fell, failed its success test
    for plans in range(1, verify.budget + 1):
        if pick.success:
            t = clock()
            grasp = np.linalg.solve(world.target_pose, pick.hand_pose)  # as planned, in the target's frame
            verdict = world.lift_grasps(grasp[None], verify)[0]
            lifting += clock() - t
            if verdict is not LiftVerdict.fell:
                pick.timings.update(total=planned, lift_verify=lifting)
                return pick, goals
            fell.add(int(pick.grasp_index))
        else:  # the plan without the grasps that fell missed the success test (a far goal: not smooth)
            failing.add(int(pick.grasp_index))
        keep = np.setdiff1d(goals.grasp_index, list(fell | failing))
        if not len(keep) or plans == verify.budget:
            break
        pick = planner.plan(start, grasps=goals.grasps[keep])
        planned += pick.timings.get("total", 0.0)
        if pick.grasp_index < 0:  # no plan at all: nothing else to try
            break
        pick.grasp_index = int(keep[pick.grasp_index])  # an index into the goal set's grasps again
    if not pick.success and (pick.grasp_index < 0 or int(pick.grasp_index) in failing):
        pick.timings.update(total=planned, lift_verify=lifting)
        return pick, goals
    failed = PlanResult.unplanned(
        PlanStatus.no_goals,
        pick.trajectory[0],
        {"total": planned, "lift_verify": lifting},
        {LiftVerdict.fell.value: len(fell)},
        f"the grasps of {len(fell)} plans fell in a lift in PyBullet",
    )
    return failed, goals
