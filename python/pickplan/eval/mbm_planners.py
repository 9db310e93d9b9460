"""The planners of ``bench mbm``, each as ``plan(world, problem, start, goal) -> PlanOutcome`` with its
own planning time: pickplan's motion planner and its pieces, OMPL's RRT-Connect (PyPI ``ompl``; its
validity test is our FCL checker, called from Python) and VAMP's (``vamp``, an optional extra built by
``../shared/tools/vamp/build-vamp.sh``; its own sphere model of the Panda and its own primitives)."""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from typing import Callable, Dict, Sequence, Tuple

import numpy as np

from pickplan.core.settings import Option
from pickplan.core.shapes import ShapeKind
from pickplan.eval.baselines import _ompl as load_ompl
from pickplan.eval.baselines import _seed_ompl, ompl_setup
from pickplan.omg.motion import MotionSettings, RrtSettings, Smoothing, plan_chomp, plan_motion


class MbmPlanner(Option):
    pickplan = "pickplan"  # straight line, else RRT-Connect + shortcuts, then CHOMP (the default)
    pickplan_rrt = "pickplan-rrt"  # the same without CHOMP smoothing
    pickplan_sampled = "pickplan-sampled"  # the default with the sampled motion check (1 cm), not the proof
    chomp = "chomp"  # CHOMP from the straight line only (no sampling)
    chomp_multi = "chomp-multi"  # CHOMP from several initializations (no sampling)
    ompl = "ompl"  # OMPL RRT-Connect + its simplification, our FCL checker
    vamp = "vamp"  # VAMP RRT-Connect + its simplification (optional extra)


@dataclass
class PlanOutcome:
    """What a planner gave for one problem: its own verdict, the path and the time it took."""

    solved: bool
    path: np.ndarray
    wall: float  # s
    cpu: float  # s of this thread's CPU
    source: str = ""  # how (straight, rrt, chomp, ...)
    detail: dict = field(default_factory=dict)


def timer() -> Tuple[float, float]:
    """(wall, thread CPU) start marks; ``elapsed(marks)`` gives both in seconds."""
    return time.perf_counter(), time.thread_time()


def elapsed(marks) -> Tuple[float, float]:
    return time.perf_counter() - marks[0], time.thread_time() - marks[1]


Plan = Callable[..., PlanOutcome]


def vamp_module():
    """The ``vamp`` module, or None when it is not built into this environment."""
    try:
        import vamp
    except ImportError:
        return None
    return vamp if hasattr(vamp, "panda") else None


def adapters(planners: Sequence[MbmPlanner], time_limit: float, seed: int) -> Dict[str, Plan]:
    """The planners asked for, by name; VAMP only when it imports (the summary says when it did not)."""
    out: Dict[str, Plan] = {}
    for p in planners:
        if p is MbmPlanner.vamp and vamp_module() is None:
            continue
        out[p.value] = _ADAPTERS[p](time_limit, seed)
    return out


def _ours(time_limit: float, seed: int, smoothing: Smoothing, certified: bool = True) -> Plan:
    base = MotionSettings(rrt=RrtSettings(time_limit=time_limit, certified=certified), smoothing=smoothing)

    def plan(world, problem, start, goal) -> PlanOutcome:
        s = replace(base, rrt=replace(base.rrt, seed=seed + problem.index))
        marks = timer()
        r = plan_motion(world, start, goal, s)
        wall, cpu = elapsed(marks)
        return PlanOutcome(
            r.solved,
            r.path,
            wall,
            cpu,
            r.source,
            {"rrt_ms": 1e3 * r.timings["rrt"], "chomp_ms": 1e3 * r.timings["chomp"], "status": r.status.value},
        )

    return plan


def _chomp(time_limit: float, seed: int, initializations: int) -> Plan:
    def plan(world, problem, start, goal) -> PlanOutcome:
        marks = timer()
        r = plan_chomp(world, start, goal, MotionSettings(), initializations, seed=seed + problem.index)
        wall, cpu = elapsed(marks)
        return PlanOutcome(r.solved, r.path, wall, cpu, r.source, {"status": r.status.value})

    return plan


def _ompl(time_limit: float, seed: int) -> Plan:
    ob, og, ou = load_ompl()
    _seed_ompl(ou, seed)

    def plan(world, problem, start, goal) -> PlanOutcome:
        robot, checker = world.robot, world.checker.native
        dof = robot.dof
        space, ss = ompl_setup(ob, og, robot, dof)
        q = np.zeros(dof)

        def valid(state) -> bool:
            for j in range(dof):
                q[j] = state[j]
            return not bool(checker.in_collision(q))  # a Python bool: OMPL's binding rejects numpy's

        ss.setStateValidityChecker(valid)
        si = ss.getSpaceInformation()
        si.setStateValidityCheckingResolution(0.005)  # OMPL's fraction of the space's extent (as baselines.py)
        a, b = space.allocState(), space.allocState()
        for j in range(dof):
            a[j], b[j] = float(start[j]), float(goal[j])
        ss.setStartAndGoalStates(a, b)
        ss.setPlanner(og.RRTConnect(si))
        marks = timer()
        solved = bool(ss.solve(time_limit)) and bool(ss.haveExactSolutionPath())
        path = np.zeros((0, dof))
        if solved:
            ss.simplifySolution(1.0)
            p = ss.getSolutionPath()
            path = np.array([[p.getState(i)[j] for j in range(dof)] for i in range(p.getStateCount())])
        wall, cpu = elapsed(marks)
        return PlanOutcome(solved, path, wall, cpu, "ompl")

    return plan


def _vamp(time_limit: float, seed: int) -> Plan:
    vamp = vamp_module()
    panda = vamp.panda
    rrtc = vamp.RRTCSettings()
    rrtc.max_iterations = 1_000_000
    simplify = vamp.SimplifySettings()

    def plan(world, problem, start, goal) -> PlanOutcome:
        env = vamp_environment(vamp, world.obstacles, cylinders_as_boxes=problem.set.startswith("box"))
        rng = panda.halton()
        marks = timer()
        result = panda.rrtc(list(map(float, start)), list(map(float, goal)), env, rrtc, rng)
        solved = bool(result.solved)
        path = np.zeros((0, len(start)))
        if solved:
            simple = panda.simplify(result.path, env, simplify, rng)
            path = np.asarray(simple.path.numpy(), dtype=float)
        wall, cpu = elapsed(marks)
        return PlanOutcome(solved, path, wall, cpu, "vamp", {"vamp_ns": int(result.nanoseconds)})

    return plan


def vamp_environment(vamp, obstacles, cylinders_as_boxes: bool = False):
    """VAMP's environment of the obstacles as VAMP's own MBM evaluation builds it
    (``vamp.problem_dict_to_vamp``): cuboids, spheres, cylinders as capsules (which enclose them), or
    as the boxes enclosing them in the box set (``cylinders_as_boxes``: VAMP does so there, as its
    top-down grasps would not pass a capsule's cap). Its Euler angles are extrinsic x-y-z (scipy's "xyz")."""
    from scipy.spatial.transform import Rotation

    env = vamp.Environment()
    for o in obstacles:
        T = np.asarray(o.pose, dtype=float)
        centre = [float(v) for v in T[:3, 3]]
        euler = [float(v) for v in Rotation.from_matrix(T[:3, :3]).as_euler("xyz")]
        s = o.shape
        if s.kind is ShapeKind.box:
            env.add_cuboid(vamp.Cuboid(centre, euler, [0.5 * v for v in s.size]))
        elif s.kind is ShapeKind.cylinder and cylinders_as_boxes:
            env.add_cuboid(vamp.Cuboid(centre, euler, [s.size[0], s.size[0], 0.5 * s.size[1]]))
        elif s.kind is ShapeKind.cylinder:
            env.add_capsule(vamp.Cylinder(centre, euler, s.size[0], s.size[1]))
        elif s.kind is ShapeKind.sphere:
            env.add_sphere(vamp.Sphere(centre, s.size[0]))
        else:
            raise ValueError(f"VAMP takes primitives only; obstacle {o.name!r} is a mesh")
    return env


_ADAPTERS = {
    MbmPlanner.pickplan: lambda t, s: _ours(t, s, Smoothing.chomp),
    MbmPlanner.pickplan_rrt: lambda t, s: _ours(t, s, Smoothing.none),
    MbmPlanner.pickplan_sampled: lambda t, s: _ours(t, s, Smoothing.chomp, certified=False),
    MbmPlanner.chomp: lambda t, s: _chomp(t, s, 1),
    MbmPlanner.chomp_multi: lambda t, s: _chomp(t, s, 8),
    MbmPlanner.ompl: _ompl,
    MbmPlanner.vamp: _vamp,
}
