"""Grasp quality (``omg.grasps.quality``): closed forms, the force split against an optimiser, and the
ranking of grasps on a heavy elongated tool."""

import numpy as np
import pytest
import trimesh
from scipy.optimize import linprog

from pickplan.core import objects
from pickplan.core.panda import PANDA
from pickplan.omg.grasps import quality as q

GRIP = q.Grip(force=40.0, friction=0.5, opening=0.08, pad_length=0.018, pad_width=0.02)
AT_REST = q.QualitySettings(acceleration=0.0)


def _frame(centre, closing, approach):
    y, z = np.asarray(closing, float), np.asarray(approach, float)
    T = np.eye(4)
    T[:3, :3] = np.column_stack([np.cross(y, z), y, z])
    T[:3, 3] = centre
    return T


def _box_points(extents, n=60000):
    mesh = trimesh.creation.box(extents=extents)
    return mesh, np.asarray(trimesh.sample.sample_surface(mesh, n, seed=1)[0])


def _rectangle_mean_radius(a, b, k=400):
    """Mean distance from the centre of a uniform a x b rectangle (dense midpoint grid)."""
    x, z = np.meshgrid((np.arange(k) + 0.5) / k * a - a / 2, (np.arange(k) + 0.5) / k * b - b / 2)
    return float(np.hypot(x, z).mean())


def test_a_box_held_at_its_centre_needs_friction_for_its_weight_and_the_carry():
    """Pads on two faces, the centre of mass between them: only the tangential load, m (g + a), shared
    by two pads: utilisation m (g + a) / (2 mu N)."""
    _, P = _box_points((0.04, 0.06, 0.10))
    m = 1.5
    load = q.Load(m, np.zeros(3), np.array([0.0, 0.0, -1.0]))
    G = _frame([0, 0, 0.02], [1, 0, 0], [0, 0, -1])  # from above, closing across the 4 cm
    s = q.QualitySettings(acceleration=2.5)
    out = q.grasp_quality(P, G[None], load, GRIP, s)
    expected = m * (9.81 + 2.5) / (2 * GRIP.friction * GRIP.force)
    assert out.margin[0] == pytest.approx(1 - expected, abs=5e-4)  # patch centres from samples
    assert out.patches.gap[0] == pytest.approx(0.04, abs=1e-6)
    assert out.fit[0] is q.GraspFit.holds
    heavy = q.grasp_quality(P, G[None], q.Load(4 * m, np.zeros(3), load.down), GRIP, s)
    assert heavy.fit[0] is q.GraspFit.slips and heavy.margin[0] == pytest.approx(1 - 4 * expected, abs=2e-3)


def test_an_off_centre_pinch_must_hold_the_weights_torque_by_torsional_friction():
    """The pads d away from the centre of mass along the box: gravity's torque d m g about the closing
    axis, held by mu N rho at each flat patch (rho: the mean radius of the pad's rectangle)."""
    _, P = _box_points((0.20, 0.04, 0.05))
    m, d = 0.3, 0.05
    load = q.Load(m, np.zeros(3), np.array([0.0, 0.0, -1.0]))
    G = _frame([d, 0, 0.0], [0, 1, 0], [0, 0, -1])
    out = q.grasp_quality(P, G[None], load, GRIP, AT_REST)
    rho = _rectangle_mean_radius(GRIP.pad_width, GRIP.pad_length)
    assert out.patches.radius[0] == pytest.approx([rho, rho], rel=0.03)
    mu_n = GRIP.friction * GRIP.force
    expected = np.hypot(m * 9.81 / (2 * mu_n), d * m * 9.81 / (2 * mu_n * rho))
    assert 1 - out.margin[0] == pytest.approx(expected, rel=0.03)
    central = q.grasp_quality(P, _frame([0, 0, 0], [0, 1, 0], [0, 0, -1])[None], load, GRIP, AT_REST)
    assert central.margin[0] > out.margin[0]


def test_a_pad_that_meets_nothing_misses():
    _, P = _box_points((0.04, 0.06, 0.10))
    load = q.Load(0.1, np.zeros(3), np.array([0.0, 0.0, -1.0]))
    beside = _frame([0.2, 0, 0], [1, 0, 0], [0, 0, -1])  # nowhere near the box
    too_wide = _frame([0, 0, 0], [0, 1, 0], [0, 0, -1])  # 6 cm across: inside the 8 cm opening, fine
    out = q.grasp_quality(P, np.stack([beside, too_wide]), load, GRIP, AT_REST)
    assert out.fit == [q.GraspFit.misses, q.GraspFit.holds]
    assert out.margin[0] == -np.inf


def _sphere(k=300):
    """k unit vectors spread over the sphere (a Fibonacci lattice)."""
    i = np.arange(k) + 0.5
    z = 1 - 2 * i / k
    a = np.pi * (1 + 5**0.5) * i
    return np.column_stack([np.sqrt(1 - z**2) * np.cos(a), np.sqrt(1 - z**2) * np.sin(a), z])


def _optimal_utilisation(patches, frame, load, grip, settings):
    """The least worst-pad utilisation over every force distribution the contact model allows, by linear
    programming, each pad's limit ellipsoid (|t| / mu N, m / mu N rho) replaced by the polytope of its
    tangent planes at ``_sphere`` points (which contains it): never above the true optimum."""
    best = 0.0
    R, origin = frame[:3, :3], frame[:3, 3]
    c = patches.centre[0]
    o = 0.5 * (c[0] + c[1])
    com = R.T @ (load.com - origin) - o
    rho = np.maximum(patches.radius[0], settings.min_radius)
    h = patches.half[0]
    p = c - o
    for F in load.forces(settings) @ R:
        T = np.cross(com, F)
        N = (grip.force - 0.5 * F[1], grip.force + 0.5 * F[1])
        # variables: t+ (x, z), t- (x, z), m+, m-, N+ cop+ (x, z), N- cop- (x, z), u
        A_eq = [
            [1, 0, 1, 0, 0, 0, 0, 0, 0, 0, 0],
            [0, 1, 0, 1, 0, 0, 0, 0, 0, 0, 0],
            [0, 0, 0, 0, 1, 1, 0, 0, 0, 0, 0],
            [0, p[0, 1], 0, p[1, 1], 0, 0, 0, 1, 0, -1, 0],  # torque about x
            [-p[0, 1], 0, -p[1, 1], 0, 0, 0, -1, 0, 1, 0, 0],
        ]  # torque about z
        b_eq = [F[0], F[2], T[1], T[0], T[2]]  # the object settled in the grip: no squeeze couple left
        A_ub = []
        for i, (Ni, r) in enumerate(zip(N, rho)):
            for d in _sphere():
                row = [0.0] * 11
                row[2 * i], row[2 * i + 1] = d[0] / (grip.friction * Ni), d[1] / (grip.friction * Ni)
                row[4 + i], row[10] = d[2] / (grip.friction * Ni * r), -1.0
                A_ub.append(row)
        bounds = [(None, None)] * 6 + [
            (-N[0] * h[0, 0], N[0] * h[0, 0]),
            (-N[0] * h[0, 1], N[0] * h[0, 1]),
            (-N[1] * h[1, 0], N[1] * h[1, 0]),
            (-N[1] * h[1, 1], N[1] * h[1, 1]),
            (0, None),
        ]
        res = linprog([0] * 10 + [1], A_ub=A_ub, b_ub=np.zeros(len(A_ub)), A_eq=A_eq, b_eq=b_eq, bounds=bounds)
        assert res.status == 0
        best = max(best, res.fun)
    return best


def test_the_force_split_is_feasible_so_never_better_than_the_optimum():
    """The quality's closed-form split is one feasible distribution: its utilisation is at least the
    optimum over all distributions (bounded from below by the linear programme), on random boxes,
    loads and grasp frames."""
    judged = 0
    for seed in range(8):
        rng = np.random.default_rng(seed)
        _, P = _box_points(rng.uniform(0.03, 0.07, 3) * [3, 1, 1])
        load = q.Load(rng.uniform(0.1, 1.0), rng.uniform(-0.02, 0.02, 3), np.array([0.0, 0.0, -1.0]))
        z = rng.normal(size=3)
        z = np.array([z[0], z[1], -abs(z[2]) - 0.5])
        z /= np.linalg.norm(z)
        y = np.cross(z, [0.0, 1.0, 0.0] if seed % 2 else [1.0, 0.0, 0.0])
        y /= np.linalg.norm(y)
        G = _frame(rng.uniform(-0.02, 0.02, 3), y, z)
        s = q.QualitySettings(acceleration=2.0)
        out = q.grasp_quality(P, G[None], load, GRIP, s)
        if out.fit[0] is q.GraspFit.misses:
            continue  # this frame closes on nothing: nothing to split
        judged += 1
        ours, best = 1 - out.margin[0], _optimal_utilisation(out.patches, G, load, GRIP, s)
        assert best - 1e-9 <= ours <= 3 * best, seed  # feasible, and not far from the best
    assert judged >= 6


def test_a_pinch_far_from_a_heavy_clamps_centre_of_mass_ranks_below_a_central_one():
    """A heavy clamp-like tool (procedural clamp family, 1.5 kg) lying flat: a pinch across its spine
    beside the centre of mass against one across the far end of a jaw; the far one ranks lower and slips."""
    lib = objects.library("procedural")
    base = lib.get("clamp_01")
    model = objects.make_object(
        "heavy_clamp", base.mesh, base.collision_parts, "test", mass=1.5, friction=base.friction
    )
    pose = model.resting_poses[0]
    down = pose[:3, :3].T @ [0.0, 0.0, -1.0]
    (x0, y0, _), (x1, _, _) = model.mesh.bounds
    z = model.com[2]
    # the spine runs along y at the lowest x, the jaws along +x from its ends (the screw in the +y one):
    # across the spine just beside the centre of mass, and across the -y jaw at its far end
    central = _frame([x0 + 0.008, model.com[1] - 0.015, z], [1.0, 0.0, 0.0], down)
    far = _frame([x1 - 0.01, y0 + 0.008, z], [0.0, 1.0, 0.0], down)
    out = q.model_quality(model, np.stack([central, far]) @ PANDA.hand_from_grasp, pose, PANDA)
    assert out.fit == [q.GraspFit.holds, q.GraspFit.slips]
    assert out.margin[0] > out.margin[1] and list(out.order()) == [0, 1]


def test_a_worlds_grasp_verdicts_are_its_quality_kept_per_grasp():
    """``World.grasp_verdicts`` (what the goal set ranks by) equals ``World.grasp_quality`` grasp for
    grasp; a grasp seen before is not computed again (also in another order, or with the target moved
    without turning), and a target that turned (gravity another way in its frame) is judged anew."""
    from pickplan.omg.world import World
    from pickplan.sim import scenes

    world = World(scenes.generate_scene(3))
    com = np.asarray(world.target_model.com, float)
    info = world.robot.info
    frames = []
    for yaw in np.linspace(0.0, np.pi, 12, endpoint=False):
        down = _frame(com + [0.0, 0.0, 0.01 * np.sin(3 * yaw)], [np.cos(yaw), np.sin(yaw), 0.0], [0.0, 0.0, -1.0])
        frames.append(down @ np.linalg.inv(info.grasp_frame))  # hand poses, object frame
    hands = np.array(frames)
    settings = q.QualitySettings()

    def check(rows):
        truth = world.grasp_quality(hands[rows], settings)
        margin, fit = world.grasp_verdicts(hands[rows], settings)
        np.testing.assert_array_equal(margin, truth.margin)
        assert fit == truth.fit

    verdicts = world.cache.grasp_verdicts
    check(np.arange(12))
    assert (verdicts.hits, verdicts.misses) == (0, 12)
    assert {f.value for f in world.grasp_verdicts(hands, settings)[1]} >= {"holds"}
    check(np.arange(12)[::-3])
    assert verdicts.misses == 12
    T = world.target_pose.copy()
    T[:3, 3] += [0.02, -0.01, 0.0]
    world.move_object(world.scene.target, T)
    check(np.arange(12))
    assert verdicts.misses == 12  # moved, not turned: the same verdicts
    c, s = np.cos(0.3), np.sin(0.3)
    T[:3, :3] = np.array([[1.0, 0, 0], [0, c, -s], [0, s, c]]) @ T[:3, :3]
    world.move_object(world.scene.target, T)
    check(np.arange(12))
    assert verdicts.misses == 24  # turned: judged again


def test_quality_settings_refuse_what_they_cannot_mean():
    with pytest.raises(ValueError, match="point_density: expected a positive value"):
        q.QualitySettings(point_density=0.0)
    with pytest.raises(ValueError, match="point_density_light must not exceed point_density"):
        q.QualitySettings(point_density=100.0, point_density_light=200.0)
    with pytest.raises(ValueError, match="acceleration >= 0"):
        q.QualitySettings(acceleration=-1.0)
