"""Pick-up problem files: a user's problem (base start and goal, the part, obstacles, limits) as JSON,
validated at the door, and the native PickupProblem built from it.

```
{"base_start": [x, y, yaw], "base_goal": [x, y, yaw],
 "part": {"position": [x, y, z], "yaw": a, "grasp": "top" | "side",
          "metamodel": "box" | "standin" | "PATH.json",
          "uncertainty": "low" | "medium" | "high" | {"sigma_r": m, "sigma_phi": rad}},
 "gamma": 0.96,
 "obstacles": [{"sphere": [x, y, z, r]}, {"box": {"center": [x, y, z], "size": [a, b, c], "yaw": t}}],
 "arm_start": [6 joints], "goal_tolerance": {"position": m, "yaw": rad},
 "limits": {"base_speed": m/s, "base_yaw_rate": rad/s, "arm_rates": [6] rad/s},
 "grasp_area": {"r_min": m, "r_max": m}}
```
Metres and radians, world frame; the keys after "obstacles" are optional (defaults: the paper's
cases). Every error is an InputError naming the file and the field. The robot is the mobile UR5
(``planner.mobile_ur5``); its body spheres and tool frame are fixed here, as in the paper's cases.
A box obstacle becomes the spheres of a grid that covers it (the NLP's obstacles are spheres).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field, replace
from typing import Optional

import numpy as np

from pickplan import _core
from pickplan.core.errors import InputError
from pickplan.core.fields import FieldReader, shown
from pickplan.core.io import read_json, write_json
from pickplan.core.settings import Option

FORMAT = "pickplan.pickup_problem"
VERSION = 1
STANDIN = "standin"  # metamodel: the labelled stand-in surface (no physics)
BUILTIN_PARTS = ("box", "cylinder", "l_bracket")
DEFAULT_ARM_START = (0.0, -2.2, 2.0, -1.4, -1.5708, 0.0)
ARM_DOF = 6
MAX_BOX_SPHERES = 64  # per box obstacle (each sphere adds collision rows)
MAX_OBSTACLE_SIZE = 100.0  # m: a sphere's radius, a box's side
# The mobile UR5's body spheres (link, centre in the link frame, radius), as in the paper's cases.
BODY_SPHERES = (
    ("base_link", (0.0, 0.0, 0.2), 0.3),
    ("upper_arm_link", (-0.2125, 0.0, 0.136), 0.08),
    ("forearm_link", (-0.196, 0.0, 0.017), 0.07),
    ("wrist_2_link", (0.0, 0.0, 0.0), 0.06),
    ("flange", (0.0, 0.0, 0.0), 0.05),
)


class Uncertainty(Option):
    """The part's pose uncertainty: the paper's three levels or sigmas given in the file."""

    low = "low"
    medium = "medium"
    high = "high"
    custom = "custom"


SIGMAS = {
    Uncertainty.low: (0.002, math.radians(5)),
    Uncertainty.medium: (0.007, math.radians(10)),
    Uncertainty.high: (0.012, math.radians(15)),
}


class GraspKind(Option):
    """top: tool z down, fingers closing across the part's x; side: tool z along the part's x
    (native ``GraspKind``; ``PickupProblem.set_part_grasp`` builds the pose)."""

    top = "top"
    side = "side"


@dataclass(frozen=True)
class SphereObstacle:
    center: tuple
    radius: float


@dataclass(frozen=True)
class BoxObstacle:
    center: tuple
    size: tuple  # full extents along the box's x, y, z
    yaw: float = 0.0

    def spheres(self) -> list:
        """Spheres covering the box: a grid of cells no wider than the box's smallest side (coarser
        when that takes more than MAX_BOX_SPHERES), each inside its circumscribed sphere
        (conservative by at most the cell's half diagonal)."""
        size = np.asarray(self.size, float)
        h = size.min()
        while np.prod(np.maximum(1, np.ceil(size / h - 1e-9))) > MAX_BOX_SPHERES:
            h *= 1.1
        n = np.maximum(1, np.ceil(size / h - 1e-9)).astype(int)
        cell = size / n
        radius = 0.5 * float(np.linalg.norm(cell))
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        out = []
        for idx in np.ndindex(*n):
            local = (np.asarray(idx) + 0.5) * cell - size / 2
            out.append((np.asarray(self.center, float) + R @ local, radius))
        return out


@dataclass(frozen=True)
class PickupProblemSpec:
    """A problem file's content. Equality ignores ``source`` (the file it was read from)."""

    base_start: tuple
    base_goal: tuple
    part_position: tuple
    part_yaw: float
    metamodel: str
    uncertainty: Uncertainty
    sigma_r: float
    sigma_phi: float
    gamma: float
    obstacles: tuple = ()
    grasp: GraspKind = GraspKind.top
    arm_start: tuple = DEFAULT_ARM_START
    goal_tol_pos: float = 0.5
    goal_tol_yaw: float = math.pi / 4
    base_speed_limit: float = 2.0
    base_yaw_rate_limit: float = math.pi
    arm_rate_limits: tuple = (math.pi,) * ARM_DOF
    grasp_area: tuple = (0.35, 0.8)
    source: Optional[str] = field(default=None, compare=False)

    def to_dict(self) -> dict:
        unc = (
            str(self.uncertainty)
            if self.uncertainty is not Uncertainty.custom
            else {"sigma_r": self.sigma_r, "sigma_phi": self.sigma_phi}
        )
        obstacles = [
            {"sphere": [*o.center, o.radius]}
            if isinstance(o, SphereObstacle)
            else {"box": {"center": list(o.center), "size": list(o.size), "yaw": o.yaw}}
            for o in self.obstacles
        ]
        return {
            "format": FORMAT,
            "version": VERSION,
            "base_start": list(self.base_start),
            "base_goal": list(self.base_goal),
            "part": {
                "position": list(self.part_position),
                "yaw": self.part_yaw,
                "grasp": str(self.grasp),
                "metamodel": self.metamodel,
                "uncertainty": unc,
            },
            "gamma": self.gamma,
            "obstacles": obstacles,
            "arm_start": list(self.arm_start),
            "goal_tolerance": {"position": self.goal_tol_pos, "yaw": self.goal_tol_yaw},
            "limits": {
                "base_speed": self.base_speed_limit,
                "base_yaw_rate": self.base_yaw_rate_limit,
                "arm_rates": list(self.arm_rate_limits),
            },
            "grasp_area": {"r_min": self.grasp_area[0], "r_max": self.grasp_area[1]},
        }

    def with_uncertainty(self, level) -> "PickupProblemSpec":
        level = Uncertainty.parse(level, "uncertainty")
        if level is Uncertainty.custom:
            raise ValueError("with_uncertainty: give a named level (low, medium, high)")
        return replace(self, uncertainty=level, sigma_r=SIGMAS[level][0], sigma_phi=SIGMAS[level][1])

    def metamodel_path(self) -> Optional[str]:
        """The meta-model file the problem names (relative paths: from the problem file's folder),
        or None for a built-in part name or the stand-in."""
        if self.metamodel == STANDIN or self.metamodel in BUILTIN_PARTS:
            return None
        base = os.path.dirname(self.source) if self.source else ""
        return os.path.normpath(os.path.join(base, self.metamodel))


# ---- validation ----------------------------------------------------------------------------------
_TOP = ("base_start", "base_goal", "part", "gamma", "obstacles")
_OPTIONAL = ("format", "version", "arm_start", "goal_tolerance", "limits", "grasp_area")
_PART = ("position", "yaw", "metamodel", "uncertainty", "grasp")
_DEFAULTS = PickupProblemSpec((0, 0, 0), (0, 0, 0), (0, 0, 0), 0.0, STANDIN, Uncertainty.medium, 0.0, 0.0, 0.96)
POSITION = dict(lo=-1e4, hi=1e4)  # m: world coordinates
ANGLE = dict(lo=-4 * math.pi, hi=4 * math.pi)
RATE = dict(hi=20.0, positive=True)  # m/s or rad/s


def _obstacle(r: FieldReader, o, where: str):
    r.table(o, where, known=("sphere", "box"))
    if len(o) != 1:
        r.fail(where, "expected exactly one of 'sphere' or 'box'")
    if "sphere" in o:
        x, y, z, radius = r.vector(o["sphere"], f"{where}.sphere", 4, **POSITION)
        return SphereObstacle((x, y, z), r.number(radius, f"{where}.sphere[3]", hi=MAX_OBSTACLE_SIZE, positive=True))
    w = f"{where}.box"
    b = r.table(o.get("box"), w, known=("center", "size", "yaw"))
    center = r.get(b, "center", w, r.vector, n=3, **POSITION)
    size = r.get(b, "size", w, r.vector, n=3, hi=MAX_OBSTACLE_SIZE, positive=True)
    yaw = r.get(b, "yaw", w, r.number, default=0.0, required=False, **ANGLE)
    if center is None or size is None or yaw is None:
        r.skip()
    return BoxObstacle(center, size, yaw)


def _uncertainty(r: FieldReader, u, where: str):
    if isinstance(u, dict):
        r.table(u, where, known=("sigma_r", "sigma_phi"))
        sigmas = (
            r.get(u, "sigma_r", where, r.number, hi=0.1, positive=True),
            r.get(u, "sigma_phi", where, r.number, hi=math.pi, positive=True),
        )
        if None in sigmas:
            r.skip()
        return (Uncertainty.custom, *sigmas)
    if not isinstance(u, str) or u not in ("low", "medium", "high"):
        r.fail(where, f"expected 'low', 'medium', 'high' or {{'sigma_r', 'sigma_phi'}}, got {shown(u)}")
    level = Uncertainty(u)
    return (level, *SIGMAS[level])


def _options(r: FieldReader, d: dict) -> dict:
    """The optional keys' values (defaults: the paper's cases)."""
    kw = {}
    if "arm_start" in d:
        kw["arm_start"] = r.attempt(r.vector, d["arm_start"], "arm_start", ARM_DOF, **ANGLE)
    g = r.get(d, "goal_tolerance", "", r.table, default={}, required=False, known=("position", "yaw"))
    kw["goal_tol_pos"] = r.get(
        g, "position", "goal_tolerance", r.number, default=_DEFAULTS.goal_tol_pos, required=False, positive=True
    )
    kw["goal_tol_yaw"] = r.get(
        g, "yaw", "goal_tolerance", r.number, default=_DEFAULTS.goal_tol_yaw, required=False, hi=math.pi, positive=True
    )
    lim = r.get(
        d, "limits", "", r.table, default={}, required=False, known=("base_speed", "base_yaw_rate", "arm_rates")
    )
    kw["base_speed_limit"] = r.get(
        lim, "base_speed", "limits", r.number, default=_DEFAULTS.base_speed_limit, required=False, **RATE
    )
    kw["base_yaw_rate_limit"] = r.get(
        lim, "base_yaw_rate", "limits", r.number, default=_DEFAULTS.base_yaw_rate_limit, required=False, **RATE
    )
    kw["arm_rate_limits"] = r.get(
        lim, "arm_rates", "limits", r.vector, default=_DEFAULTS.arm_rate_limits, required=False, n=ARM_DOF, **RATE
    )
    if "grasp_area" in d:
        a = r.attempt(r.table, d["grasp_area"], "grasp_area", default={}, known=("r_min", "r_max"))
        lo = r.get(a, "r_min", "grasp_area", r.number, positive=True)
        hi = r.get(a, "r_max", "grasp_area", r.number, hi=5.0, positive=True)
        if lo is not None and hi is not None and not lo < hi:
            r.note("grasp_area", f"expected r_min < r_max, got {lo} >= {hi}")
        kw["grasp_area"] = (lo, hi)
    return kw


def problem_from_dict(d, path: Optional[str] = None) -> PickupProblemSpec:
    """The validated problem of a parsed problem file (``path`` names it in errors and resolves a
    relative meta-model path); InputError naming every problem found."""
    r = FieldReader(path)
    with r:
        r.table(d, "", known=_TOP + _OPTIONAL)
        for key in _TOP:
            if key not in d:
                r.note(key, "missing")
        if "format" in d and d["format"] != FORMAT:
            r.note("format", f"expected {FORMAT!r}, got {shown(d['format'])}")
        if "version" in d and (isinstance(d["version"], bool) or d["version"] != VERSION):
            r.note("version", f"expected {VERSION}, got {shown(d['version'])}")
        p = r.attempt(r.table, d.get("part", {}), "part", default={}, known=_PART)
        grasp = r.get(p, "grasp", "part", r.choice, default="top", required=False, options=("top", "side"))
        level, sigma_r, sigma_phi = r.get(
            p, "uncertainty", "part", lambda u, w: _uncertainty(r, u, w), default=(None,) * 3, required="part" in d
        )
        obstacles = [
            r.attempt(_obstacle, r, o, f)
            for f, o in r.attempt(r.items, d.get("obstacles", []), "obstacles", default=[])
        ]
        kw = _options(r, d)
        spec = dict(
            base_start=r.get(d, "base_start", "", r.vector, required=False, n=3, **POSITION),
            base_goal=r.get(d, "base_goal", "", r.vector, required=False, n=3, **POSITION),
            part_position=r.get(p, "position", "part", r.vector, required="part" in d, n=3, **POSITION),
            part_yaw=r.get(p, "yaw", "part", r.number, required="part" in d, **ANGLE),
            metamodel=r.get(p, "metamodel", "part", r.text, required="part" in d),
            gamma=r.get(d, "gamma", "", r.number, required=False, hi=1.0, positive=True),
        )
        r.check()
        return PickupProblemSpec(
            uncertainty=level,
            sigma_r=sigma_r,
            sigma_phi=sigma_phi,
            obstacles=tuple(obstacles),
            grasp=GraspKind(grasp),
            source=os.fspath(path) if path else None,
            **spec,
            **kw,
        )


def load_problem(path) -> PickupProblemSpec:
    """The problem of a JSON file; InputError (file and field) for anything wrong in it."""
    path = os.fspath(path)
    return problem_from_dict(read_json(path, "pick-up problem file"), path)


def dump_problem(spec: PickupProblemSpec, path) -> None:
    """Writes the problem file atomically (``load_problem`` reads back an equal problem)."""
    write_json(os.fspath(path), spec.to_dict())


# ---- the native problem --------------------------------------------------------------------------
def native_problem(robot, spec: PickupProblemSpec, rho) -> "_core.PickupProblem":
    """The native PickupProblem for the mobile UR5 (``robot``) with the surface ``rho``
    (a native RhoPoly); ValueError naming the file when the robot rejects it."""
    lo, hi = np.asarray(robot.lower_limits), np.asarray(robot.upper_limits)
    for i, v in enumerate(spec.arm_start):
        if not lo[3 + i] <= v <= hi[3 + i]:
            raise InputError(
                f"{v} outside the joint's limits [{lo[3 + i]:.4f}, {hi[3 + i]:.4f}]",
                path=spec.source,
                field=f"arm_start[{i}]",
            )
    for name, pose in (("base_start", spec.base_start), ("base_goal", spec.base_goal)):
        if not all(lo[i] <= pose[i] <= hi[i] for i in range(2)):
            raise InputError(
                f"({pose[0]}, {pose[1]}) outside the base's range [{lo[0]}, {hi[0]}] m", path=spec.source, field=name
            )
    pb = _core.PickupProblem()
    pb.start = np.asarray(spec.base_start, float)
    pb.goal = np.asarray(spec.base_goal, float)
    pb.goal_tol_pos, pb.goal_tol_yaw = spec.goal_tol_pos, spec.goal_tol_yaw
    pb.arm_start = np.asarray(spec.arm_start, float)
    pb.arm_rate_limits = np.asarray(spec.arm_rate_limits, float)
    pb.base_speed_limit, pb.base_yaw_rate_limit = spec.base_speed_limit, spec.base_yaw_rate_limit
    pb.rho, pb.gamma = rho, spec.gamma
    pb.tool_link = robot.link_index("tool")
    pb.set_part_grasp(getattr(_core.GraspKind, spec.grasp.name), spec.part_yaw, np.asarray(spec.part_position, float))
    pb.grasp_area_rmin, pb.grasp_area_rmax = spec.grasp_area
    spheres = []
    for o in spec.obstacles:
        spheres += [(np.asarray(o.center, float), o.radius)] if isinstance(o, SphereObstacle) else o.spheres()
    pb.obstacles = spheres
    pb.body_spheres = [(robot.link_index(link), np.asarray(c, float), rad) for link, c, rad in BODY_SPHERES]
    try:
        pb.validate(robot.native)
    except ValueError as exc:
        raise InputError(str(exc), path=spec.source, field="problem") from None
    return pb
