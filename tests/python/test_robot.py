"""Robot kinematics against PyBullet (independent implementation) and finite differences."""

import os

import numpy as np
import pybullet as pb
import pytest

from pickplan.core import robots


def _load_in_bullet(cid, robot):
    body = pb.loadURDF(robot.urdf_path, useFixedBase=True, physicsClientId=cid)
    name_to_index = {pb.getBodyInfo(body, physicsClientId=cid)[0].decode(): -1}
    movable = []
    for j in range(pb.getNumJoints(body, physicsClientId=cid)):
        info = pb.getJointInfo(body, j, physicsClientId=cid)
        name_to_index[info[12].decode()] = j
        if info[2] != pb.JOINT_FIXED:
            movable.append((info[1].decode(), j))
    return body, name_to_index, movable


def _set_q(cid, body, movable, robot, q):
    for name, j in movable:
        pb.resetJointState(body, j, q[robot.joint_names.index(name)], physicsClientId=cid)


def _quat_to_matrix(q):
    return np.array(pb.getMatrixFromQuaternion(q)).reshape(3, 3)


def test_panda_model_matches_urdf(panda):
    assert panda.dof == 9
    assert panda.joint_names[:7] == [f"panda_joint{i}" for i in range(1, 8)]
    assert panda.joint_names[7:] == ["panda_finger_joint1", "panda_finger_joint2"]
    assert panda.hand_link in panda.link_names and all(f in panda.link_names for f in panda.finger_links)
    np.testing.assert_allclose(panda.lower_limits[:7], [-2.9671, -1.8326, -2.9671, -3.1416, -2.9671, -0.0873, -2.9671])
    np.testing.assert_allclose(panda.velocity_limits[:4], 2.175)
    assert panda.native.mimic["panda_finger_joint2"][0] == "panda_finger_joint1"


def test_fk_matches_pybullet_1000_random_configurations(panda, bullet):
    body, index, movable = _load_in_bullet(bullet, panda)
    Q = panda.random_configurations(1000, seed=1)
    poses = panda.fk_batch(Q)
    worst_p = worst_r = 0.0
    for b, q in enumerate(Q):
        _set_q(bullet, body, movable, panda, q)
        states = pb.getLinkStates(
            body,
            list(range(pb.getNumJoints(body, physicsClientId=bullet))),
            computeForwardKinematics=True,
            physicsClientId=bullet,
        )
        for li, name in enumerate(panda.link_names):
            j = index[name]
            if j < 0:
                # The base pose PyBullet reports is its inertial frame: undo the inertial offset.
                com_pos, com_orn = pb.getBasePositionAndOrientation(body, physicsClientId=bullet)
                ipos, iorn = pb.getDynamicsInfo(body, -1, physicsClientId=bullet)[3:5]
                inv_pos, inv_orn = pb.invertTransform(ipos, iorn)
                pos, orn = pb.multiplyTransforms(com_pos, com_orn, inv_pos, inv_orn)
            else:
                pos, orn = states[j][4], states[j][5]
            worst_p = max(worst_p, np.abs(poses[b, li, :3, 3] - pos).max())
            worst_r = max(worst_r, np.abs(poses[b, li, :3, :3] - _quat_to_matrix(orn)).max())
    # PyBullet parses URDF origins in single precision (0.333 -> 0.33300000429), so it agrees
    # only to ~1e-7; the 1e-9 check is against the independent double-precision reference below.
    assert worst_p <= 1e-6, worst_p
    assert worst_r <= 1e-6, worst_r


def _rpy_matrix(r, p, y):
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    Rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    Ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    Rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return Rz @ Ry @ Rx


def _reference_fk(urdf_path, joint_names, q):
    """Link poses by the URDF spec, in numpy double precision, from the XML itself."""
    import xml.etree.ElementTree as ET

    root = ET.parse(urdf_path).getroot()
    joints = {}
    for j in root.findall("joint"):
        o = j.find("origin")
        xyz = np.array([float(v) for v in (o.get("xyz", "0 0 0") if o is not None else "0 0 0").split()])
        rpy = [float(v) for v in (o.get("rpy", "0 0 0") if o is not None else "0 0 0").split()]
        a = j.find("axis")
        axis = np.array([float(v) for v in (a.get("xyz") if a is not None else "1 0 0").split()])
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = _rpy_matrix(*rpy), xyz
        joints[j.find("child").get("link")] = (j.get("name"), j.get("type"), j.find("parent").get("link"), T, axis)
    poses = {}

    def pose(link):
        if link in poses:
            return poses[link]
        if link not in joints:
            poses[link] = np.eye(4)
            return poses[link]
        name, kind, parent, T, axis = joints[link]
        M = pose(parent) @ T
        if kind in ("revolute", "continuous"):
            v = q[joint_names.index(name)]
            k = axis / np.linalg.norm(axis)
            K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
            R = np.eye(4)
            R[:3, :3] = np.eye(3) + np.sin(v) * K + (1 - np.cos(v)) * K @ K
            M = M @ R
        elif kind == "prismatic":
            P = np.eye(4)
            P[:3, 3] = axis / np.linalg.norm(axis) * q[joint_names.index(name)]
            M = M @ P
        poses[link] = M
        return M

    return pose


def test_fk_matches_double_precision_reference_to_1e9(panda):
    Q = panda.random_configurations(1000, seed=8)
    poses = panda.fk_batch(Q)
    worst = 0.0
    for b, q in enumerate(Q):
        pose = _reference_fk(panda.urdf_path, panda.joint_names, q)
        for li, name in enumerate(panda.link_names):
            worst = max(worst, np.abs(poses[b, li] - pose(name)).max())
    assert worst <= 1e-9, worst


def test_jacobian_matches_pybullet(panda, bullet):
    body, index, movable = _load_in_bullet(bullet, panda)
    rng = np.random.default_rng(2)
    for q in panda.random_configurations(50, seed=3):
        _set_q(bullet, body, movable, panda, q)
        for link in ("panda_link4", "panda_hand", "panda_leftfinger"):
            j = index[link]
            p_link = rng.uniform(-0.05, 0.05, 3)
            # Measured: for this URDF PyBullet's localPosition is the URDF link frame.
            lin, ang = pb.calculateJacobian(
                body, j, p_link.tolist(), q.tolist(), [0.0] * 9, [0.0] * 9, physicsClientId=bullet
            )
            J = panda.jacobian(q, link, p_link)
            # PyBullet's single-precision URDF parse bounds the agreement (see the FK test).
            np.testing.assert_allclose(J[:3], np.array(lin), atol=1e-6)
            np.testing.assert_allclose(J[3:], np.array(ang), atol=1e-6)


def _rotation_log(R):
    c = np.clip((np.trace(R) - 1) / 2, -1, 1)
    th = np.arccos(c)
    w = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    return w / 2 if th < 1e-9 else th / (2 * np.sin(th)) * w


def test_jacobian_matches_central_finite_differences(panda):
    h = 1e-6
    rng = np.random.default_rng(4)
    for q in panda.random_configurations(30, seed=5):
        for li in range(len(panda.link_names)):
            p = rng.uniform(-0.1, 0.1, 3)
            J = panda.jacobian(q, li, p)
            J_fd = np.zeros_like(J)
            T0 = panda.fk(q)[li]
            for k in range(panda.dof):
                dq = np.zeros(panda.dof)
                dq[k] = h
                Tp, Tm = panda.fk(q + dq)[li], panda.fk(q - dq)[li]
                J_fd[:3, k] = ((Tp[:3, :3] @ p + Tp[:3, 3]) - (Tm[:3, :3] @ p + Tm[:3, 3])) / (2 * h)
                J_fd[3:, k] = (_rotation_log(Tp[:3, :3] @ T0[:3, :3].T) - _rotation_log(Tm[:3, :3] @ T0[:3, :3].T)) / (
                    2 * h
                )
            np.testing.assert_allclose(J, J_fd, atol=1e-7)


def test_link_jacobians_equal_single_jacobians_and_batch_equals_single(panda):
    Q = panda.random_configurations(5, seed=6)
    for q in Q:
        Js = panda.link_jacobians(q)
        for li in range(len(panda.link_names)):
            np.testing.assert_array_equal(Js[li], panda.jacobian(q, li))
    batch = panda.fk_batch(Q)
    for b, q in enumerate(Q):
        np.testing.assert_array_equal(batch[b], panda.fk(q))


def test_transform_points_equals_fk_of_each_point(panda):
    body = panda.sample_body_points(per_link=5, seed=0)
    Q = panda.random_configurations(4, seed=7)
    X = panda.transform_points(Q, body)
    assert X.shape == (4, len(body), 3)
    for t, q in enumerate(Q):
        T = panda.fk(q)
        expect = np.einsum("nij,nj->ni", T[body.links, :3, :3], body.points) + T[body.links, :3, 3]
        np.testing.assert_allclose(X[t], expect, atol=1e-12)


def test_body_points_lie_on_link_meshes_and_are_seeded(panda):
    a = panda.sample_body_points(per_link=20, seed=11)
    b = panda.sample_body_points(per_link=20, seed=11)
    c = panda.sample_body_points(per_link=20, seed=12)
    np.testing.assert_array_equal(a.points, b.points)
    assert not np.array_equal(a.points, c.points)
    # The fixed base (panda_link0) is excluded; link8 and grasptarget have no collision geometry.
    assert panda.link_names[0] not in [panda.link_names[i] for i in panda.moving_links()]
    assert len(a) == 10 * 20 and 0 not in set(a.links.tolist())
    np.testing.assert_allclose(np.linalg.norm(a.normals, axis=1), 1.0, atol=1e-9)
    hand = panda.link_index("panda_hand")
    mesh = panda.collision_meshes(hand)
    d = np.abs(mesh.nearest.signed_distance(a.points[a.links == hand]))
    assert d.max() < 1e-6


def test_with_base_moves_every_link(panda):
    T = np.eye(4)
    T[:3, 3] = [0.1, -0.2, 0.3]
    c, s = np.cos(0.4), np.sin(0.4)
    T[:2, :2] = [[c, -s], [s, c]]
    moved = panda.with_base(T)
    q = panda.ready_configuration
    np.testing.assert_allclose(moved.fk(q), np.einsum("ij,ljk->lik", T, panda.fk(q)), atol=1e-12)
    assert np.array_equal(panda.base_pose, np.eye(4))  # the original is unchanged


@pytest.mark.parametrize(
    "bad, message",
    [
        (np.zeros(7), "expected 9 joint values, got 7"),
        (np.array([0.0] * 8 + [np.nan]), "NaN or infinite"),
        (np.array([0.0] * 8 + [np.inf]), "NaN or infinite"),
        (np.zeros((2, 9)), "expected a 1-D array"),
    ],
)
def test_bad_configurations_raise_clear_errors(panda, bad, message):
    with pytest.raises(ValueError, match=message):
        panda.fk(bad)


def test_bad_batch_and_link_inputs(panda):
    with pytest.raises(ValueError, match=r"expected shape \(B, 9\), got \(3, 7\)"):
        panda.fk_batch(np.zeros((3, 7)))
    with pytest.raises(ValueError, match="unknown link 'panda_nose'"):
        panda.jacobian(panda.ready_configuration, "panda_nose")
    with pytest.raises(ValueError, match=r"point: expected shape \(3,\)"):
        panda.jacobian(panda.ready_configuration, "panda_hand", np.zeros(2))
    with pytest.raises(ValueError, match="not a rigid transform"):
        panda.with_base(np.ones((4, 4)))


def test_missing_urdf_names_the_path(tmp_path):
    path = tmp_path / "nope.urdf"
    with pytest.raises(FileNotFoundError, match="nope.urdf"):
        robots.Robot.from_urdf(path)


def test_malformed_urdf_is_a_value_error(tmp_path):
    path = tmp_path / "broken.urdf"
    path.write_text("<robot name='x'><link name='a'/><joint name='j' type='revolute'><parent link='a'/>")
    with pytest.raises(ValueError, match="malformed URDF"):
        robots.Robot.from_urdf(path)
    path.write_text("this is not xml at all")
    with pytest.raises(ValueError, match="malformed URDF"):
        robots.Robot.from_urdf(path)


def test_missing_mesh_names_mesh_and_link(tmp_path):
    path = tmp_path / "r.urdf"
    path.write_text("""<robot name="r"><link name="base"><collision><geometry>
      <mesh filename="package://nowhere/ghost.obj"/></geometry></collision></link></robot>""")
    with pytest.raises(FileNotFoundError, match=r"ghost\.obj.*'base'"):
        robots.Robot.from_urdf(path)


def test_import_panda_from_fresh_interpreter():
    import subprocess
    import sys

    out = subprocess.run(
        [sys.executable, "-c", "from pickplan.core import robots; r = robots.panda(); print(r.dof, r.link_names)"],
        capture_output=True,
        text=True,
        check=True,
        cwd=os.path.dirname(__file__),
    )
    assert out.stdout.startswith("9 ['panda_link0'")
