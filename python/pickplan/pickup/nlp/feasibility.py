"""What the geometry of a pick-up problem allows, before any NLP: where the base may stand while the
arm grasps, a lower bound on T, and the reasons a problem has no solution (issue 37).

Everything here is a *necessary* condition, so the bound never exceeds the T of a solved problem and
a reason is never given for a problem that has a solution:

- the base's body spheres (those on links only the base DOFs move) must clear every obstacle: an
  obstacle sphere blocks the disk of base positions within sqrt((r_b + r_o)^2 - dz^2) - |offset_xy|
  of its centre (clearance >= 0: the dense check's own test; the NLP asks for a margin on top);
- the tool is at most R from the first arm joint (the triangle inequality over the fixed link
  offsets, as the native reachability pre-check), so the base stands within sqrt(R^2 - dz^2) + mount
  (horizontally) of the grasp point, mount being the first joint's horizontal offset on the base;
- at T1 and T2 the base is in the grasping annulus (the NLP's area rows), free and within reach;
- the base moves at most at its speed limit, the goal is reached within its position tolerance, and
  the grasp window T2 - T1 = stroke / S_c is at least stroke over the largest S_c for which some S_g
  reaches gamma on the meta-model's surface.

The bound is T >= min over grasp positions p (at T1) and q (at T2) of |p - start| / v +
max(W, |p - q| / v) + max(0, |q - goal| - tol) / v, and >= t_min: straight lines, the obstacles only
through the grasp set (a lower bound; detours around obstacles make routes longer, not shorter).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial.distance import cdist

from pickplan.core.settings import Option


class Reason(Option):
    """Why a plan was or was not found (``PickupPlan.reason``)."""

    none = "none"  # solved
    out_of_reach = "out_of_reach"  # no free base position in the grasping area reaches the part
    gamma_unattainable = "gamma_unattainable"  # the meta-model's rho stays below gamma at every speed
    horizon_too_short = "horizon_too_short"  # the lower bound on T exceeds the horizon t_max
    solver_failed = "solver_failed"  # feasible as far as the bound tells; no solver run succeeded
    time_limit = "time_limit"  # the budget ran out before any feasible plan


RING_RADII = 7  # grasp-set grid: radii across the grasping annulus ...
RING_ANGLES = 144  # ... times angles around the part (2.5 deg)
SC_GRID = 64  # S_c grid of the grasp-window bound


@dataclass(frozen=True)
class BaseGeometry:
    """The planar facts of a problem the route seeds and the bound use (metres, seconds, radians)."""

    start: np.ndarray  # base x, y, yaw at t = 0
    goal: np.ndarray  # base x, y, yaw at T
    goal_tol: float
    v_max: float
    w_max: float
    part_xy: np.ndarray
    grasp_xy: np.ndarray
    r_min: float
    r_max: float
    disks: np.ndarray  # (n, 3): x, y, r of the base positions each obstacle blocks (clearance 0)
    reach_xy: float  # the base within this of grasp_xy (NaN: the grasp height is out of reach)
    window: float  # least grasp window T2 - T1 (s; inf: gamma unattainable)
    t_min: float
    t_max: float

    def free(self, xy, margin: float = 0.0) -> np.ndarray:
        """Whether base positions (n, 2) clear every obstacle (by ``margin`` more than contact)."""
        xy = np.atleast_2d(np.asarray(xy, float))
        if not len(self.disks):
            return np.ones(len(xy), bool)
        d = np.linalg.norm(xy[:, None, :] - self.disks[None, :, :2], axis=2)
        return np.all(d >= self.disks[None, :, 2] + margin, axis=1)

    def spacing(self, radii: int = RING_RADII, angles: int = RING_ANGLES) -> float:
        """The covering radius h of the annulus grid: every point of the annulus is within h of one."""
        dr = (self.r_max - self.r_min) / max(radii - 1, 1)
        return math.hypot(dr / 2, self.r_max * math.pi / angles)

    def grasp_set(self, reach: bool = True, radii: int = RING_RADII, angles: int = RING_ANGLES) -> np.ndarray:
        """Grid points (n, 2) of the grasping annulus that pass the free (and, with ``reach``, the
        reach) test relaxed by the grid's covering radius h: every free (reachable) base position of
        the annulus has one within h, so an empty set proves there is none and a bound over the set,
        less what h can change, stays a bound."""
        if reach and not math.isfinite(self.reach_xy):
            return np.zeros((0, 2))
        h = self.spacing(radii, angles)
        r = np.linspace(self.r_min, self.r_max, radii)
        a = np.linspace(0.0, 2 * math.pi, angles, endpoint=False)
        R, A = np.meshgrid(r, a)
        p = self.part_xy + np.stack([R.ravel() * np.cos(A.ravel()), R.ravel() * np.sin(A.ravel())], axis=1)
        ok = self.free(p, -h)
        if reach:
            ok &= np.linalg.norm(p - self.grasp_xy, axis=1) <= self.reach_xy + h
        return p[ok]


def _base_only_links(robot) -> set:
    """Links whose pose depends on no joint but the base's three (q indices 0-2)."""
    parents, q_index = robot.native.link_parents, robot.native.link_q_index
    out = set()
    for i in range(len(parents)):
        k, ok = i, True
        while k >= 0:
            ok &= q_index[k] < 3
            k = parents[k]
        if ok:
            out.add(i)
    return out


def _arm_reach(robot, tool: int) -> tuple:
    """(R, first arm joint's position at q = 0): R bounds the tool's distance from that joint."""
    parents, q_index = robot.native.link_parents, robot.native.link_q_index
    poses = robot.fk(np.zeros(robot.dof))
    first = next(i for i in range(len(q_index)) if q_index[i] == 3)
    reach, k = 0.0, tool
    while k >= 0 and k != first:
        reach += float(np.linalg.norm(poses[k][:3, 3] - poses[parents[k]][:3, 3]))
        k = parents[k]
    return reach, poses[first][:3, 3]


def grasp_window(problem) -> float:
    """The least T2 - T1: stroke over the largest S_c at which some S_g reaches gamma (inf: none)."""
    rho = problem.rho
    lo, hi = rho.sc_range
    grid = np.linspace(lo, hi, SC_GRID)
    ok = [not math.isnan(rho.sg_upper_bound(problem.gamma, c, c)) for c in grid]
    if not any(ok):
        return math.inf
    last = max(i for i, v in enumerate(ok) if v)
    # The next grid point up (or sc_hi): the true largest S_c lies below it, so the window is a bound.
    sc = grid[min(last + 1, len(grid) - 1)]
    return problem.stroke / sc


def base_geometry(robot, problem, settings) -> BaseGeometry:
    """The problem's planar geometry (``settings``: the PlannerSettings, for t_min and t_max)."""
    base_links = _base_only_links(robot)
    poses = robot.fk(np.zeros(robot.dof))
    disks = []
    for link, centre, radius in problem.body_spheres:
        if link not in base_links:
            continue
        c = poses[link][:3, :3] @ np.asarray(centre) + poses[link][:3, 3]
        offset = math.hypot(c[0], c[1])
        for oc, orad in problem.obstacles:
            reach = (radius + orad) ** 2 - (oc[2] - c[2]) ** 2
            if reach > 0 and math.sqrt(reach) - offset > 0:
                disks.append((oc[0], oc[1], math.sqrt(reach) - offset))
    R, j0 = _arm_reach(robot, problem.tool_link)
    grasp = np.asarray(problem.grasp_pose)[:3, 3]
    dz = grasp[2] - j0[2]
    reach_xy = math.sqrt(R * R - dz * dz) + math.hypot(j0[0], j0[1]) if abs(dz) <= R else math.nan
    return BaseGeometry(
        start=np.asarray(problem.start, float),
        goal=np.asarray(problem.goal, float),
        goal_tol=float(problem.goal_tol_pos),
        v_max=float(problem.base_speed_limit),
        w_max=float(problem.base_yaw_rate_limit),
        part_xy=np.asarray(problem.part_xy, float),
        grasp_xy=grasp[:2].copy(),
        r_min=float(problem.grasp_area_rmin),
        r_max=float(problem.grasp_area_rmax),
        disks=np.asarray(disks, float).reshape(-1, 3),
        reach_xy=reach_xy,
        window=grasp_window(problem),
        t_min=float(settings.t_min),
        t_max=float(settings.t_max),
    )


def lower_bound(geo: BaseGeometry) -> float:
    """The lower bound on T (module doc); inf when no grasp position exists or gamma is unattainable.
    The base at T1 is in the free annulus (the tool is then S_g (T2 - T1) short of the grasp point,
    so no reach test), at T2 also within reach. The minimum over the grids is lowered by 4 h / v:
    moving p and q by h each changes the three terms by at most that."""
    A1, A2 = geo.grasp_set(reach=False), geo.grasp_set()
    if not len(A2) or not math.isfinite(geo.window):
        return math.inf
    v = geo.v_max
    d1 = np.linalg.norm(A1 - geo.start[:2], axis=1) / v
    d2 = np.maximum(0.0, np.linalg.norm(A2 - geo.goal[:2], axis=1) - geo.goal_tol) / v
    total = np.maximum(cdist(A1, A2) / v, geo.window)  # in place: ~10^6 pairs
    total += d1[:, None]
    total += d2[None, :]
    return max(geo.t_min, float(total.min()) - 4 * geo.spacing() / v)


@dataclass(frozen=True)
class Certificate:
    """What the geometry says before solving: a reason (none: nothing rules the problem out) and
    the lower bound on T."""

    reason: Reason
    lower_bound: float
    detail: str = ""

    @property
    def feasible(self) -> bool:
        return self.reason is Reason.none


def certify(robot, problem, settings) -> Certificate:
    """The reasons that rule a problem out, checked in order: gamma, reach, horizon."""
    geo = base_geometry(robot, problem, settings)
    if not math.isfinite(geo.window):
        best = max(
            problem.rho.value(s, c)
            for s in np.linspace(*problem.rho.sg_range, 32)
            for c in np.linspace(*problem.rho.sc_range, 32)
        )
        return Certificate(
            Reason.gamma_unattainable,
            math.inf,
            f"the meta-model's rho is at most {best:.3f} < gamma {problem.gamma} at this uncertainty",
        )
    A = geo.grasp_set()
    if not len(A):
        why = (
            "the grasp point is out of the arm's vertical reach"
            if not math.isfinite(geo.reach_xy)
            else "no base position in the grasping area both clears the obstacles and brings the arm within reach"
        )
        return Certificate(Reason.out_of_reach, math.inf, why)
    lb = lower_bound(geo)
    if lb > geo.t_max:
        return Certificate(
            Reason.horizon_too_short, lb, f"T >= {lb:.2f} s by the geometry, above the horizon t_max {geo.t_max:.2f} s"
        )
    return Certificate(Reason.none, lb)
