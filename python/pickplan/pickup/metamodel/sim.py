"""Moving-gripper grasp simulation in PyBullet (Sec. IV of Thakar et al.).

One call, one private DIRECT client: the gripper (assets/gripper_2f85.urdf) is driven along
its +x axis at constant speed S_g by a fixed constraint whose target moves every step (the
body is never teleported). Its coupled fingers close at speed S_c, starting at
t' - (w_open - w_part) / (2 S_c) so that, for the nominal part pose, closing ends exactly at
the grasp point at t'. The part sits on the table at its nominal pose offset by
(x, y, phi) in the frame B (world-aligned, at the part's nominal origin; the world is aligned
with the gripper at t', so these are also offsets relative to the gripper). After t' the
gripper keeps moving at S_g and lifts for `hold_time`.

Success is conservative, as in the paper: at the end the part is between the pads (the
fingers did not close on nothing), it has been lifted off the table with the gripper, and the
distance of a fixed point on the part (its centre of mass) from the TCP has changed by less than
`drift_threshold` since `settle_time` after t'.
"""

from __future__ import annotations

import math
import os
import time
from dataclasses import dataclass

import numpy as np

from pickplan.pickup.metamodel.parts import Part, get_part
from pickplan.sim.bullet import connect, pb as pybullet
from pickplan.core.paths import assets_dir

OPEN_WIDTH = 0.085  # distance between the pads when open (2F-85 stroke)
FINGER_HALF_X = 0.011  # half the pad width along the approach axis
_LEFT, _RIGHT = 0, 1  # finger joint indices in the URDF


def default_urdf_path() -> str:
    """assets/gripper_2f85.urdf, installed inside the package (or the source tree's assets/)."""

    return os.path.join(assets_dir(), "gripper_2f85.urdf")


@dataclass(frozen=True)
class SimConfig:
    """Physics and success-test settings. Speeds outside sg_range / sc_range raise ValueError
    (the meta-model is only valid where it was built)."""

    time_step: float = 1.0 / 240.0
    solver_iterations: int = 20
    finger_force: float = 60.0  # N per finger (2F-85: 20..235 N)
    gripper_max_force: float = 2000.0  # N, the driving constraint
    pad_friction: float = 1.0
    table_friction: float = 0.4
    friction_jitter: float = 0.1  # relative, seeded: models physics uncertainty at the GSB
    hold_time: float = 0.35  # s the gripper keeps moving after t'
    settle_time: float = 0.1  # s after t' when the reference relative position is taken
    lift_speed: float = 0.1  # m/s, reached over lift_ramp
    lift_ramp: float = 0.05
    drift_threshold: float = 0.005  # m
    min_lift_fraction: float = 0.5  # part must rise by this fraction of the gripper's lift
    clearance: float = 0.005  # m; the run starts this far before any possible contact
    sg_range: tuple = (0.05, 1.2)  # m/s, modelled gripper speeds (the paper reports up to 1.05)
    sc_range: tuple = (0.05, 0.15)  # m/s, modelled closing speeds (per finger)
    urdf_path: str = ""  # empty: default_urdf_path()


@dataclass(frozen=True)
class GraspOutcome:
    success: bool
    reason: str  # 'success', 'missed', 'dropped', 'slipped'
    drift: float  # m, change of the part-to-TCP distance during the hold
    lift: float  # m, rise of the part
    steps: int
    wall_time: float


def check_speeds(s_g: float, s_c: float, config: SimConfig) -> None:
    """Raise ValueError if (s_g, s_c) lies outside the modelled range."""
    lo, hi = config.sg_range
    if not (lo <= s_g <= hi):
        raise ValueError(f"gripper speed S_g={s_g} m/s outside the modelled range [{lo}, {hi}]")
    lo, hi = config.sc_range
    if not (lo <= s_c <= hi):
        raise ValueError(f"closing speed S_c={s_c} m/s outside the modelled range [{lo}, {hi}]")


def closing_time(part: Part, s_c: float) -> float:
    """Time the fingers need to close from open onto the nominal part width."""
    return (OPEN_WIDTH - part.strategy.grasp_width) / (2.0 * s_c)


def _yaw_quat(yaw: float):
    return pybullet.getQuaternionFromEuler([0.0, 0.0, yaw])


def nominal_part_pose(part: Part):
    """Part origin (x, y) and yaw in the world such that the TCP at t' (world origin in x, y,
    yaw 0) is at the strategy's grasp pose."""
    s = part.strategy
    yaw = -s.tcp_yaw
    c, sn = math.cos(yaw), math.sin(yaw)
    tx, ty = s.tcp_xyz[0], s.tcp_xyz[1]
    return np.array([-(c * tx - sn * ty), -(sn * tx + c * ty)]), yaw


def _create_mesh_part(cid: int, part: Part, xy, yaw, friction: float) -> int:
    """A part from a mesh: its convex hull (PyBullet's dynamic meshes are convex) about the mesh's
    own centre of mass (Shape.pos)."""
    shape = part.shapes[0]
    com = np.asarray(shape.pos, float)
    col = pybullet.createCollisionShape(
        pybullet.GEOM_MESH, vertices=[list(np.asarray(v) - com) for v in shape.size], physicsClientId=cid
    )
    c, sn = math.cos(yaw), math.sin(yaw)
    world_com = [xy[0] + c * com[0] - sn * com[1], xy[1] + sn * com[0] + c * com[1], com[2]]
    body = pybullet.createMultiBody(
        baseMass=part.mass,
        baseCollisionShapeIndex=col,
        basePosition=world_com,
        baseOrientation=_yaw_quat(yaw),
        physicsClientId=cid,
    )
    pybullet.changeDynamics(body, -1, lateralFriction=friction, physicsClientId=cid)
    return body


def _create_part(cid: int, part: Part, xy, yaw, friction: float) -> int:
    if part.shapes[0].kind == "mesh":
        return _create_mesh_part(cid, part, xy, yaw, friction)
    kinds = {"box": pybullet.GEOM_BOX, "cylinder": pybullet.GEOM_CYLINDER}
    shape_types, half_extents, radii, lengths, positions = [], [], [], [], []
    vols = []
    for s in part.shapes:
        shape_types.append(kinds[s.kind])
        if s.kind == "box":
            half_extents.append([v / 2 for v in s.size])
            radii.append(0.0)
            lengths.append(0.0)
            vols.append(s.size[0] * s.size[1] * s.size[2])
        else:
            half_extents.append([0.0, 0.0, 0.0])
            radii.append(s.size[0])
            lengths.append(s.size[1])
            vols.append(math.pi * s.size[0] ** 2 * s.size[1])
        positions.append(list(s.pos))
    w = np.asarray(vols) / np.sum(vols)
    com = (w[:, None] * np.asarray(positions)).sum(axis=0)
    # Shapes are placed relative to the centre of mass (the multibody's base frame).
    rel = [list(np.asarray(p) - com) for p in positions]
    col = pybullet.createCollisionShapeArray(
        shapeTypes=shape_types,
        halfExtents=half_extents,
        radii=radii,
        lengths=lengths,
        collisionFramePositions=rel,
        physicsClientId=cid,
    )
    c, sn = math.cos(yaw), math.sin(yaw)
    world_com = [xy[0] + c * com[0] - sn * com[1], xy[1] + sn * com[0] + c * com[1], com[2]]
    body = pybullet.createMultiBody(
        baseMass=part.mass,
        baseCollisionShapeIndex=col,
        basePosition=world_com,
        baseOrientation=_yaw_quat(yaw),
        physicsClientId=cid,
    )
    pybullet.changeDynamics(body, -1, lateralFriction=friction, physicsClientId=cid)
    return body


def simulate_grasp(
    part, offset, s_g: float, s_c: float, config: SimConfig = SimConfig(), seed: int = 0
) -> GraspOutcome:
    """Simulate one pick-up on the move. offset = (x [m], y [m], phi [rad]) of the part from
    its nominal pose in frame B. Deterministic for a given (inputs, config, seed)."""
    part = get_part(part)
    offset = np.asarray(offset, dtype=float)
    if offset.shape != (3,):
        raise ValueError(f"expected offset of shape (3,) = (x, y, phi), got {offset.shape}")
    if not np.all(np.isfinite(offset)):
        raise ValueError("offset must be finite")
    check_speeds(s_g, s_c, config)
    rng = np.random.default_rng(seed)
    jit = 1.0 + config.friction_jitter * rng.uniform(-1.0, 1.0, size=3)
    t_wall = time.perf_counter()
    dt = config.time_step
    t_close = closing_time(part, s_c)
    z_tcp = part.strategy.tcp_xyz[2]

    nominal_xy, nominal_yaw = nominal_part_pose(part)
    xy = nominal_xy + offset[:2]
    yaw = nominal_yaw + offset[2]
    # Start the run where the fingers are still open and no contact is possible yet: the
    # motion before that is contact-free and constant-speed, so skipping it changes nothing.
    # The grasp point moves by at most |p| + R*|phi| under the offset.
    reach = part.footprint_radius + FINGER_HALF_X + config.clearance
    shift = float(np.hypot(*offset[:2])) + part.footprint_radius * abs(offset[2])
    d_start = max(s_g * t_close, reach + shift) + s_g * dt
    t0 = -d_start / s_g  # t' = 0
    n_steps = int(math.ceil((config.hold_time - t0) / dt))

    cid = connect()
    try:
        pybullet.setGravity(0, 0, -9.81, physicsClientId=cid)
        pybullet.setPhysicsEngineParameter(
            fixedTimeStep=dt,
            numSolverIterations=config.solver_iterations,
            deterministicOverlappingPairs=1,
            physicsClientId=cid,
        )
        plane = pybullet.createCollisionShape(pybullet.GEOM_PLANE, physicsClientId=cid)
        table = pybullet.createMultiBody(0, plane, physicsClientId=cid)
        pybullet.changeDynamics(table, -1, lateralFriction=config.table_friction * jit[0], physicsClientId=cid)
        body = _create_part(cid, part, xy, yaw, part.lateral_friction * jit[1])

        urdf = config.urdf_path or default_urdf_path()
        if not os.path.exists(urdf):
            raise FileNotFoundError(f"gripper URDF not found: {urdf}")
        start = [s_g * t0, 0.0, z_tcp]
        grip = pybullet.loadURDF(
            urdf,
            start,
            [0, 0, 0, 1],
            useFixedBase=False,
            flags=pybullet.URDF_USE_INERTIA_FROM_FILE,
            physicsClientId=cid,
        )
        for link in (_LEFT, _RIGHT):
            pybullet.changeDynamics(grip, link, lateralFriction=config.pad_friction * jit[2], physicsClientId=cid)
        pybullet.resetBaseVelocity(grip, [s_g, 0, 0], [0, 0, 0], physicsClientId=cid)
        drive = pybullet.createConstraint(
            grip, -1, -1, -1, pybullet.JOINT_FIXED, [0, 0, 0], [0, 0, 0], start, physicsClientId=cid
        )
        # Couple the fingers (the 2F-85 linkage closes them symmetrically).
        gear = pybullet.createConstraint(
            grip, _LEFT, grip, _RIGHT, pybullet.JOINT_GEAR, [0, 1, 0], [0, 0, 0], [0, 0, 0], physicsClientId=cid
        )
        pybullet.changeConstraint(gear, gearRatio=-1, maxForce=500, erp=0.8, physicsClientId=cid)
        return _run(cid, grip, body, drive, part, s_g, s_c, t0, t_close, n_steps, z_tcp, config, t_wall)
    finally:
        pybullet.disconnect(physicsClientId=cid)


def _rel_distance(cid: int, grip: int, body: int) -> float:
    g = pybullet.getBasePositionAndOrientation(grip, physicsClientId=cid)[0]
    p = pybullet.getBasePositionAndOrientation(body, physicsClientId=cid)[0]
    return math.dist(g, p)


def _run(cid, grip, body, drive, part, s_g, s_c, t0, t_close, n_steps, z_tcp, config, t_wall):
    dt = config.time_step
    vmode = pybullet.VELOCITY_CONTROL
    z_part0 = pybullet.getBasePositionAndOrientation(body, physicsClientId=cid)[0][2]
    closing = False
    ref = None
    lift = 0.0
    drift = 0.0
    reason = None
    for i in range(1, n_steps + 1):
        t = t0 + i * dt
        if not closing and t >= -t_close:
            closing = True
            pybullet.setJointMotorControlArray(
                grip,
                [_LEFT, _RIGHT],
                vmode,
                targetVelocities=[s_c, s_c],
                forces=[config.finger_force] * 2,
                physicsClientId=cid,
            )
        elif not closing:
            pybullet.setJointMotorControlArray(
                grip,
                [_LEFT, _RIGHT],
                vmode,
                targetVelocities=[0.0, 0.0],
                forces=[config.finger_force] * 2,
                physicsClientId=cid,
            )
        tau = max(0.0, t)
        if tau < config.lift_ramp:
            lift = config.lift_speed * tau * tau / (2 * config.lift_ramp)
        else:
            lift = config.lift_speed * (tau - config.lift_ramp / 2)
        pybullet.changeConstraint(
            drive, jointChildPivot=[s_g * t, 0.0, z_tcp + lift], maxForce=config.gripper_max_force, physicsClientId=cid
        )
        pybullet.stepSimulation(physicsClientId=cid)
        if ref is None and t >= config.settle_time:
            if _finger_gap(cid, grip) < 0.002:
                reason = "missed"  # fingers closed on nothing: the part is not between them
                break
            ref = _rel_distance(cid, grip, body)
        elif ref is not None:
            drift = abs(_rel_distance(cid, grip, body) - ref)
            if drift > config.drift_threshold:
                reason = "slipped"
                break
    part_lift = pybullet.getBasePositionAndOrientation(body, physicsClientId=cid)[0][2] - z_part0
    if reason is None:
        if _finger_gap(cid, grip) < 0.002:
            reason = "missed"
        elif part_lift < config.min_lift_fraction * lift:
            reason = "dropped"
        else:
            reason = "success"
    return GraspOutcome(
        success=reason == "success",
        reason=reason,
        drift=float(drift),
        lift=float(part_lift),
        steps=i,
        wall_time=time.perf_counter() - t_wall,
    )


def _finger_gap(cid: int, grip: int) -> float:
    ql = pybullet.getJointState(grip, _LEFT, physicsClientId=cid)[0]
    qr = pybullet.getJointState(grip, _RIGHT, physicsClientId=cid)[0]
    return OPEN_WIDTH - ql - qr
