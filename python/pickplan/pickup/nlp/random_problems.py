"""Seeded random pick-up problems in a stated workspace (`pickplan pickup problems`), for benchmarks.

Each problem: the base drives from a start near the workspace's west edge to a goal near its east
edge, picking up a part on a pedestal off the route (the paper's cases, moved about). Feasible by
construction as far as cheap checks tell: start, goal and a ring of grasping-area base poses clear
the obstacles by the base's radius, the pillars keep a lane free around the part, and the part's
height is within the arm's reach. Whether a trajectory exists is the solver's to find.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional

import numpy as np

from pickplan.core.settings import Option
from pickplan.pickup.nlp.problem_file import (
    DEFAULT_ARM_START,
    GraspKind,
    PickupProblemSpec,
    SIGMAS,
    SphereObstacle,
    Uncertainty,
)

BASE_RADIUS = 0.3  # the base's body sphere (problem_file.BODY_SPHERES)
PEDESTAL_GAP = 0.17  # m from the grasp point down to the pedestal top sphere's centre


class Layout(Option):
    """Where the part stands relative to the base's route (issue 37's benchmark layouts)."""

    paper = "paper"  # beside the path, start facing the part, goal facing away (the paper's cases moved about)
    side = "side"  # 2-5 m to either side of the start-goal line, start and goal headings along the line
    behind = "behind"  # behind the start (2-5 m back along the line, +-2 m across), start heading along the line
    cluttered = "cluttered"  # the paper's geometry with 3-6 pillars between start, part and goal
    headings = "headings"  # the paper's geometry with uniformly random start and goal headings


@dataclass(frozen=True)
class Workspace:
    """Where problems are drawn (metres, radians, world frame); ``layout`` other than paper
    changes where the part stands and how the base heads (``Layout``)."""

    start_x: tuple = (-1.0, 1.0)
    start_y: tuple = (-1.0, 1.0)
    goal_x: tuple = (7.0, 9.0)
    goal_y: tuple = (-1.0, 1.0)
    heading_spread: float = math.pi / 4  # start yaw: towards the part +- this; goal yaw: from the part
    part_x: tuple = (2.0, 5.0)
    part_y: tuple = (3.0, 5.0)
    part_z: tuple = (0.4, 0.6)  # grasp height
    pillars: tuple = (0, 2)  # extra sphere obstacles beside the route (inclusive)
    pillar_radius: tuple = (0.15, 0.35)
    metamodel: str = "box"
    uncertainty: Uncertainty = Uncertainty.medium
    gamma: float = 0.96
    layout: Layout = Layout.paper

    def describe(self) -> str:
        if self.layout is not Layout.paper:
            return f"layout {self.layout.value}: {Layout.__doc__.splitlines()[0]} ({_LAYOUT_TEXT[self.layout]})"
        return (
            f"start x {self.start_x} y {self.start_y} (yaw: towards the part +- "
            f"{math.degrees(self.heading_spread):.0f} deg), goal x {self.goal_x} y {self.goal_y} (yaw: away "
            f"from the part +- {math.degrees(self.heading_spread):.0f} deg), part x {self.part_x} y {self.part_y} "
            f"z {self.part_z} any yaw, top or side grasp, on a pedestal; {self.pillars[0]}-{self.pillars[1]} "
            f"pillars r {self.pillar_radius} between start and goal"
        )


def _heading(a, b) -> float:
    return math.atan2(b[1] - a[1], b[0] - a[0])


def _clear(xy, radius, obstacles, margin) -> bool:
    """A base sphere of ``radius`` at ``xy`` (floor level) clears every obstacle by ``margin``."""
    for o in obstacles:
        dz = max(0.0, abs(o.center[2] - 0.2) - 0.2)  # the base sphere spans z in [0, 0.4] roughly
        if math.hypot(math.hypot(xy[0] - o.center[0], xy[1] - o.center[1]), dz) < radius + o.radius + margin:
            return False
    return True


def _grasp_ring_clear(part_xy, obstacles, r_min=0.35, r_max=0.8) -> bool:
    """Some base position at the middle of the grasping area clears the obstacles."""
    r = 0.5 * (r_min + r_max)
    for a in np.linspace(0.0, 2 * math.pi, 24, endpoint=False):
        xy = (part_xy[0] + r * math.cos(a), part_xy[1] + r * math.sin(a))
        if _clear(xy, BASE_RADIUS, [o for o in obstacles if o.radius > 0.1], 0.05):
            return True
    return False


_LAYOUT_TEXT = {
    Layout.side: "part 2-5 m off the line at 20-80 % of the way, headings along the line +- 45 deg",
    Layout.behind: "part 2-5 m behind the start, +-2 m across, headings along the line +- 45 deg",
    Layout.cluttered: "the paper's geometry, 3-6 pillars on the legs start-part and part-goal",
    Layout.headings: "the paper's geometry, start and goal headings uniform in [-pi, pi)",
}


def _part_and_headings(rng, ws: Workspace, start, goal, u) -> tuple:
    """(part x, y, z; start yaw; goal yaw) of the layout (paper: the Workspace's ranges)."""
    line = _heading(start, goal)
    spread = lambda: u((-ws.heading_spread, ws.heading_spread))  # noqa: E731
    if ws.layout is Layout.side:
        w, off = u((0.2, 0.8)), u((2.0, 5.0)) * (1 if rng.random() < 0.5 else -1)
        p = start + w * (goal - start) + off * np.array([-math.sin(line), math.cos(line)])
        return (float(p[0]), float(p[1]), u(ws.part_z)), line + spread(), line + spread()
    if ws.layout is Layout.behind:
        back, across = u((2.0, 5.0)), u((-2.0, 2.0))
        p = (
            start
            - back * np.array([math.cos(line), math.sin(line)])
            + across * np.array([-math.sin(line), math.cos(line)])
        )
        return (float(p[0]), float(p[1]), u(ws.part_z)), line + spread(), line + spread()
    part = (u(ws.part_x), u(ws.part_y), u(ws.part_z))
    if ws.layout is Layout.headings:
        return part, u((-math.pi, math.pi)), u((-math.pi, math.pi))
    return part, _heading(start, part) + spread(), _heading(part, goal) + spread()


def _pillars(rng, ws: Workspace, start, goal, part, u) -> list:
    """Pillars: beside the route (paper and the others), or on the two legs (cluttered)."""
    out = []
    if ws.layout is Layout.cluttered:
        for _ in range(int(rng.integers(3, 7))):
            r = u(ws.pillar_radius)
            a, b = (start, np.asarray(part[:2])) if rng.random() < 0.5 else (np.asarray(part[:2]), goal)
            c = a + float(rng.uniform(0.25, 0.75)) * (b - a) + rng.normal(0.0, 0.5, 2)
            out.append(SphereObstacle((float(c[0]), float(c[1]), r), r))
        return out
    for _ in range(int(rng.integers(ws.pillars[0], ws.pillars[1] + 1))):
        r = u(ws.pillar_radius)
        w = float(rng.uniform(0.25, 0.75))
        c = start + w * (goal - start) + rng.normal(0.0, 0.8, 2)
        out.append(SphereObstacle((float(c[0]), float(c[1]), r), r))
    return out


def random_problem(rng: np.random.Generator, ws: Workspace = Workspace(), max_tries: int = 100) -> PickupProblemSpec:
    """One problem that passes the cheap checks (RuntimeError after max_tries draws)."""
    u = lambda lo_hi: float(rng.uniform(*lo_hi))  # noqa: E731
    sr, sp = SIGMAS.get(ws.uncertainty, SIGMAS[Uncertainty.medium])
    for _ in range(max_tries):
        start = np.array([u(ws.start_x), u(ws.start_y)])
        goal = np.array([u(ws.goal_x), u(ws.goal_y)])
        if ws.layout is Layout.paper:  # the draws in the order of the first release (same problems per seed)
            part = (u(ws.part_x), u(ws.part_y), u(ws.part_z))
            yaw0 = yaw1 = None
        else:
            part, yaw0, yaw1 = _part_and_headings(rng, ws, start, goal, u)
        obstacles = [
            SphereObstacle((part[0], part[1], 0.15), 0.15),  # pedestal
            SphereObstacle((part[0], part[1], part[2] - PEDESTAL_GAP), 0.06),
        ]  # its top
        obstacles += _pillars(rng, ws, start, goal, part, u)
        pillars = obstacles[2:]
        if not (_clear(start, BASE_RADIUS, obstacles, 0.2) and _clear(goal, BASE_RADIUS, obstacles, 0.2)):
            continue
        if not all(
            math.hypot(o.center[0] - part[0], o.center[1] - part[1]) > 0.8 + BASE_RADIUS + o.radius + 0.2
            for o in pillars
        ):
            continue
        if not _grasp_ring_clear(part[:2], obstacles):
            continue
        if yaw0 is None:
            yaw0 = _heading(start, part) + u((-ws.heading_spread, ws.heading_spread))
            yaw1 = _heading(part, goal) + u((-ws.heading_spread, ws.heading_spread))
        return PickupProblemSpec(
            base_start=(float(start[0]), float(start[1]), float(yaw0)),
            base_goal=(float(goal[0]), float(goal[1]), float(yaw1)),
            part_position=part,
            part_yaw=u((-math.pi, math.pi)),
            metamodel=ws.metamodel,
            uncertainty=ws.uncertainty,
            sigma_r=sr,
            sigma_phi=sp,
            gamma=ws.gamma,
            obstacles=tuple(obstacles),
            grasp=GraspKind.top if rng.random() < 0.5 else GraspKind.side,
            arm_start=DEFAULT_ARM_START,
        )
    raise RuntimeError(f"no problem passed the cheap checks in {max_tries} draws: the workspace is too tight")


def random_problems(n: int, seed: int, ws: Optional[Workspace] = None) -> list:
    """``n`` problems from one seeded generator (the same n and seed give the same problems)."""
    if n < 1:
        raise ValueError(f"n must be >= 1, got {n}")
    rng = np.random.default_rng(seed)
    return [random_problem(rng, ws or Workspace()) for _ in range(n)]
