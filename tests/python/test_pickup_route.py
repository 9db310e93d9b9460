"""Car-like route seeds of pick-up on the move (issue 37): Dubins geometry, routes that are continuous,
car-like and clear (via poses round obstacles where two legs cannot clear), and their seeds' speed and
yaw-rate limits."""

import math
from dataclasses import replace

import numpy as np
import pytest

from pickplan import _core
from pickplan.pickup.nlp import planner, problem_file, random_problems, route
from pickplan.pickup.nlp.feasibility import base_geometry
from routed_fixtures import FAST, _native, _part_on_pillar, _spec


@pytest.fixture(scope="module")
def robot():
    return planner.mobile_ur5()


# ---- Dubins and the routes ------------------------------------------------------------------------
def _end(q0, word, seg, rho):
    return route.sample_dubins(q0, word, seg, rho)[-1]


@pytest.mark.parametrize(
    "q1", [(5.0, 0.0, 0.0), (0.0, 2.0, math.pi), (-3.0, 1.0, 2.0), (1.0, -4.0, -1.0), (0.3, 0.2, 3.0)]
)
def test_every_dubins_word_ends_at_the_goal_pose_and_the_shortest_is_known_in_closed_form(q1):
    rho, q0 = 1.0, (0.0, 0.0, 0.0)
    words = route.dubins_words(q0, q1, rho)
    assert words
    for word, seg in words:
        e = _end(q0, word, seg, rho)
        assert np.allclose(e[:2], q1[:2], atol=1e-9) and abs(math.remainder(e[2] - q1[2], 2 * math.pi)) < 1e-9, word
    length = route.dubins_shortest(q0, q1, rho)[2]
    if q1 == (5.0, 0.0, 0.0):
        assert length == pytest.approx(5.0)  # straight ahead
    if q1 == (0.0, 2.0, math.pi):
        assert length == pytest.approx(math.pi)  # a half circle of radius 1
    assert length >= math.hypot(q1[0], q1[1]) - 1e-12  # never shorter than the straight line


def _assert_car_like_and_clear(P, geo, rho, start=None, end=None):
    """Poses P (n, 3) from ``start`` to ``end`` (the problem's start and goal by default): continuous,
    curvature at most 1 / rho, no lateral motion, clear of the obstacles by 5 cm."""
    start, end = geo.start if start is None else np.asarray(start), geo.goal if end is None else np.asarray(end)
    step = np.linalg.norm(np.diff(P[:, :2], axis=0), axis=1)
    assert step.max() <= route.STEP + 1e-9  # continuous
    assert np.allclose(P[0], start) and np.allclose(P[-1, :2], end[:2], atol=1e-9)
    assert abs(math.remainder(P[-1, 2] - end[2], 2 * math.pi)) < 1e-9
    turn = np.abs(np.diff(P[:, 2]))
    assert np.all(2 * rho * np.sin(turn / 2) <= step + 1e-9)  # curvature <= 1 / rho (chords)
    motion = np.arctan2(np.diff(P[:, 1]), np.diff(P[:, 0]))  # no lateral motion
    lateral = np.abs(np.sin(motion - P[1:, 2]))[step > 1e-6]
    assert lateral.max() < 0.05
    assert geo.free(P[:, :2], 0.05).all()


def test_a_leg_an_obstacle_blocks_goes_round_it_through_a_via_pose(robot):
    pillar = problem_file.SphereObstacle((2.0, 0.0, 0.4), 0.4)
    problem = _native(robot, _spec(obstacles=_spec().obstacles + (pillar,)))
    geo = base_geometry(robot, problem, FAST)
    rho, margin = geo.v_max / geo.w_max, 0.05
    a, b = (0.0, 0.0, 0.0), (4.0, 0.0, 0.0)  # straight through the pillar
    vias = route.via_poses(geo, margin, rho)
    assert vias and geo.free(np.array(vias)[:, :2], margin).all()
    for sign in (1, -1):  # forwards, and backwards the other way
        a, b = (a, b) if sign > 0 else (b, a)
        assert not geo.free(route._leg(a, b, rho, sign).poses(rho)[:, :2], margin).all()
        legs = route.clear_leg(geo, a, b, rho, sign, vias, margin)
        assert len(legs) == 2 and all(leg.sign == sign for leg in legs)
        P = np.concatenate([legs[0].poses(rho), legs[1].poses(rho)[1:]])
        P[:, 2] = a[2] + np.unwrap(P[:, 2] - a[2])
        _assert_car_like_and_clear(P, geo, rho, start=a, end=b)
        assert sum(leg.length for leg in legs) >= 4.0  # no shorter than the straight line
    assert route.clear_leg(geo, a, b, rho, 1, [], margin) is None  # no via pose: no clear leg
    assert len(route.clear_leg(geo, (0.0, 0.0, 0.0), (1.0, -1.0, -0.5), rho, 1, vias, margin)) == 1  # clear as it is


def test_clutter_that_blocks_every_two_leg_route_of_a_class_gets_a_route_through_via_poses(robot):
    ws = random_problems.Workspace(layout=random_problems.Layout.cluttered, metamodel="standin")
    via = 0
    for spec in random_problems.random_problems(24, 1, ws):
        geo = base_geometry(robot, _native(robot, spec), FAST)
        rho = geo.v_max / geo.w_max
        routes = route.candidate_routes(geo, count=4)
        assert len({r.label.split()[0] for r in routes}) == len(routes)  # one per class (side, sense)
        for r in routes:
            _assert_car_like_and_clear(r.poses, geo, rho)
            assert geo.r_min <= np.linalg.norm(r.poses[r.grasp_index, :2] - geo.part_xy) <= geo.r_max
            via += r.label.endswith(" via")
    assert via > 0  # pillars between the start, the part and the goal block some class in some problem


def test_routes_are_continuous_car_like_and_clear_and_their_seeds_keep_the_limits(robot):
    spec = _spec(
        base_start=(0.0, 0.0, math.pi / 2),
        part_position=(4.0, 3.5, 0.5),
        obstacles=_spec().obstacles[:0]
        + (problem_file.SphereObstacle((4.0, 3.5, 0.15), 0.15), problem_file.SphereObstacle((2.0, 1.5, 0.3), 0.3)),
    )
    problem = _native(robot, spec)
    geo = base_geometry(robot, problem, FAST)
    routes = route.candidate_routes(geo, count=4)
    assert len(routes) >= 2 and len({r.label for r in routes}) == len(routes)
    rho = geo.v_max / geo.w_max
    template = np.array(_core.pickup_heuristic_seed(robot.native, problem, FAST.to_native()))
    for r in routes:
        _assert_car_like_and_clear(r.poses, geo, rho)
        g = r.poses[r.grasp_index, :2]
        assert geo.r_min <= np.linalg.norm(g - geo.part_xy) <= geo.r_max
        x = route.route_seed(r, geo, template, FAST, robot.dof, problem.stroke)
        nc = len(x) - 5
        T, s1, s2 = x[nc + 2], x[nc], x[nc + 1]
        assert 0 <= s1 < s2 <= 1 and (s2 - s1) * T == pytest.approx(problem.stroke / x[nc + 4])
        coeff = [x[o : o + 6] for o in (0, 6, 12)]
        u = np.linspace(0, 1, 2001)
        v = [np.polynomial.polynomial.polyval(u, np.polynomial.polynomial.polyder(c)) / T for c in coeff]
        assert np.hypot(v[0], v[1]).max() <= geo.v_max * (1 + 1e-9)  # the speed limit
        assert np.abs(v[2]).max() <= geo.w_max * (1 + 1e-9)  # the yaw-rate limit
        assert np.allclose([c[0] for c in coeff], geo.start)


def test_a_route_seed_comes_to_rest_at_a_cusp_and_heads_along_its_path(robot):
    """Part behind the start: each route drives back to the grasp pose and forwards to the goal. The
    seed's time law stops at the cusp at a constant deceleration over the shorter leg (closed form:
    that leg takes twice its length at the cruise speed), and its fitted base path slides sideways
    little on average (a constant-speed fit rounds the cusp sideways: 0.39-0.47 of the speed)."""
    spec = _part_on_pillar((-3.0, 1.0, 0.5))
    problem = _native(robot, spec)
    settings = replace(FAST, degrees=[7, 7, 7, 5, 5, 5, 3, 3, 3])
    geo = base_geometry(robot, problem, settings)
    template = np.array(_core.pickup_heuristic_seed(robot.native, problem, settings.to_native()))
    routes = route.candidate_routes(geo, count=4)
    assert routes
    P = np.polynomial.polynomial
    for r in routes:
        (cusp,) = np.flatnonzero(np.diff(r.direction) != 0)  # one reversal, at the grasp pose
        first, second = r.s[cusp], r.length - r.s[cusp]
        short, long_ = min(first, second), max(first, second)
        t = route.route_times(r)
        assert t[0] == 0 and t[-1] == pytest.approx(1) and np.all(np.diff(t) > 0)
        # at cruise speed 1: the shorter leg 2 * short, the longer 2 * short (its ramp) + long - short
        expected = (2 * first if first <= second else 2 * short + long_ - short) / (3 * short + long_)
        assert t[cusp] == pytest.approx(expected, rel=0.03)
        speed = np.diff(r.s) / np.diff(t)
        assert speed[cusp - 1 : cusp + 1].max() < 0.25 * speed.max()  # (nearly) at rest round the cusp
        x = route.route_seed(r, geo, template, settings, robot.dof, problem.stroke)
        c = [x[o : o + 8] for o in (0, 8, 16)]
        u = np.linspace(0, 1, 2001)
        dx, dy = (P.polyval(u, P.polyder(cc)) for cc in c[:2])
        heading = P.polyval(u, c[2])
        lateral = np.abs(dx * np.sin(heading) - dy * np.cos(heading))
        assert lateral.mean() < 0.2 * np.hypot(dx, dy).mean()


def test_a_route_without_a_cusp_is_timed_at_constant_speed(robot):
    problem = _native(robot, _spec())
    geo = base_geometry(robot, problem, FAST)
    forwards = [r for r in route.candidate_routes(geo, count=4) if np.all(r.direction == 1)]
    assert forwards  # the part beside the straight line: some route drives forwards throughout
    for r in forwards:
        assert np.allclose(route.route_times(r), r.s / r.length)


# ---- reversing base paths -----------------------------------------------------------------------------
def _base(x, y, theta, arm=(0.0,) * 4):
    """NLP variables with base polynomials x, y, theta (monomial coefficients in s, low first) and a
    dummy arm / timing tail (``reverses`` reads only the base)."""
    return np.concatenate([x, y, theta, arm]), [len(x) - 1, len(y) - 1, len(theta) - 1]


@pytest.mark.parametrize(
    "x, y, theta, backwards",
    [
        ([0, 4], [0], [0], False),  # straight ahead
        ([0, -4], [0], [0], True),  # straight back, heading 0
        ([0, -4], [0], [math.pi], False),  # the same motion, heading pi: forwards
        ([0, 2, -2], [0], [0], True),  # x' = 2 - 4 s: forwards, then back at the same peak speed
        ([0, 0, 0, 1], [0], [0], False),  # x' = 3 s^2: starts at rest, never back
        ([0, 1, -0.52], [0], [0], False),  # x' = 1 - 1.04 s: back at 4 % of its peak, below the share
        ([0, 1, -0.6], [0], [0], True),  # x' = 1 - 1.2 s: back at 20 % of its peak
        ([0, 0, 0], [0, 3], [math.pi / 2], False),  # along y facing +y
        ([0, 3], [0, 3], [-3 * math.pi / 4], True),  # along the diagonal facing its opposite
        ([0], [0], [0, 1], False),  # turning on the spot: no speed along the heading
    ],
)
def test_a_base_path_reverses_where_its_speed_along_its_heading_falls_below_a_share_of_its_peak(x, y, theta, backwards):
    xs, degrees = _base(np.array(x, float), np.array(y, float), np.array(theta, float))
    assert route.reverses(xs, degrees) is backwards
