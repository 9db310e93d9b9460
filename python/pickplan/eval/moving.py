"""Picking a moving target in PyBullet (issue 36): observe, replan at a fixed rate, execute, grasp in pace.

``run_episode(scene, path, method, settings)``: the scene's target rides a belt or is nudged
(``sim.conveyor``; the scene from ``conveyor_scene``), and the robot

1. observes: at ``observe_rate`` the target's true pose with seeded noise (``noise`` m on each axis,
   ``yaw_noise`` rad about the vertical) goes to a ``MotionEstimator``; it holds its start for
   ``observe_time`` first (open_loop stops observing once it planned);
2. plans to the target's pose predicted for the hand's arrival (``omg.moving.MovingPlanner``) and follows
   the plan at its timing (one sample per control step, velocity feed-forward). ``MovingMethod``:
   closed_loop replans warm at ``rate`` from the commanded configuration and velocity, until the
   arrival is less than ``commit_time`` away; fresh does the same from scratch; open_loop plans once.
   A new plan is followed when it passes the success test and arrives no later than the plan followed, or
   the plan followed has gone stale (the target will not be where it goes); otherwise that one goes on;
3. grasps in pace: from the arrival the hand keeps the target's estimated velocity while the fingers
   close (execution's closing time) and for ``carry_time`` into the lift; then execution's lift and hold.

Success is execution's test (``lifted_and_held``). Planning takes no simulated time (the simulation
waits for it); its CPU time is reported apart. Deterministic for a seed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import List, Optional

import numpy as np

from pickplan.core import objects as objects_mod
from pickplan.core import robots
from pickplan.core.settings import Option
from pickplan.omg.moving import MotionEstimator, MovingPlanner, MovingSettings, ReplanMode
from pickplan.omg.planner import OMGPlanner, OMGSettings
from pickplan.omg.replan import Replanner, ReplanSettings
from pickplan.sim.arm_sim import ArmSim, follow, hold, open_sim
from pickplan.sim.conveyor import Conveyor, TargetPath
from pickplan.sim.execution import ExecutionSettings, lifted_and_held
from pickplan.sim.hand_path import hand_path
from pickplan.sim.scenes import Scene


class MovingMethod(Option):
    closed_loop = "closed_loop"  # warm replans at the observation rate (omg.replan)
    fresh = "fresh"  # plans from scratch at the same rate
    open_loop = "open_loop"  # one plan to the pose predicted for the arrival


class EpisodeStatus(Option):
    lifted = "lifted"  # success: held and lifted at the end
    dropped = "dropped"  # between the fingers after closing, not held or not lifted at the end
    missed = "missed"  # the fingers closed without the target between them
    no_plan = "no_plan"  # no plan passed the success test before the target left (or max_time)
    unstable = "unstable"  # the simulation diverged


@dataclass(frozen=True)
class LoopSettings:
    rate: float = 5.0  # Hz: replans
    observe_rate: float = 30.0  # Hz: observations (a camera's frame rate)
    observe_time: float = 0.6  # s observed before the first plan
    noise: float = 0.002  # m, sigma of each observed coordinate
    yaw_noise: float = 0.01  # rad, sigma of the observed turn about the vertical
    window: int = 30  # observations in the velocity fit (1 s)
    jump: float = 0.02  # m from the prediction: a nudge (the fit restarts)
    commit_time: float = 0.3  # s: no replan when the hand arrives sooner
    # A new plan is followed when it arrives no later than the one followed (by delay_slack s), or when the
    # one followed is stale: it meets the target farther than ``stale`` m from where it will be then.
    delay_slack: float = 0.05
    stale: float = 0.01
    max_time: float = 8.0  # s: no arrival by then is no_plan
    carry_time: float = 0.3  # s the hand keeps the target's pace into the lift
    track_rate: float = 60.0  # Hz: waypoints of the hand's path while grasping
    execution: ExecutionSettings = field(default_factory=ExecutionSettings)
    moving: MovingSettings = field(default_factory=MovingSettings)
    replan: ReplanSettings = field(default_factory=ReplanSettings)
    seed: int = 0

    def __post_init__(self):
        for name in ("rate", "observe_rate", "track_rate", "max_time"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ValueError(f"loop settings: {name} must be a finite number > 0, got {value!r}")
        for name in ("observe_time", "noise", "yaw_noise", "commit_time", "carry_time", "delay_slack", "stale"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0):
                raise ValueError(f"loop settings: {name} must be a finite number >= 0, got {value!r}")


@dataclass
class EpisodeResult:
    method: MovingMethod
    status: EpisodeStatus
    lifted: bool
    plans: int  # plans made (each of one or more prediction rounds)
    plan_ms: List[float]  # CPU ms of each (planning and timing)
    planner_ms: List[float]  # of plan_ms, the planner's own (OMGSettings.clock; the rest is the timing)
    arrival: float  # s the hand reached its goal (nan: never)
    miss: float  # m between the target's pose planned for and its true pose on arrival
    target_lift: float  # m
    max_penetration: float  # m, the robot into non-target bodies while approaching
    sim_time: float

    def row(self) -> dict:
        ms = np.asarray(self.plan_ms)
        return {
            "method": str(self.method),
            "status": str(self.status),
            "lifted": self.lifted,
            "plans": self.plans,
            "plan_ms_median": float(np.median(ms)) if len(ms) else float("nan"),
            "plan_ms_max": float(ms.max()) if len(ms) else float("nan"),
            "planner_ms_median": float(np.median(self.planner_ms[1:] or self.planner_ms or [np.nan])),
            "arrival": self.arrival,
            "miss": self.miss,
            "target_lift": self.target_lift,
            "max_penetration": self.max_penetration,
            "sim_time": self.sim_time,
        }


class _MovingSim(ArmSim):
    """The execution's simulation with the belt driven before every step."""

    belt: Optional[Conveyor] = None

    def step(self, watch_contacts: bool = False) -> None:
        if self.belt is not None:
            self.belt.before_step(self.steps * self.s.time_step)
        super().step(watch_contacts)
        if self.belt is not None:
            self.belt.after_step()


def _observe(pose: np.ndarray, rng: np.random.Generator, s: LoopSettings) -> np.ndarray:
    """The pose with seeded noise: its position, and a turn about the vertical."""
    a = rng.normal(0.0, s.yaw_noise)
    turn = np.array([[math.cos(a), -math.sin(a), 0.0], [math.sin(a), math.cos(a), 0.0], [0.0, 0.0, 1.0]])
    out = pose.copy()
    out[:3, :3] = turn @ pose[:3, :3]
    out[:3, 3] += rng.normal(0.0, s.noise, 3)
    return out


class _Episode:
    """One run's state: the simulation, the estimator, the planner and the plan followed."""

    def __init__(self, scene: Scene, path: TargetPath, method: MovingMethod, s: LoopSettings, omg: OMGSettings, cache):
        self.method, self.s = MovingMethod.parse(method, "moving method"), s
        mode = ReplanMode.fresh if self.method is MovingMethod.fresh else ReplanMode.warm
        self.planner = OMGPlanner(None, scene, omg, cache=cache)
        self.mover = MovingPlanner(Replanner(self.planner, s.replan), replace(s.moving, mode=mode))
        world = self.planner.world()
        self.robot = robots.load_robot(s.execution.robot, np.asarray(scene.robot_base, dtype=float))
        models = {o.name: objects_mod.model_from_source(o.name, o.source) for o in scene.objects}
        self.q = np.asarray(world.start, dtype=float)
        self.v = np.zeros_like(self.q)  # the commanded configuration and velocity
        self.estimator = MotionEstimator(s.window, s.jump)
        self.rng = np.random.default_rng(s.seed)
        self.plan, self.k0, self.plan_ms, self.planner_ms = None, 0, [], []
        self.sim = open_sim(scene, self.robot, self.q, s.execution, models, sim_class=_MovingSim)
        try:
            self.sim.belt = Conveyor(
                self.sim.c, self.sim.bodies[scene.target], models[scene.target], path, s.execution.time_step
            )
        except BaseException:
            self.sim.pb.disconnect(self.sim.c)
            raise

    @property
    def t(self) -> float:
        return self.sim.steps * self.s.execution.time_step

    def observe(self) -> None:
        self.estimator.observe(self.t, _observe(self.sim.belt.pose(), self.rng, self.s))

    def tick(self) -> None:
        """A plan when the method makes one now."""
        motion = self.estimator.motion
        if self.t < self.s.observe_time - 1e-9:
            return
        if self.plan is not None and (
            self.method is MovingMethod.open_loop or self.plan.arrival - self.t <= self.s.commit_time
        ):
            return
        new = self.mover.plan(motion, self.t, start=self.q, start_velocity=self.v)
        self.plan_ms.append(1000.0 * new.seconds)
        self.planner_ms.append(1000.0 * new.planner_seconds)
        if new.result.success and (
            self.plan is None
            or new.arrival <= self.plan.arrival + self.s.delay_slack
            or self.stale(motion) > self.s.stale
        ):
            self.plan, self.k0 = new, self.sim.steps

    def stale(self, motion) -> float:
        """m between where the plan followed meets the target and where ``motion`` puts it then."""
        return float(np.linalg.norm(motion.predict(self.plan.arrival)[:3, 3] - self.plan.target_pose[:3, 3]))

    def approach(self) -> bool:
        """Observe, plan and follow until the arrival (True) or max_time (False)."""
        s, sim = self.s, self.sim
        next_tick = next_observation = 0.0
        arm = self.robot.info.arm_dof
        sim.command_fingers(self.q[arm], sim.grip_force)
        while self.t < s.max_time:
            blind = self.method is MovingMethod.open_loop and self.plan is not None
            if self.t >= next_observation - 1e-9 and not blind:
                next_observation += 1.0 / s.observe_rate
                self.observe()
            if self.t >= next_tick - 1e-9:
                next_tick += 1.0 / s.rate
                if not (self.method is MovingMethod.open_loop and self.plan is not None):
                    self.tick()
                if self.plan is None and self.method is MovingMethod.open_loop and self.t >= s.observe_time:
                    return False  # the one plan failed
            self.v = np.zeros(self.robot.dof)
            if self.plan is not None:
                k = sim.steps - self.k0
                timed = self.plan.timed
                if k >= len(timed.q) - 1:
                    self.q = timed.q[-1].copy()
                    return True
                self.q, self.v = timed.q[k + 1], timed.qd[k + 1]
            sim.command_arm(self.q, self.v)
            sim.step(True)
        return False

    def grasp(self) -> tuple:
        """Close in pace with the target, lift (carrying its pace for carry_time), hold: (held, lift m)."""
        s, ex, sim = self.s, self.s.execution, self.sim
        v = self.estimator.motion.velocity if self.estimator.motion is not None else np.zeros(3)
        close = ex.closing_time(self.robot.info)
        n = int(math.ceil((close + ex.lift_duration) * s.track_rate))
        tau = np.arange(1, n + 1) / s.track_rate
        offsets = v[None, :] * np.minimum(tau, close + s.carry_time)[:, None]
        offsets[:, 2] += ex.lift_height * np.clip((tau - close) / ex.lift_duration, 0.0, 1.0)
        path = hand_path(self.robot, self.q, offsets, ex.ik_damping)
        seg = 1.0 / s.track_rate
        steps = max(1, int(round(seg / ex.time_step)))
        sim.command_fingers(self.robot.info.finger_closed, sim.grip_force)
        z0 = sim.belt.z0
        k_close = int(round(close * s.track_rate))
        follow(sim, path[: k_close + 1], [(seg, steps)] * k_close, False, sim.grip_force, False)
        self.held_after_close = sim.held()
        sim.belt.release()  # the fingers hold it now: the belt's hold on it is no match (sim.conveyor)
        follow(sim, path[k_close:], [(seg, steps)] * (n - k_close), False, sim.grip_force, False)
        hold(sim, path[-1], ex.hold_duration, False)
        return sim.held(), float(sim.belt.com()[2] - z0)

    def miss(self) -> float:
        """m between the target's position the plan followed was made for and its true position on arrival."""
        if self.plan is None:
            return float("nan")
        true = self.sim.belt.pose()
        return float(np.linalg.norm(true[:3, 3] - self.plan.target_pose[:3, 3]))


def run_episode(
    scene: Scene,
    path: TargetPath,
    method: MovingMethod,
    settings: LoopSettings = LoopSettings(),
    omg: OMGSettings = OMGSettings(grasp_kind="antipodal", clock="thread_cpu"),
    cache=None,
) -> EpisodeResult:
    """One closed (or open) loop pick of ``scene``'s moving target; see the module doc."""
    ep = _Episode(scene, path, method, settings, omg, cache)
    try:
        arrived = ep.approach()
        arrival, miss = (ep.t, ep.miss()) if arrived else (float("nan"), float("nan"))
        held, lift = ep.grasp() if arrived else (False, 0.0)
        finite = bool(np.all(np.isfinite(ep.sim.joint_positions())) and math.isfinite(lift))
        held_after_close = getattr(ep, "held_after_close", False)
        sim_time, pen = ep.t, max(ep.sim.contacts.values(), default=0.0)
    finally:
        from pickplan.sim.bullet import pb

        pb.disconnect(ep.sim.c)
    success = finite and lifted_and_held(settings.execution, held, lift)
    status = (
        EpisodeStatus.no_plan
        if not arrived
        else EpisodeStatus.unstable
        if not finite
        else EpisodeStatus.lifted
        if success
        else EpisodeStatus.dropped
        if held_after_close
        else EpisodeStatus.missed
    )
    return EpisodeResult(
        ep.method,
        status,
        bool(success),
        len(ep.plan_ms),
        ep.plan_ms,
        ep.planner_ms,
        arrival,
        miss,
        lift,
        float(pen),
        sim_time,
    )
