"""PyBullet bodies for pickplan's objects, table and robot, and the quaternion conventions they use.

Kept apart from scene generation (``scenes``) so that execution, grasp verification and scene
generation build bodies the same way.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, List, Optional, Sequence, Tuple

import numpy as np

from pickplan.core import objects as objects_mod
from pickplan.core.panda import PANDA, panda_urdf_path

if TYPE_CHECKING:  # a table is read for its size and pose only
    from pickplan.sim.scenes import Scene, Table


def _panda_defaults() -> Tuple[str, Tuple[float, ...]]:
    """URDF path and ready configuration of the Panda."""
    return panda_urdf_path(), tuple(PANDA.ready)


def _inertial_frame(model: objects_mod.ObjectModel) -> Tuple[np.ndarray, np.ndarray]:
    """Object -> principal inertial frame (4x4) and the principal moments."""
    moments, axes = np.linalg.eigh(model.inertia)
    if np.linalg.det(axes) < 0:
        axes[:, 2] *= -1
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = axes, model.com
    return T, np.maximum(moments, 1e-9)


def _mat_to_quat(R: np.ndarray) -> List[float]:
    """Rotation matrix -> (x, y, z, w), the numerically stable branch per largest diagonal term."""
    m = R
    tr = m[0, 0] + m[1, 1] + m[2, 2]
    if tr > 0:
        s = 2.0 * math.sqrt(tr + 1.0)
        return [(m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s, 0.25 * s]
    i = int(np.argmax([m[0, 0], m[1, 1], m[2, 2]]))
    j, k = (i + 1) % 3, (i + 2) % 3
    s = 2.0 * math.sqrt(max(1.0 + m[i, i] - m[j, j] - m[k, k], 1e-300))
    q = [0.0, 0.0, 0.0, 0.0]
    q[i] = 0.25 * s
    q[j] = (m[j, i] + m[i, j]) / s
    q[k] = (m[k, i] + m[i, k]) / s
    q[3] = (m[k, j] - m[j, k]) / s
    return q


def _quat_to_mat(q) -> np.ndarray:
    x, y, z, w = q
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def add_object_body(client: int, model: objects_mod.ObjectModel, pose: np.ndarray, friction: float = 0.8) -> int:
    """Create a dynamic body for ``model`` at ``pose`` (object frame -> world); returns its id.
    ``friction`` applies unless the model has its own (procedural objects do).

    The body's base frame is the object's principal inertial frame, so PyBullet's base pose (which
    it always reports for the inertial frame) needs no further correction; ``object_pose`` converts
    back to the object frame.
    """
    from pickplan.sim.bullet import pb

    T_in, moments = _inertial_frame(model)
    T_shape = np.linalg.inv(T_in)  # the object (mesh) frame seen from the inertial frame
    shape = pb.createCollisionShape(
        pb.GEOM_MESH,
        fileName=model.collision_obj_path(),
        collisionFramePosition=T_shape[:3, 3].tolist(),
        collisionFrameOrientation=_mat_to_quat(T_shape[:3, :3]),
        physicsClientId=client,
    )
    if shape < 0:
        raise RuntimeError(f"PyBullet could not create the collision shape of {model.name}")
    T_base = np.asarray(pose, dtype=float) @ T_in
    body = pb.createMultiBody(
        baseMass=model.mass,
        baseCollisionShapeIndex=shape,
        basePosition=T_base[:3, 3].tolist(),
        baseOrientation=_mat_to_quat(T_base[:3, :3]),
        physicsClientId=client,
    )
    own = getattr(model, "friction", None)  # an object's own friction wins over the scene's default
    pb.changeDynamics(
        body,
        -1,
        localInertiaDiagonal=moments.tolist(),
        lateralFriction=friction if own is None else own,
        rollingFriction=1e-4,
        spinningFriction=1e-3,
        restitution=0.0,
        physicsClientId=client,
    )
    return body


def object_pose(client: int, body: int, model: objects_mod.ObjectModel) -> np.ndarray:
    """The object-frame pose (4x4) of a body created by ``add_object_body``."""
    from pickplan.sim.bullet import pb

    pos, quat = pb.getBasePositionAndOrientation(body, physicsClientId=client)
    T_base = np.eye(4)
    T_base[:3, :3], T_base[:3, 3] = _quat_to_mat(quat), pos
    return T_base @ np.linalg.inv(_inertial_frame(model)[0])


def add_table(client: int, table: Table, friction: float = 0.8) -> int:
    from pickplan.sim.bullet import pb

    half = (np.asarray(table.size, dtype=float) / 2).tolist()
    shape = pb.createCollisionShape(pb.GEOM_BOX, halfExtents=half, physicsClientId=client)
    visual = pb.createVisualShape(pb.GEOM_BOX, halfExtents=half, rgbaColor=[0.75, 0.65, 0.5, 1], physicsClientId=client)
    T = np.asarray(table.pose, dtype=float)
    body = pb.createMultiBody(
        0.0,
        shape,
        visual,
        basePosition=T[:3, 3].tolist(),
        baseOrientation=_mat_to_quat(T[:3, :3]),
        physicsClientId=client,
    )
    pb.changeDynamics(body, -1, lateralFriction=friction, physicsClientId=client)
    return body


def add_obstacle_body(client: int, obstacle, friction: float = 0.8) -> int:
    """A static body for a ``shapes.Obstacle``: PyBullet's own box, cylinder or sphere for a
    primitive (exact, as the planner's), the mesh file for a mesh (convex parts as PyBullet reads it)."""
    import pybullet as pb

    shape = obstacle.shape
    kind = shape.kind.value
    if kind == "box":
        geometry = dict(shapeType=pb.GEOM_BOX, halfExtents=[0.5 * v for v in shape.size])
    elif kind == "cylinder":
        geometry = dict(shapeType=pb.GEOM_CYLINDER, radius=shape.size[0])
    elif kind == "sphere":
        geometry = dict(shapeType=pb.GEOM_SPHERE, radius=shape.size[0])
    else:
        geometry = dict(shapeType=pb.GEOM_MESH, fileName=shape.file, meshScale=list(shape.size))
    collision = pb.createCollisionShape(
        **geometry, **({"height": shape.size[1]} if kind == "cylinder" else {}), physicsClientId=client
    )
    visual = pb.createVisualShape(
        **geometry,
        **({"length": shape.size[1]} if kind == "cylinder" else {}),
        rgbaColor=[0.6, 0.55, 0.5, 1],
        physicsClientId=client,
    )
    if collision < 0:
        raise RuntimeError(f"PyBullet could not create the collision shape of obstacle {obstacle.name!r}")
    T = np.asarray(obstacle.pose, dtype=float)
    body = pb.createMultiBody(
        0.0,
        collision,
        visual,
        basePosition=T[:3, 3].tolist(),
        baseOrientation=_mat_to_quat(T[:3, :3]),
        physicsClientId=client,
    )
    pb.changeDynamics(body, -1, lateralFriction=friction, physicsClientId=client)
    return body


def add_robot(client: int, base: np.ndarray, q: Optional[Sequence] = None, urdf: Optional[str] = None) -> int:
    """A robot with a fixed base (``urdf``; default the Panda); ``q`` sets the movable joints in URDF
    order (the Panda's: 7 arm + 2 fingers; None or empty: its ready configuration, the Panda only)."""
    from pickplan.sim.bullet import pb

    panda_urdf, ready = _panda_defaults()
    if urdf is not None and (q is None or len(q) == 0):
        raise ValueError("robot configuration: give the joint values of a robot other than the Panda")
    urdf = panda_urdf if urdf is None else urdf
    T = np.asarray(base, dtype=float)
    body = pb.loadURDF(
        urdf,
        basePosition=T[:3, 3].tolist(),
        baseOrientation=_mat_to_quat(T[:3, :3]),
        useFixedBase=True,
        physicsClientId=client,
    )
    q = ready if q is None or len(q) == 0 else q
    movable = [
        j
        for j in range(pb.getNumJoints(body, physicsClientId=client))
        if pb.getJointInfo(body, j, physicsClientId=client)[2] != pb.JOINT_FIXED
    ]
    if len(q) != len(movable):
        raise ValueError(f"robot configuration: expected {len(movable)} joint values, got {len(q)}")
    for j, v in zip(movable, q):
        pb.resetJointState(body, j, float(v), physicsClientId=client)
        # hold the pose against gravity while objects settle
        pb.setJointMotorControl2(
            body, j, pb.POSITION_CONTROL, targetPosition=float(v), force=500.0, physicsClientId=client
        )
    return body


def open_world(scene: "Scene", robot, q0, models: dict, time_step: float, solver_iterations: int) -> Tuple[int, dict]:
    """A fresh DIRECT client with gravity, the time step and the solver's iterations, holding the scene's
    table (if any) and obstacles, ``robot`` (a described robot, at its base) at ``q0`` and the scene's objects (``models`` by
    name), in ``scenes.load_into_pybullet``'s order: (client, body ids by name, "table" and "robot")."""
    from pickplan.sim.bullet import connect, pb

    client = connect()
    try:
        pb.resetSimulation(physicsClientId=client)
        pb.setPhysicsEngineParameter(
            deterministicOverlappingPairs=1, numSolverIterations=solver_iterations, physicsClientId=client
        )
        pb.setGravity(0, 0, -9.81, physicsClientId=client)
        pb.setTimeStep(time_step, physicsClientId=client)
        ids = {} if scene.table is None else {"table": add_table(client, scene.table)}
        ids.update({o.name: add_obstacle_body(client, o) for o in scene.obstacles})
        ids["robot"] = add_robot(client, robot.base_pose, q0, robot.description.urdf)
        for o in scene.objects:
            ids[o.name] = add_object_body(client, models[o.name], o.pose)
    except BaseException:
        pb.disconnect(client)
        raise
    return client, ids
