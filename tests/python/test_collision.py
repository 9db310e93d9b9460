"""FCL collision checker (pickplan.core.collision) against PyBullet's closest points, plus the
Python layer: settings, contacts, batches, errors."""

from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pybullet as pb
import pytest
import trimesh

from pickplan.core.collision import CollisionChecker, CollisionSettings, SceneMesh, Table

N_SCENES = 4
N_PER_SCENE = 250  # 1,000 configurations in total
PB_RANGE = 0.05  # PyBullet closest points are requested within 5 cm
NEAR_TOUCH = 0.005  # disagreements must lie within 5 mm of contact


def _rot_z(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])


def make_scene(seed):
    """3-7 boxes and cylinders standing on the table (top at z = 0) in front of the robot."""
    rng = np.random.default_rng(seed)
    objects = []
    for i in range(int(rng.integers(3, 8))):
        if rng.random() < 0.5:
            ext = [rng.uniform(0.04, 0.12), rng.uniform(0.04, 0.12), rng.uniform(0.05, 0.22)]
            mesh, h = trimesh.creation.box(extents=ext), ext[2]
        else:
            r, h = rng.uniform(0.025, 0.05), rng.uniform(0.06, 0.22)
            mesh = trimesh.creation.cylinder(radius=r, height=h, sections=24)
        pose = np.eye(4)
        pose[:3, :3] = _rot_z(rng.uniform(-np.pi, np.pi))
        pose[:3, 3] = [rng.uniform(0.35, 0.75), rng.uniform(-0.35, 0.35), h / 2]
        objects.append(SceneMesh(f"obj{i}", mesh, pose))
    return objects, Table()


def _quat(R):
    w = np.sqrt(max(0.0, 1 + np.trace(R))) / 2
    return [(R[2, 1] - R[1, 2]) / (4 * w), (R[0, 2] - R[2, 0]) / (4 * w), (R[1, 0] - R[0, 1]) / (4 * w), w]


class BulletScene:
    """The same robot, objects (convex hulls of the same vertices) and table box in PyBullet."""

    def __init__(self, cid, robot, objects, table):
        self.cid, self.robot = cid, robot
        self.body = pb.loadURDF(robot.urdf_path, useFixedBase=True, physicsClientId=cid)
        self.joints = {pb.getBodyInfo(self.body, physicsClientId=cid)[0].decode(): -1}  # link name -> index
        self.movable = []
        for j in range(pb.getNumJoints(self.body, physicsClientId=cid)):
            info = pb.getJointInfo(self.body, j, physicsClientId=cid)
            self.joints[info[12].decode()] = j
            if info[2] != pb.JOINT_FIXED:
                self.movable.append((robot.joint_names.index(info[1].decode()), j))
        self.others = []
        for obj in objects:
            shape = pb.createCollisionShape(
                pb.GEOM_MESH, vertices=np.asarray(obj.mesh.vertices).tolist(), physicsClientId=cid
            )
            self.others.append(
                pb.createMultiBody(
                    0,
                    shape,
                    basePosition=obj.pose[:3, 3].tolist(),
                    baseOrientation=_quat(obj.pose[:3, :3]),
                    physicsClientId=cid,
                )
            )
        T = table.pose_matrix()
        shape = pb.createCollisionShape(
            pb.GEOM_BOX, halfExtents=(np.asarray(table.size) / 2).tolist(), physicsClientId=cid
        )
        self.others.append(
            pb.createMultiBody(
                0, shape, basePosition=T[:3, 3].tolist(), baseOrientation=_quat(T[:3, :3]), physicsClientId=cid
            )
        )

    def set_q(self, q):
        for qi, j in self.movable:
            pb.resetJointState(self.body, j, q[qi], physicsClientId=self.cid)

    def distance(self, q):
        """Smallest robot-to-scene contact distance (negative: penetration), capped at PB_RANGE."""
        self.set_q(q)
        best = PB_RANGE
        for other in self.others:
            for p in pb.getClosestPoints(self.body, other, PB_RANGE, physicsClientId=self.cid):
                best = min(best, p[8])
        return best


def sample_configurations(panda, n, seed):
    """Half uniform within the joint limits, half with the hand inside the clutter region
    (rejection sampling on FK), so that contacts with objects and table are frequent."""
    uniform = panda.random_configurations(n // 2, seed=seed)
    pool = panda.random_configurations(40 * n, seed=seed + 1)
    hand = panda.fk_batch(pool)[:, panda.link_index(panda.hand_link), :3, 3]
    inside = (
        (hand[:, 0] > 0.25)
        & (hand[:, 0] < 0.85)
        & (np.abs(hand[:, 1]) < 0.45)
        & (hand[:, 2] > -0.05)
        & (hand[:, 2] < 0.3)
    )
    reaching = pool[inside][: n - n // 2]
    assert len(reaching) == n - n // 2
    return np.concatenate([uniform, reaching])


@pytest.fixture(scope="module")
def scenes(panda):
    out = []
    for s in range(N_SCENES):
        objects, table = make_scene(100 + s)
        out.append((objects, table, sample_configurations(panda, N_PER_SCENE, seed=200 + 10 * s)))
    return out


def test_verdicts_agree_with_pybullet_on_1000_configurations(panda, bullet, scenes):
    fcl_hit, pb_hit, fcl_d, pb_d = [], [], [], []
    for objects, table, Q in scenes:
        checker = CollisionChecker(panda, objects, table, convex_links=True)
        assert checker.object_names == [o.name for o in objects]
        fcl_hit.append(checker.in_collision_batch(Q))
        fcl_d.append(checker.min_distance_batch(Q))
        pb.resetSimulation(physicsClientId=bullet)
        scene = BulletScene(bullet, panda, objects, table)
        d = np.array([scene.distance(q) for q in Q])
        pb_d.append(d)
        pb_hit.append(d < 0.0)
    fcl_hit, pb_hit = np.concatenate(fcl_hit), np.concatenate(pb_hit)
    fcl_d, pb_d = np.concatenate(fcl_d), np.concatenate(pb_d)
    n = len(fcl_hit)
    assert n == 1000
    # Both classes are well represented, so agreement is not trivial.
    assert 0.2 < pb_hit.mean() < 0.8, pb_hit.mean()
    np.testing.assert_array_equal(fcl_hit, fcl_d <= 0.0)
    disagree = np.flatnonzero(fcl_hit != pb_hit)
    agreement = 1.0 - len(disagree) / n
    print(
        f"\nFCL vs PyBullet: {n} configurations, {pb_hit.sum()} colliding (PyBullet), agreement "
        f"{100 * agreement:.1f} %, disagreements {len(disagree)}: FCL distance "
        f"{np.round(fcl_d[disagree] * 1000, 2).tolist()} mm, PyBullet {np.round(pb_d[disagree] * 1000, 2).tolist()} mm"
    )
    assert agreement >= 0.99
    # Every disagreement is a near-touching configuration in both checkers.
    assert np.all(np.abs(fcl_d[disagree]) < NEAR_TOUCH)
    assert np.all(np.abs(pb_d[disagree]) < NEAR_TOUCH)
    # Where both see the robot free and close, the distances themselves agree (Bullet adds
    # a collision margin of about a millimetre to convex hulls).
    close = (~fcl_hit) & (~pb_hit) & (fcl_d < PB_RANGE - 0.01)
    assert close.sum() > 20
    err = fcl_d[close] - pb_d[close]
    print(
        f"free and within 4 cm: {close.sum()} configurations, FCL - PyBullet distance: min "
        f"{1000 * err.min():.2f} mm, median {1000 * np.median(err):.2f} mm, max {1000 * err.max():.2f} mm"
    )
    assert np.all(err > -1e-4) and np.all(err < 0.0025)


def test_exact_link_meshes_differ_from_hulls_only_near_contact(panda, scenes):
    """The default (exact link meshes) is inside the hulls: it can only drop hull collisions."""
    objects, table, Q = scenes[0]
    exact = CollisionChecker(panda, objects, table)
    hull = CollisionChecker(panda, objects, table, convex_links=True)
    e, h = exact.in_collision_batch(Q), hull.in_collision_batch(Q)
    assert not np.any(e & ~h)
    assert (e == h).mean() >= 0.97


def test_batch_equals_single_and_threads(panda, scenes):
    objects, table, Q = scenes[1]
    checker = CollisionChecker(panda, objects, table, CollisionSettings(self_collision=True))
    Q = Q[:120]
    single = np.array([checker.in_collision(q) for q in Q])
    dist = np.array([checker.min_distance(q) for q in Q])
    np.testing.assert_array_equal(checker.in_collision_batch(Q), single)
    np.testing.assert_array_equal(checker.min_distance_batch(Q, threads=2), dist)
    np.testing.assert_array_equal(checker.in_collision_batch(Q, threads=0), single)
    # Python threads run native batches concurrently (the GIL is released) with the same answers.
    with ThreadPoolExecutor(2) as pool:
        halves = list(pool.map(checker.in_collision_batch, [Q[:60], Q[60:]]))
    np.testing.assert_array_equal(np.concatenate(halves), single)


def test_contacts_allowed_pairs_and_exclusions(panda, scenes):
    objects, table, Q = scenes[2]
    checker = CollisionChecker(panda, objects, table)
    # A configuration that touches exactly one scene object (not the table).
    for q in Q:
        cs = checker.contacts(q)
        others = {c.other for c in cs}
        if len(others) == 1 and "table" not in others:
            break
    else:
        pytest.fail("no configuration touching exactly one object")
    target = cs[0].other
    assert all(c.kind == "object" and c.distance <= 0 and c.link in panda.link_names for c in cs)
    assert checker.in_collision(q) and checker.min_distance(q) <= 0
    assert not CollisionChecker(panda, objects, table, CollisionSettings(excluded_objects=(target,))).in_collision(q)
    allowed = tuple((c.link, target) for c in cs)
    relaxed = CollisionChecker(panda, objects, table, CollisionSettings(allowed_pairs=allowed))
    assert not relaxed.in_collision(q)
    assert len(relaxed.checked_pairs) == len(checker.checked_pairs) - len(allowed)
    # Free configuration: no contacts; with `within`, the nearest pairs with positive distances.
    free = next(q for q in Q if not checker.in_collision(q))
    assert checker.contacts(free) == []
    near = checker.contacts(free, within=10.0)
    assert near and near[0].distance == pytest.approx(checker.min_distance(free))
    # A margin turns near misses into collisions.
    d = checker.min_distance(free)
    assert CollisionChecker(panda, objects, table, CollisionSettings(margin=d + 1e-3)).in_collision(free)
    assert not CollisionChecker(panda, objects, table, CollisionSettings(margin=max(0.0, d - 1e-3))).in_collision(free)


def test_self_collision_sanity_against_pybullet(panda, bullet):
    checker = CollisionChecker(panda, [], None, CollisionSettings(self_collision=True), convex_links=True)
    pairs = checker.checked_pairs
    links = set(panda.link_names)
    assert all(a in links and b in links for a, b in pairs)
    # Adjacent links (hand on link7 through the geometry-less link8, fingers on the hand) are skipped.
    names = {frozenset(p) for p in pairs}
    for adjacent in [("panda_link7", "panda_hand"), ("panda_hand", "panda_leftfinger"), ("panda_link3", "panda_link4")]:
        assert frozenset(adjacent) not in names
    assert frozenset(("panda_link1", "panda_hand")) in names
    assert not checker.in_collision(panda.ready_configuration)
    # PyBullet as the judge of the same link pairs.
    scene = BulletScene(bullet, panda, [], Table())
    idx = scene.joints

    def pb_self(q):
        scene.set_q(q)
        return any(
            pb.getClosestPoints(scene.body, scene.body, 0.0, idx[a], idx[b], physicsClientId=bullet) for a, b in pairs
        )

    Q = panda.random_configurations(300, seed=5)
    fcl = checker.in_collision_batch(Q)
    truth = np.array([pb_self(q) for q in Q])
    assert truth.sum() > 10
    dist = checker.min_distance_batch(Q)
    disagree = np.flatnonzero(fcl != truth)
    print(
        f"\nself-collision: {truth.sum()} / 300 colliding (PyBullet); disagreements {len(disagree)} at "
        f"FCL distances {np.round(dist[disagree] * 1000, 2).tolist()} mm"
    )
    assert (fcl == truth).mean() >= 0.98
    assert np.all(np.abs(dist[disagree]) < NEAR_TOUCH)
    # Contacts of a self-colliding configuration name checked link pairs only.
    q = Q[np.flatnonzero(fcl & truth)[0]]
    cs = checker.contacts(q)
    assert cs and all(c.kind == "link" and (c.link, c.other) in pairs for c in cs)


def test_bad_inputs_raise_clear_errors(panda, scenes):
    objects, table, _ = scenes[0]
    checker = CollisionChecker(panda, objects, table)
    with pytest.raises(ValueError, match="expected 9 joint values, got 7"):
        checker.in_collision(np.zeros(7))
    with pytest.raises(ValueError, match="configuration"):
        checker.min_distance(np.full(9, np.nan))
    with pytest.raises(ValueError, match=r"\(B, 9\)"):
        checker.in_collision_batch(np.zeros((4, 8)))
    Q = np.zeros((3, 9))
    Q[1, 2] = np.inf
    with pytest.raises(ValueError):
        checker.min_distance_batch(Q)
    with pytest.raises(ValueError, match="empty mesh"):
        CollisionChecker(panda, [SceneMesh("void", trimesh.Trimesh(), np.eye(4))], table)
    with pytest.raises(ValueError, match="expected a mesh"):
        CollisionChecker(panda, [SceneMesh("none", None, np.eye(4))], table)
    with pytest.raises(ValueError, match=r"\(4, 4\)"):
        CollisionChecker(panda, [SceneMesh("b", objects[0].mesh, np.eye(3))], table)
    with pytest.raises(ValueError, match="rigid"):
        CollisionChecker(panda, [SceneMesh("b", objects[0].mesh, np.diag([2.0, 1, 1, 1]))], table)
    with pytest.raises(ValueError, match="unknown object 'ghost'"):
        CollisionChecker(panda, objects, table, CollisionSettings(excluded_objects=("ghost",)))
    with pytest.raises(ValueError, match="ghost"):
        CollisionChecker(panda, objects, table, CollisionSettings(allowed_pairs=(("panda_hand", "ghost"),)))
    with pytest.raises(ValueError, match="given twice"):
        CollisionChecker(panda, [objects[0], objects[0]], table)
    with pytest.raises(ValueError, match="margin"):
        CollisionChecker(panda, objects, table, CollisionSettings(margin=-1.0))
    nan_mesh = trimesh.creation.box(extents=[0.1, 0.1, 0.1])
    nan_mesh.vertices[0, 0] = np.nan
    with pytest.raises(ValueError):
        CollisionChecker(panda, [SceneMesh("nan", nan_mesh, np.eye(4))], table)
