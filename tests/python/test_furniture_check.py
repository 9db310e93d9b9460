"""The success test among furniture (issue 35, ``omg.furniture_check``): the links' hulls measured against the
furniture exactly, checked against trimesh (the hulls' surfaces against the boxes in closed form) and
PyBullet's execution, on two generated cabinet picks the paper's padded body points judged wrongly."""

from dataclasses import replace

import numpy as np
import pytest
import trimesh

from pickplan import _core
from pickplan.core import objects
from pickplan.core.shapes import ShapeKind
from pickplan.eval.methods import method_spec
from pickplan.eval.units import _unit_grasps
from pickplan.omg.chomp import MetricSettings
from pickplan.omg.furniture_check import furniture_distances
from pickplan.omg.planner import OMGPlanner, PlanStatus
from pickplan.omg.world import World, WorldSettings
from pickplan.sim.execution import ExecutionSettings, execute_plan
from pickplan.sim.layouts import Layout, generate_layout

# Three cabinets of the bench's set (seed 0: its scenes 27, 4 and 79). In the first, the optimizer on the paper's
# 20 body points per link, run to the horizon, takes panda_link6 into the cabinet's top before the pre-grasp; in
# the second the 5 cm padding refused a plan that keeps clear of the cabinet and lifts the bleach bottle; in the
# third the loop, stopping early on the padded test only, ran to the horizon and returned a plan with a link
# 1.3 cm in the cabinet (session 21), though its 15th iterate passes the exact test.
LINK_IN_THE_TOP = 3920528224
PADDING_REFUSED = 2642120001
EARLY_STOP_EXACT = 620036939
PAPERS = WorldSettings(furniture_body_points_per_link=None)  # the paper's body points among furniture too


@pytest.fixture(scope="module")
def lib():
    return objects.library("builtin")


def _plan(lib, seed: int, world_settings: WorldSettings = WorldSettings(), **changes):
    """The bench's OMG unit's plan (antipodal grasps, its settings) of a generated cabinet."""
    scene = generate_layout(Layout.cabinet, seed=seed, library=lib)
    world = World(scene, world_settings)
    omg = method_spec("planners", "OMG").omg_settings(30, 100, 50, 0, world_settings)
    omg = replace(omg, **changes)
    grasps = _unit_grasps(world, scene, "antipodal", 100, "panda").poses
    return OMGPlanner(None, scene, omg, world=world).plan(grasps=grasps), world


def _box_distance(points: np.ndarray, size, pose: np.ndarray) -> np.ndarray:
    """Signed distance of world points to a solid box (full ``size``, centred at ``pose``), in closed form."""
    local = (points - pose[:3, 3]) @ pose[:3, :3]
    q = np.abs(local) - np.asarray(size) / 2
    outside = np.linalg.norm(np.maximum(q, 0.0), axis=1)
    return outside + np.minimum(q.max(axis=1), 0.0)


def _hull_distances(world, q: np.ndarray) -> dict:
    """{(link, other): least distance} of every link's convex hull (vertices and 3000 surface samples) to every
    box of the furniture (signed, closed form) and every object but the target (its mesh, trimesh; points
    farther from its bounding box than the least distance so far are not queried)."""
    robot, F = world.robot, world.robot.fk(q)
    others = [o for o in world.scene.objects if o.name != world.target]
    meshes = {o.name: world.models[o.name].mesh.copy().apply_transform(o.pose) for o in others}
    out = {}
    for link in robot.moving_links():
        mesh = robot.collision_meshes(link)
        if mesh is None:
            continue
        hull = mesh.convex_hull
        hull.apply_transform(F[link])
        points = np.vstack([hull.vertices, trimesh.sample.sample_surface(hull, 3000, seed=0)[0]])
        for o in world.scene.obstacles:
            assert o.shape.kind is ShapeKind.box
            out[(robot.link_names[link], o.name)] = float(_box_distance(points, o.shape.size, o.pose).min())
        for name, m in meshes.items():
            lo, hi = m.bounds
            near = points[
                np.linalg.norm(np.maximum(np.maximum(lo - points, points - hi), 0), axis=1) < min(out.values())
            ]
            if len(near):
                out[(robot.link_names[link], name)] = float(trimesh.proximity.closest_point(m, near)[1].min())
    return out


def test_the_exact_check_finds_a_link_in_the_cabinet_between_the_papers_body_points(lib):
    """Planned with the paper's 20 body points per link and run to the horizon, the optimizer takes panda_link6
    into the cabinet's top between them; the exact check refuses the plan, trimesh confirms it (hull surface
    points inside the box), and the check's distances agree with trimesh's where the hulls are clear."""
    result, world = _plan(lib, LINK_IN_THE_TOP, PAPERS, pre_terminate=False)
    assert result.status is PlanStatus.in_collision and result.history["furniture_distance"] < -0.01
    settings = MetricSettings()
    d = furniture_distances(world, result.trajectory, settings.steps)
    assert d.min() == result.history["furniture_distance"]
    dense = _core.interpolate(result.trajectory[0], result.trajectory[1:], settings.steps)
    worst = _hull_distances(world, dense[int(np.argmin(d))])
    # trimesh: hull points lie 5 mm or more inside a board (FCL's depth is the translation that frees the hull,
    # deeper than any point can lie in a board 2 cm thick)
    assert min(worst.values()) < -0.005, worst
    for t in (0, 60, 120):
        truth = min(_hull_distances(world, dense[t]).values())
        assert truth - 2e-3 <= d[t] <= truth + 1e-4, (t, d[t], truth)  # samples only overestimate


def test_a_cabinet_pick_the_padding_refused_passes_the_exact_check_and_is_lifted(lib):
    """The paper's padding refused this pick (the bench, session 20); the exact check passes the one planned now (the links' hulls a
    few cm from the cabinet at their closest, trimesh agreeing), and PyBullet lifts the target with it."""
    result, world = _plan(lib, PADDING_REFUSED)
    assert result.success, result.status
    d = furniture_distances(world, result.trajectory, 200)
    assert 0.0 < d.min() < 0.05  # clear, where the padding asks 5 cm of the body points
    dense = _core.interpolate(result.trajectory[0], result.trajectory[1:], 200)
    truth = min(_hull_distances(world, dense[int(np.argmin(d))]).values())
    assert truth - 2e-3 <= d.min() <= truth + 1e-4, (d.min(), truth)
    executed = execute_plan(world.scene, result.trajectory, ExecutionSettings(waypoint_dt=0.1))
    assert executed.status == "lifted", executed.message


def test_the_loop_stops_early_on_the_exact_test_and_the_pick_is_lifted(lib):
    """The bench's unit (session 21: in collision, the loop run to the horizon): the loop now stops on an iterate
    the exact test passes, its closest approach to the furniture confirmed by trimesh, and PyBullet lifts the
    target with it."""
    result, world = _plan(lib, EARLY_STOP_EXACT)
    assert result.success and result.iterations < 50, (result.status, result.iterations)
    d = furniture_distances(world, result.trajectory, 200)
    assert d.min() == result.history["furniture_distance"] > 0.0
    dense = _core.interpolate(result.trajectory[0], result.trajectory[1:], 200)
    truth = min(_hull_distances(world, dense[int(np.argmin(d))]).values())
    assert truth - 2e-3 <= d.min() <= truth + 1e-4, (d.min(), truth)
    executed = execute_plan(world.scene, result.trajectory, ExecutionSettings(waypoint_dt=0.1))
    assert executed.status == "lifted", executed.message
