"""Goal sets: grasps (hand poses in the object frame) -> the support surface (fingertips may rest on
the table; grasps pushing them deeper are shifted up or tilted) -> IK -> standoff approach -> FCL
filter (approach clearance) -> diversity -> cap. Native but the support step; every rejected grasp
records why."""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field
from typing import ClassVar, Optional, Tuple

import numpy as np

from pickplan import _core
from pickplan.core.poses import RIGID_CLEAN_TOLERANCE, rigid_errors
from pickplan.core import collision
from pickplan.core.ik import IkSettings
from pickplan.core.settings import native_defaults, to_native
from pickplan.omg.grasps.quality import GraspFit, QualitySettings
from pickplan.omg.grasps.verify import VerifySettings
from pickplan.omg.world import CheckerKind, World
from pickplan.sim.execution import ExecutionSettings
from pickplan.sim.lift import URDF_COLLISION_MARGIN, lift_path


@dataclass(frozen=True)
class SupportSettings:
    """How grasps meet the support surface (the table top). A grasp pushing the fingers into it, at
    the grasp or at its pre-grasp, is moved back along its approach axis until they just touch, by at
    most ``max_shift`` (None: half the pad length, so the original contacts stay on the pads): first
    as it is, then with its closing axis rolled towards the support's plane (by at most
    ``max_level_deg``, about the pad centre), then that tilted about the closing axis by each of
    ``tilts_deg``. Grasps no variant clears stay as they are when their fingers press in no deeper
    than ``contact``'s tolerance (default from the gripper's pad length), else are rejected as
    "support_penetration"."""

    contact: collision.SupportContact = collision.SupportContact()
    max_shift: Optional[float] = None
    max_level_deg: float = 30.0
    tilts_deg: Tuple[float, ...] = (15.0, -15.0, 30.0, -30.0)


@dataclass(frozen=True)
@native_defaults(_core.GoalSetSettings)
class GoalSetSettings:
    """Mirror of the native ``GoalSetSettings`` (paper: 30 goals per scene, 8 cm standoff), plus
    ``approach_clearance``: every configuration of the standoff approach (pre-grasp to grasp) must
    keep this distance from the other objects, measured as the success test measures it (body
    points in the scene SDF, target and table left out): the clearance the test demands of a plan's
    approach (``MetricSettings.tail_clearance``). The approach is pinned: neither CHOMP nor the
    goal-cost estimate can move or charge it, so a goal failing this could never succeed.
    0 disables the check."""

    approach_clearance: float = 0.01
    # Grasps whose pads cannot hold the target as it lies against gravity and the carry
    # (``grasps.quality``) are rejected ("slips", "misses") and the rest tried best margin first;
    # None: every grasp, in the order given.
    quality: Optional[QualitySettings] = QualitySettings()
    # Where the quality leaves no reachable grasp, the grasps it is unsure of are lifted in PyBullet
    # (``grasps.verify``, cached; worlds with the target's model only) and those that hold are tried:
    # what the model cannot judge (a pad's pressure over its patch, the simulator's contacts). None: never.
    verify: Optional[VerifySettings] = VerifySettings(budget=12)
    standoff: float
    standoff_steps: int
    max_joint_jump: float
    diversity: float
    max_goals: int
    max_solutions: int
    seed: int
    # world direction of the standoff approach (unit; zero: the hand's +z; a place: gravity)
    approach: Tuple[float, float, float]
    # the approach clearance also between the tail's configurations, at this many joint-linear steps
    # per interval (1: at the configurations only)
    approach_substeps: int
    # m the hand, fingers and target must be free to rise from the grasp among the scene's obstacles
    # (furniture: a shelf's next board; ``lift_blocked``), keeping ``lift_clearance`` from them:
    # execution's shortest lift and its clearance, which execution measures in PyBullet (its hulls'
    # collision margin nearer than the exact distances the goal set takes).
    lift: float = ExecutionSettings.min_lift
    lift_clearance: float = ExecutionSettings.lift_clearance + URDF_COLLISION_MARGIN

    # What the Python side applies itself (the native struct has no such fields; the drift test reads this)
    PYTHON_ONLY: ClassVar[Tuple[str, ...]] = ("approach_clearance", "quality", "verify", "lift", "lift_clearance")

    def to_native(self) -> "_core.GoalSetSettings":
        return to_native(self, _core.GoalSetSettings, skip=self.PYTHON_ONLY)


@dataclass
class GoalSet:
    goals: np.ndarray  # (G, dof) grasp configurations
    tails: np.ndarray  # (G, standoff_steps + 1, dof): pre-grasp first, grasp last
    grasp_index: np.ndarray  # (G,) index into ``grasps``
    grasps: np.ndarray  # (N, 4, 4) the input grasps (hand in the object frame)
    reasons: list  # per input grasp: "ok" or why it was rejected
    seconds: float
    adjusted: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))  # (N,) moved off the support
    margin: np.ndarray = field(default_factory=lambda: np.zeros(0))  # (N,) grasp quality margin (nan: not judged)

    def __len__(self) -> int:
        return int(self.goals.shape[0])

    def reason_counts(self) -> dict:
        """Rejections by reason; no grasps at all is "no_candidates" (counted, so a table says why)."""
        return dict(Counter(self.reasons)) if len(self.grasps) else {"no_candidates": 1}


def check_grasps(grasps) -> np.ndarray:
    g = np.asarray(grasps, dtype=float)
    if g.ndim != 3 or g.shape[1:] != (4, 4):
        raise ValueError(f"grasps: expected shape (N, 4, 4), got {g.shape}")
    # Checked before the support may move a grasp: a moved grasp is rebuilt rigid, hiding a bad input.
    err = rigid_errors(g) if len(g) else np.zeros(0)
    bad = np.flatnonzero(~(err <= RIGID_CLEAN_TOLERANCE))
    if len(bad):
        raise ValueError(
            f"grasps [{bad[0]}]: not a rigid transform (error {err[bad[0]]:.1e} > "
            f"{RIGID_CLEAN_TOLERANCE:.0e}; {len(bad)} of {len(g)} bad)"
        )
    return g


def ik_solver(world: World, settings: IkSettings = IkSettings()) -> "_core.IkSolver":
    """The IK solver of the world's robot hand; immutable, so kept in the world's model cache per robot
    model, base and settings (a replan's goal set built it anew: 80 us of its 2 ms)."""
    robot = world.robot

    def build():
        active = [i < robot.info.arm_dof for i in range(robot.dof)]
        return _core.IkSolver(robot.native, robot.hand_link, settings.to_native(active))

    cache = getattr(world, "cache", None)
    if cache is None:
        return build()
    return cache.robot_derived(robot, ("ik_solver", robot.hand_link, robot.base_pose.tobytes(), settings), build)


def _about_pad_centre(R: np.ndarray, pad_depth: float) -> np.ndarray:
    """Hand-frame transforms (..., 4, 4) rotating the hand by ``R`` (..., 3, 3) about the pad centre."""
    T = np.zeros(R.shape[:-2] + (4, 4))
    T[..., :3, :3], T[..., 3, 3] = R, 1.0
    centre = np.array([0.0, 0.0, pad_depth])
    T[..., :3, 3] = centre - R @ centre
    return T


def _about_closing_axis(angle: float, pad_depth: float) -> np.ndarray:
    """Tilt by ``angle`` about the closing axis (y) through the pad centre."""
    c, si = np.cos(angle), np.sin(angle)
    return _about_pad_centre(np.array([[c, 0.0, si], [0.0, 1.0, 0.0], [-si, 0.0, c]]), pad_depth)


def _levelled(H: np.ndarray, normal: np.ndarray, pad_depth: float, max_angle: float) -> np.ndarray:
    """The hand poses rolled about their x axis (through the pad centre) towards a closing axis
    parallel to the support, by at most ``max_angle``: a closing axis sloping down puts one finger
    into the table however far the hand moves back."""
    yn, zn = H[:, :3, 1] @ normal, H[:, :3, 2] @ normal
    with np.errstate(divide="ignore", invalid="ignore"):
        phi = np.clip(np.arctan(np.where(np.abs(zn) > 1e-9, -yn / zn, 0.0)), -max_angle, max_angle)
    c, si = np.cos(phi), np.sin(phi)
    R = np.zeros((len(H), 3, 3))
    R[:, 0, 0], R[:, 1, 1], R[:, 1, 2], R[:, 2, 1], R[:, 2, 2] = 1.0, c, -si, si, c
    return H @ _about_pad_centre(R, pad_depth)


def support_adjusted(
    world: World,
    hand_poses: np.ndarray,
    start: np.ndarray,
    standoff: float,
    settings: SupportSettings = SupportSettings(),
) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """World hand poses moved off the support where their fingers (at the grasp or at the pre-grasp
    ``standoff`` back) press into it (``SupportSettings``). Returns the poses, a (N,) mask of those
    moved, and a (N,) mask of those no variant clears that press in deeper than the tolerance."""
    robot = world.robot
    gripper = collision.gripper_spec(robot)
    tolerance = settings.contact.resolved(robot)
    max_shift = 0.5 * gripper.pad_length if settings.max_shift is None else float(settings.max_shift)
    pad_depth = float(gripper.grasp_frame[2, 3])
    fingers = world.cache.finger_geometry(robot, start)
    if fingers is None:
        raise ValueError("support adjustment: the robot's hand has no finger links")
    normal, offset = world.support_plane

    def depths(H):  # deepest finger point at the grasp and at the pre-grasp; moving back lifts both alike
        back = H.copy()
        back[:, :3, 3] -= standoff * H[:, :3, 2]
        return np.maximum(fingers.penetration(H, normal, offset), fingers.penetration(back, normal, offset))

    poses = np.array(hand_poses, dtype=float).reshape(-1, 4, 4)
    depth = depths(poses)
    # pressing into the table at all: lifted when a variant can, else kept within the tolerance; a hand
    # beyond the table's edge is not over the support (its plane does not extend there)
    todo = (depth > 0.0) & world.over_support(poses[:, :3, 3])
    moved = np.zeros(len(poses), bool)
    level = np.radians(settings.max_level_deg)
    for levelled, tilt in [(False, 0.0)] + [(True, t) for t in (0.0,) + tuple(np.radians(settings.tilts_deg))]:
        idx = np.flatnonzero(todo)
        if len(idx) == 0:
            break
        H = _levelled(poses[idx], normal, pad_depth, level) if levelled else poses[idx]
        H = H @ _about_closing_axis(tilt, pad_depth)
        lift = -H[:, :3, 2] @ normal  # finger rise per metre moved back along the approach axis
        with np.errstate(divide="ignore", invalid="ignore"):
            shift = np.where(lift > 1e-3, np.maximum(depths(H), 0.0) / lift, np.inf)
        ok = shift <= max_shift
        H[:, :3, 3] -= shift[:, None].clip(max=max_shift) * H[:, :3, 2]
        poses[idx[ok]], moved[idx[ok]], todo[idx[ok]] = H[ok], True, False
    return poses, moved, todo & (depth > tolerance)


def _rigid_with_hand(robot) -> Tuple[str, ...]:
    """The links fixed to the hand link (the hand, a wrist flange and the last arm link before it):
    the same pose relative to the hand at two configurations."""
    Q = robot.random_configurations(2, seed=0)
    hand = robot.link_index(robot.hand_link)
    rel = [np.linalg.inv(robot.fk(q)[hand]) @ robot.fk(q) for q in Q]
    same = np.all(np.abs(rel[0] - rel[1]) < 1e-9, axis=(1, 2))
    return tuple(n for i, n in enumerate(robot.link_names) if same[i] and robot.collision_meshes(n) is not None)


def lift_blocked(
    world: World, hand_poses: np.ndarray, start: np.ndarray, lift: float, step: float = 0.01
) -> np.ndarray:
    """(N,) world hand poses whose hand, the links fixed to it and the fingers (collision hull vertices,
    open as in ``start``) or target, raised straight up by up to ``lift`` m, would enter one of the
    scene's obstacles (``_raised_blocked``): no lift can follow such a grasp, whatever the arm does."""
    poses = np.asarray(hand_poses, float).reshape(-1, 4, 4)
    if lift <= 0 or not getattr(world.scene, "obstacles", None) or not len(poses):
        return np.zeros(len(poses), bool)
    robot, q = world.robot, np.asarray(start, float)
    fingers = world.cache.finger_geometry(robot, q)
    palm = world.cache.robot_derived(
        robot,
        ("rigid_hand_hull_vertices", q.tobytes()),
        lambda: collision.HandGeometry(robot, q, robot.hand_link, _rigid_with_hand(robot)).vertices,
    )
    V = np.vstack([palm] + ([fingers.vertices] if fingers is not None else []))
    return _raised_blocked(world, np.einsum("nij,pj->npi", poses[:, :3, :3], V) + poses[:, None, :3, 3], lift, step)


def lift_blocked_configurations(
    world: World, Q: np.ndarray, lift: float, clearance: float, execution: ExecutionSettings = ExecutionSettings()
) -> np.ndarray:
    """(G,) goal configurations whose lift the scene's obstacles block, judged as execution judges it
    (``sim.lift.lift_headroom``): along the lift's own IK path (``lift_path``, its waypoints up to ``lift``
    m) a link (its convex hull, as PyBullet takes it: ``CheckerKind.furniture``) or the target (its hull's
    vertices, carried by the hand) comes closer to an obstacle than ``clearance`` and closer than at the
    grasp. A rigid rise misses what the arm's IK adds: lifting a hand deep in a cabinet raises the forearm
    faster than the hand; and a hull's vertices miss a face passing under a board's edge."""
    robot = world.robot
    Q = np.asarray(Q, float).reshape(-1, robot.dof)
    if lift <= 0 or not getattr(world.scene, "obstacles", None) or not len(Q):
        return np.zeros(len(Q), bool)
    step = execution.lift_height / execution.lift_waypoints
    count = min(int(np.ceil(lift / step - 1e-9)), execution.lift_waypoints)  # a lift stopped before is short
    paths = np.stack([lift_path(robot, q, execution)[: count + 1] for q in Q])  # (G, K + 1, dof)
    checker, within = world.checker(CheckerKind.furniture), 2.0 * clearance

    def links_blocked(path) -> bool:
        start = {(c.link, c.other): c.distance for c in checker.contacts(path[0], within)}
        return any(
            c.distance < clearance and c.distance < start.get((c.link, c.other), within) - 1e-4
            for q in path[1:]
            for c in checker.contacts(q, within)
        )

    blocked = np.array([links_blocked(path) for path in paths], bool)
    # the target rides with the hand: its pose relative to the hand at the grasp, at every waypoint
    hand = robot.link_index(robot.hand_link)
    H = robot.fk_batch(paths.reshape(-1, robot.dof))[:, hand].reshape(len(Q), count + 1, 4, 4)
    carried = H @ np.linalg.inv(H[:, :1]) @ world.target_pose
    V = np.asarray(world.target_model.mesh.convex_hull.vertices, float)
    P = np.einsum("gkij,pj->gkpi", carried[..., :3, :3], V) + carried[..., None, :3, 3]
    d, _ = world.sdf.distance(
        P.reshape(-1, 3), cutoff=within, exclude=[o.name for o in world.scene.objects], exclude_table=True
    )
    d = np.asarray(d).reshape(len(Q), count + 1, -1)
    return blocked | ((d[:, 1:] < clearance) & (d[:, 1:] < d[:, :1] - 1e-4)).any(axis=(1, 2))


def _raised_blocked(world: World, P: np.ndarray, lift: float, step: float) -> np.ndarray:
    """(N,) which sets of world points (N, K, 3), with the target's hull vertices, raised by ``step``s up to
    ``lift``, enter an obstacle of the scene (not an object, not the table) they are not in already."""
    T = world.target_pose
    target = np.asarray(world.target_model.mesh.convex_hull.vertices, float) @ T[:3, :3].T + T[:3, 3]
    P = np.concatenate([P, np.broadcast_to(target, (len(P),) + target.shape)], axis=1)
    count = int(np.ceil(lift / step - 1e-9))
    up = np.zeros((count + 1, 1, 1, 3))
    up[..., 2] = (np.arange(count + 1) * lift / count)[:, None, None]
    d, _ = world.sdf.distance(
        (P[None] + up).reshape(-1, 3), cutoff=step, exclude=[o.name for o in world.scene.objects], exclude_table=True
    )
    d = np.asarray(d).reshape(count + 1, len(P), -1).min(axis=2)
    return (d[1:].min(axis=0) < 0.0) & (d[0] >= 0.0)  # in an obstacle already: the collision checks say so


def _second_look(world, settings: GoalSetSettings):
    """How grasps the quality says slip are judged again where no other grasp gives a goal: a function
    of grasps (target frame) to a keep mask, or None. A world with the target's mesh lifts them in
    PyBullet (``settings.verify``); a world of observed points has no mesh, and its load is a guess
    (``QualitySettings.point_density_light``: those that hold the lightest such target are kept)."""
    if settings.quality is not None and hasattr(world, "light_load_holds"):
        return lambda grasps: world.light_load_holds(grasps, settings.quality)
    if settings.verify is not None and hasattr(world, "verify_grasps"):
        return lambda grasps: world.verify_grasps(grasps, settings.verify).keep
    return None


def build_goal_set(
    world: World,
    grasps,
    start: Optional[np.ndarray] = None,
    settings: GoalSetSettings = GoalSetSettings(),
    ik: IkSettings = IkSettings(),
    collision_check: bool = True,
    support: SupportSettings = SupportSettings(),
    seeds: Optional[np.ndarray] = None,
) -> GoalSet:
    """Goal configurations for the world's target from grasps in its object frame.

    With ``collision_check``, grasps are first met with the support (``support_adjusted``): the
    returned ``GoalSet.grasps`` are the grasps as used (moved ones flagged in ``adjusted``); then
    judged by ``settings.quality`` (``World.grasp_quality``): those that do not hold are rejected and the
    rest tried best margin first; if none of them gives a goal, those it is unsure of that hold on a
    second look (``_second_look``: in PyBullet, or under the lightest load points allow) are tried. An object with no reachable grasp
    gives an empty goal set (with reasons), not an exception.
    ``seeds`` (N, dof): each grasp's first IK seed (a replan: its goal before the target moved).
    """
    grasps = check_grasps(grasps)
    if seeds is not None:
        seeds = np.asarray(seeds, dtype=float)
        if seeds.shape != (len(grasps), world.robot.dof):
            raise ValueError(f"seeds: expected ({len(grasps)}, {world.robot.dof}), one per grasp, got {seeds.shape}")
    start = world.start if start is None else np.asarray(start, dtype=float)
    target = world.target_pose
    hand_poses = np.einsum("ij,njk->nik", target, grasps) if len(grasps) else grasps
    adjusted = np.zeros(len(grasps), bool)
    blocked = np.zeros(len(grasps), bool)
    if collision_check and len(grasps):
        hand_poses, adjusted, blocked = support_adjusted(world, hand_poses, start, settings.standoff, support)
        grasps = np.einsum("ij,njk->nik", np.linalg.inv(target), hand_poses)
    checker = world.checker(CheckerKind.goal).native if collision_check else None
    hand_checker = world.checker(CheckerKind.hand).native if collision_check else None
    problem = world.clearance_problem if collision_check and settings.approach_clearance > 0 else None
    reasons = ["support_penetration"] * len(grasps)
    if collision_check and len(grasps):
        no_lift = lift_blocked(world, hand_poses, start, settings.lift + settings.lift_clearance) & ~blocked
        for k in np.flatnonzero(no_lift):
            reasons[k] = "lift_blocked"
        blocked = blocked | no_lift
    tried = np.flatnonzero(~blocked)
    margin = np.full(len(grasps), np.nan)
    if collision_check and settings.quality is not None and len(tried):
        margin[tried], fits = world.grasp_verdicts(grasps[tried], settings.quality)
        for k, fit in zip(tried, fits):
            reasons[k] = fit.value
        tried = tried[np.argsort(-margin[tried], kind="stable")]  # best margin first
        tried = tried[np.asarray([reasons[k] == GraspFit.holds.value for k in tried], dtype=bool)]

    def goals(tried):
        out = _core.build_goal_set(
            ik_solver(world, ik),
            checker,
            hand_checker,
            hand_poses[tried],
            start,
            settings.to_native(),
            problem,
            float(settings.approach_clearance),
            None if seeds is None else seeds[tried],
        )  # the seeds follow the order tried
        for k, reason in zip(tried, out.reasons):
            reasons[k] = reason.name
        return out

    out = goals(tried)
    unsure = np.flatnonzero([r == GraspFit.slips.value for r in reasons])
    look = _second_look(world, settings)
    if not len(out.goals) and len(unsure) and look is not None:
        # the reachable ones only (the budget goes to grasps that can become goals), best margin first
        tried = unsure[np.argsort(-margin[unsure], kind="stable")]
        reachable = np.unique(tried[np.asarray(goals(tried).grasp_index, dtype=int)])
        held = look(grasps[reachable])
        for k in np.union1d(reachable[~held], [k for k in unsure if reasons[k] == "over_cap"]).astype(int):
            reasons[k] = GraspFit.slips.value  # failed in physics, or not looked at: the quality's verdict
        tried = reachable[held][np.argsort(-margin[reachable[held]], kind="stable")]
        out = goals(tried)
    grasp_index = tried[np.asarray(out.grasp_index, dtype=int)] if len(tried) else np.zeros(0, int)
    goals_, tails = np.asarray(out.goals), np.asarray(out.tails)
    if collision_check and len(goals_):  # the whole arm under the lift (the hand alone was checked before IK)
        stuck = lift_blocked_configurations(world, goals_, settings.lift, settings.lift_clearance)
        for k in grasp_index[stuck]:
            reasons[k] = "lift_blocked"
        goals_, tails, grasp_index = goals_[~stuck], tails[~stuck], grasp_index[~stuck]
    return GoalSet(goals_, tails, grasp_index.astype(int), grasps, reasons, float(out.seconds), adjusted, margin)
