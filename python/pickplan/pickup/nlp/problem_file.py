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
from pickplan.core.io import read_json, write_json
from pickplan.core.settings import Option

FORMAT = "pickplan.pickup_problem"
VERSION = 1
STANDIN = "standin"                    # metamodel: the labelled stand-in surface (no physics)
BUILTIN_PARTS = ("box", "cylinder", "l_bracket")
DEFAULT_ARM_START = (0.0, -2.2, 2.0, -1.4, -1.5708, 0.0)
ARM_DOF = 6
MAX_BOX_SPHERES = 64                   # per box obstacle (each sphere adds collision rows)
MAX_OBSTACLE_SIZE = 100.0              # m: a sphere's radius, a box's side
# The mobile UR5's body spheres (link, centre in the link frame, radius), as in the paper's cases.
BODY_SPHERES = (("base_link", (0.0, 0.0, 0.2), 0.3), ("upper_arm_link", (-0.2125, 0.0, 0.136), 0.08),
                ("forearm_link", (-0.196, 0.0, 0.017), 0.07), ("wrist_2_link", (0.0, 0.0, 0.0), 0.06),
                ("flange", (0.0, 0.0, 0.0), 0.05))


class Uncertainty(Option):
    """The part's pose uncertainty: the paper's three levels or sigmas given in the file."""

    low = "low"
    medium = "medium"
    high = "high"
    custom = "custom"


SIGMAS = {Uncertainty.low: (0.002, math.radians(5)), Uncertainty.medium: (0.007, math.radians(10)),
          Uncertainty.high: (0.012, math.radians(15))}


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
    size: tuple          # full extents along the box's x, y, z
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
        unc = (str(self.uncertainty) if self.uncertainty is not Uncertainty.custom
               else {"sigma_r": self.sigma_r, "sigma_phi": self.sigma_phi})
        obstacles = [{"sphere": [*o.center, o.radius]} if isinstance(o, SphereObstacle)
                     else {"box": {"center": list(o.center), "size": list(o.size), "yaw": o.yaw}}
                     for o in self.obstacles]
        return {"format": FORMAT, "version": VERSION,
                "base_start": list(self.base_start), "base_goal": list(self.base_goal),
                "part": {"position": list(self.part_position), "yaw": self.part_yaw, "grasp": str(self.grasp),
                         "metamodel": self.metamodel, "uncertainty": unc},
                "gamma": self.gamma, "obstacles": obstacles, "arm_start": list(self.arm_start),
                "goal_tolerance": {"position": self.goal_tol_pos, "yaw": self.goal_tol_yaw},
                "limits": {"base_speed": self.base_speed_limit, "base_yaw_rate": self.base_yaw_rate_limit,
                           "arm_rates": list(self.arm_rate_limits)},
                "grasp_area": {"r_min": self.grasp_area[0], "r_max": self.grasp_area[1]}}

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
class _Reader:
    """Reads fields of one file, raising InputError(path=file, field=dotted key) on any problem."""

    def __init__(self, path: Optional[str]):
        self.path = path

    def fail(self, where: str, message: str):
        raise InputError(message, path=self.path, field=where)

    def table(self, d, where: str, required=(), optional=()) -> dict:
        if not isinstance(d, dict):
            self.fail(where or "(top level)", f"expected an object, got {type(d).__name__}")
        missing = [k for k in required if k not in d]
        if missing:
            self.fail(self._key(where, missing[0]), "missing")
        unknown = sorted(set(d) - set(required) - set(optional))
        if unknown:
            self.fail(self._key(where, unknown[0]), f"unknown key; expected one of {sorted({*required, *optional})}")
        return d

    @staticmethod
    def _key(where: str, key) -> str:
        return f"{where}.{key}" if where else str(key)

    def number(self, value, where: str, lo=-math.inf, hi=math.inf, positive=False) -> float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            self.fail(where, f"expected a number, got {type(value).__name__} {value!r}"[:200])
        v = float(value)
        if not math.isfinite(v):
            self.fail(where, f"expected a finite number, got {v}")
        if positive and not v > 0:
            self.fail(where, f"expected a positive number, got {v}")
        if not lo <= v <= hi:
            self.fail(where, f"expected a number in [{lo}, {hi}], got {v}")
        return v

    def vector(self, value, where: str, n: int, **bounds) -> tuple:
        if not isinstance(value, list) or len(value) != n:
            got = f"{len(value)} values" if isinstance(value, list) else type(value).__name__
            self.fail(where, f"expected a list of {n} numbers, got {got}")
        return tuple(self.number(v, f"{where}[{i}]", **bounds) for i, v in enumerate(value))

    def text(self, value, where: str) -> str:
        if not isinstance(value, str) or not value or "\x00" in value:
            self.fail(where, f"expected a non-empty string, got {value!r}"[:200])
        return value


_TOP = ("base_start", "base_goal", "part", "gamma", "obstacles")
_OPTIONAL = ("format", "version", "arm_start", "goal_tolerance", "limits", "grasp_area")
_DEFAULTS = PickupProblemSpec((0, 0, 0), (0, 0, 0), (0, 0, 0), 0.0, STANDIN, Uncertainty.medium, 0.0, 0.0, 0.96)


def _obstacle(r: _Reader, o, where: str):
    r.table(o, where, optional=("sphere", "box"))
    if len(o) != 1:
        r.fail(where, "expected exactly one of 'sphere' or 'box'")
    if "sphere" in o:
        x, y, z, radius = r.vector(o["sphere"], f"{where}.sphere", 4, lo=-1e4, hi=1e4)
        return SphereObstacle((x, y, z), r.number(radius, f"{where}.sphere[3]", hi=MAX_OBSTACLE_SIZE, positive=True))
    b = r.table(o["box"], f"{where}.box", ("center", "size"), ("yaw",))
    box = BoxObstacle(r.vector(b["center"], f"{where}.box.center", 3, lo=-1e4, hi=1e4),
                      r.vector(b["size"], f"{where}.box.size", 3, hi=MAX_OBSTACLE_SIZE, positive=True),
                      r.number(b.get("yaw", 0.0), f"{where}.box.yaw", lo=-4 * math.pi, hi=4 * math.pi))
    return box


def _uncertainty(r: _Reader, u):
    if isinstance(u, dict):
        r.table(u, "part.uncertainty", ("sigma_r", "sigma_phi"))
        return (Uncertainty.custom, r.number(u["sigma_r"], "part.uncertainty.sigma_r", hi=0.1, positive=True),
                r.number(u["sigma_phi"], "part.uncertainty.sigma_phi", hi=math.pi, positive=True))
    if not isinstance(u, str) or u not in ("low", "medium", "high"):
        r.fail("part.uncertainty", f"expected 'low', 'medium', 'high' or {{'sigma_r', 'sigma_phi'}}, got {u!r}"[:200])
    level = Uncertainty(u)
    return (level, *SIGMAS[level])


def problem_from_dict(d, path: Optional[str] = None) -> PickupProblemSpec:
    """The validated problem of a parsed problem file (``path`` names it in errors and resolves a
    relative meta-model path)."""
    r = _Reader(path)
    r.table(d, "", _TOP, _OPTIONAL)
    if "format" in d and d["format"] != FORMAT:
        r.fail("format", f"expected {FORMAT!r}, got {d['format']!r}"[:200])
    if "version" in d and (isinstance(d["version"], bool) or d["version"] != VERSION):
        r.fail("version", f"expected {VERSION}, got {d['version']!r}"[:200])
    p = r.table(d["part"], "part", ("position", "yaw", "metamodel", "uncertainty"), ("grasp",))
    grasp = p.get("grasp", "top")
    if grasp not in ("top", "side"):
        r.fail("part.grasp", f"expected 'top' or 'side', got {grasp!r}"[:200])
    if not isinstance(d["obstacles"], list):
        r.fail("obstacles", f"expected a list, got {type(d['obstacles']).__name__}")
    level, sigma_r, sigma_phi = _uncertainty(r, p["uncertainty"])
    kw = {}
    if "arm_start" in d:
        kw["arm_start"] = r.vector(d["arm_start"], "arm_start", ARM_DOF, lo=-4 * math.pi, hi=4 * math.pi)
    if "goal_tolerance" in d:
        g = r.table(d["goal_tolerance"], "goal_tolerance", optional=("position", "yaw"))
        kw["goal_tol_pos"] = r.number(g.get("position", _DEFAULTS.goal_tol_pos), "goal_tolerance.position", positive=True)
        kw["goal_tol_yaw"] = r.number(g.get("yaw", _DEFAULTS.goal_tol_yaw), "goal_tolerance.yaw", hi=math.pi,
                                      positive=True)
    if "limits" in d:
        lim = r.table(d["limits"], "limits", optional=("base_speed", "base_yaw_rate", "arm_rates"))
        kw["base_speed_limit"] = r.number(lim.get("base_speed", _DEFAULTS.base_speed_limit), "limits.base_speed",
                                          hi=20.0, positive=True)
        kw["base_yaw_rate_limit"] = r.number(lim.get("base_yaw_rate", _DEFAULTS.base_yaw_rate_limit),
                                             "limits.base_yaw_rate", hi=20.0, positive=True)
        if "arm_rates" in lim:
            kw["arm_rate_limits"] = r.vector(lim["arm_rates"], "limits.arm_rates", ARM_DOF, hi=20.0, positive=True)
    if "grasp_area" in d:
        a = r.table(d["grasp_area"], "grasp_area", ("r_min", "r_max"))
        lo = r.number(a["r_min"], "grasp_area.r_min", positive=True)
        hi = r.number(a["r_max"], "grasp_area.r_max", hi=5.0, positive=True)
        if not lo < hi:
            r.fail("grasp_area", f"expected r_min < r_max, got {lo} >= {hi}")
        kw["grasp_area"] = (lo, hi)
    metamodel = r.text(p["metamodel"], "part.metamodel")
    return PickupProblemSpec(
        base_start=r.vector(d["base_start"], "base_start", 3, lo=-1e4, hi=1e4),
        base_goal=r.vector(d["base_goal"], "base_goal", 3, lo=-1e4, hi=1e4),
        part_position=r.vector(p["position"], "part.position", 3, lo=-1e4, hi=1e4),
        part_yaw=r.number(p["yaw"], "part.yaw", lo=-4 * math.pi, hi=4 * math.pi),
        metamodel=metamodel, uncertainty=level, sigma_r=sigma_r, sigma_phi=sigma_phi,
        gamma=r.number(d["gamma"], "gamma", hi=1.0, positive=True),
        obstacles=tuple(_obstacle(r, o, f"obstacles[{i}]") for i, o in enumerate(d["obstacles"])),
        grasp=GraspKind(grasp), source=os.fspath(path) if path else None, **kw)


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
            raise InputError(f"{v} outside the joint's limits [{lo[3 + i]:.4f}, {hi[3 + i]:.4f}]",
                             path=spec.source, field=f"arm_start[{i}]")
    for name, pose in (("base_start", spec.base_start), ("base_goal", spec.base_goal)):
        if not all(lo[i] <= pose[i] <= hi[i] for i in range(2)):
            raise InputError(f"({pose[0]}, {pose[1]}) outside the base's range [{lo[0]}, {hi[0]}] m",
                             path=spec.source, field=name)
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
