"""Timed trajectories: samples within the limits, on the planned path, rest to rest, the closed-form
time-optimal duration of a straight line, export round trips, and execution of a timed plan."""

import json
import math

import numpy as np
import pytest

from pickplan.core.description import robot_info
from pickplan.core.panda import PANDA
from pickplan.core.timing import (
    Interpolation,
    KinematicLimits,
    TimedTrajectory,
    concatenate,
    joint_move,
    panda_limits,
    time_parameterize,
)

RATE = 1000.0


@pytest.fixture(scope="module")
def demo_plan():
    """The demo's scene (seed 1) planned by OMG with antipodal grasps, as ``make demo`` does."""
    from pickplan.omg.planner import OMGPlanner, OMGSettings
    from pickplan.sim import scenes

    scene = scenes.generate_scene(1)
    result = OMGPlanner(None, scene, OMGSettings(grasp_kind="antipodal")).plan()
    assert result.success
    return scene, result


def random_paths(count=3, waypoints=12, seed=0):
    """Seeded smooth-ish paths inside the Panda's joint range (random walks, fingers fixed open)."""
    rng = np.random.default_rng(seed)
    ready = np.array(PANDA.ready)
    for _ in range(count):
        steps = rng.normal(0.0, 0.15, size=(waypoints - 1, 9))
        steps[:, 7:] = 0.0
        yield ready + np.vstack([np.zeros(9), np.cumsum(steps, axis=0)])


def check_within_limits(timed, limits):
    assert np.all(np.abs(timed.qd) <= limits.velocity * (1 + 1e-9))
    assert np.all(np.abs(timed.qdd) <= limits.acceleration * (1 + 1e-9))
    # Independent of the reported qdd: the velocity samples change no faster than the limits allow.
    dt = np.diff(timed.t)[:, None]
    assert np.all(np.abs(np.diff(timed.qd, axis=0)) <= limits.acceleration * dt * (1 + 1e-6) + 1e-12)
    # qd is the derivative of q: trapezoid rule, exact to a * dt^2 / 4 for |qdd| <= a.
    trapezoid = dt * (timed.qd[1:] + timed.qd[:-1]) / 2
    assert np.all(np.abs(np.diff(timed.q, axis=0) - trapezoid) <= limits.acceleration * dt**2 / 4 + 1e-9)


def distance_to_polyline(points, Q):
    A, d = Q[:-1], np.diff(Q, axis=0)
    L2 = np.maximum((d * d).sum(1), 1e-300)
    out = []
    for p in points:
        u = np.clip(((p - A) * d).sum(1) / L2, 0.0, 1.0)
        out.append(np.min(np.linalg.norm(A + u[:, None] * d - p, axis=1)))
    return np.array(out)


def in_some_segment_box(points, Q, tol=1e-9):
    lo = np.minimum(Q[:-1], Q[1:]) - tol
    hi = np.maximum(Q[:-1], Q[1:]) + tol
    return np.array([np.any(np.all((p >= lo) & (p <= hi), axis=1)) for p in points])


def test_panda_limits_from_urdf_and_datasheet(panda):
    limits = panda_limits(panda)
    assert np.allclose(limits.velocity[:7], [2.175] * 4 + [2.61] * 3)  # the URDF agrees with the datasheet
    assert np.allclose(limits.acceleration[:7], [15, 7.5, 10, 12.5, 15, 20, 20])
    assert len(limits.velocity) == len(limits.acceleration) == panda.dof


@pytest.mark.parametrize("interpolation", list(Interpolation))
def test_planned_trajectory_timed_within_limits_from_rest_to_rest(demo_plan, interpolation):
    _, result = demo_plan
    timed = result.timed(rate=RATE, interpolation=interpolation)
    limits = panda_limits()
    check_within_limits(timed, limits)
    assert np.allclose(np.diff(timed.t), 1.0 / RATE, rtol=0, atol=1e-12)  # exactly the chosen rate
    assert np.all(timed.qd[0] == 0) and np.all(timed.qd[-1] == 0)
    assert np.allclose(timed.q[0], result.trajectory[0]) and np.allclose(timed.q[-1], result.trajectory[-1])
    # TOPP-RA is (close to) time-optimal: some sample is at a velocity or acceleration limit.
    worst = max(np.max(np.abs(timed.qd) / limits.velocity), np.max(np.abs(timed.qdd) / limits.acceleration))
    assert worst > 0.95
    # Faster than the planner's nominal 0.1 s per waypoint, as the limits allow.
    assert 0.3 < timed.duration < 0.1 * (len(result.trajectory) - 1)


def test_planned_path_is_unchanged(demo_plan):
    _, result = demo_plan
    Q = result.trajectory
    timed = result.timed(rate=RATE)
    # PCHIP moves each joint monotonically between waypoints: every sample is in a segment's box ...
    assert np.all(in_some_segment_box(timed.q, Q))
    # ... close to the piecewise-linear path (corners are rounded by a few mrad at most) ...
    assert distance_to_polyline(timed.q, Q).max() < 0.02
    # ... and the waypoints are passed in their order, each within one sample step.
    step = np.linalg.norm(np.diff(timed.q, axis=0), axis=1).max()
    nearest = [int(np.argmin(np.linalg.norm(timed.q - w, axis=1))) for w in Q]
    assert all(np.linalg.norm(timed.q[i] - w) <= step for i, w in zip(nearest, Q))
    assert nearest == sorted(nearest)


@pytest.mark.parametrize("seed", [0, 1])
def test_random_paths_within_limits(seed):
    limits = panda_limits()
    for Q in random_paths(seed=seed):
        timed = time_parameterize(Q, 500.0, limits)
        check_within_limits(timed, limits)
        assert np.all(in_some_segment_box(timed.q, Q))
        assert np.all(timed.qd[0] == 0) and np.all(timed.qd[-1] == 0)


@pytest.mark.parametrize(
    "delta, v, a",
    [
        ((0.8, -0.3, 0.1), (2.0, 1.0, 1.0), (10.0, 4.0, 5.0)),  # reaches full speed: accelerate, coast, brake
        ((0.05, 0.02, 0.0), (2.0, 2.0, 2.0), (5.0, 5.0, 5.0)),  # too short to reach it: bang-bang
    ],
)
def test_straight_line_matches_closed_form_time_optimum(delta, v, a):
    """On a straight joint-space line q = q0 + s * delta the joints move together: the path speed is
    limited by V = min v_j / |delta_j|, A = min a_j / |delta_j|, and the fastest rest-to-rest motion
    over s in [0, 1] takes 1 / V + V / A if it reaches V (1 >= V^2 / A), else 2 sqrt(1 / A)."""
    delta, v, a = (np.array(x, dtype=float) for x in (delta, v, a))
    moving = np.abs(delta) > 0
    V = np.min(v[moving] / np.abs(delta[moving]))
    A = np.min(a[moving] / np.abs(delta[moving]))
    optimum = 1.0 / V + V / A if 1.0 >= V**2 / A else 2.0 * math.sqrt(1.0 / A)
    Q = np.array([np.zeros(3), delta])
    timed = time_parameterize(Q, RATE, KinematicLimits(v, a), grid_per_segment=200)
    assert timed.duration == pytest.approx(optimum, rel=0.02, abs=2.0 / RATE)
    assert timed.duration >= optimum - 1.0 / RATE  # nothing beats the time optimum
    assert distance_to_polyline(timed.q, Q).max() < 1e-12  # two waypoints: the path is the line


# A pick-and-place retract (0.1 m straight up in 10 IK steps, fingers open) that TOPP-RA could not time
# when grid points a hair (1e-6) either side of each waypoint made stages too short for its LP solver.
RETRACT = np.array(
    [
        [
            0.5890942746674019,
            0.9876503998544617,
            0.09051522976214928,
            -0.982238691889985,
            0.2507158176705692,
            1.9789558478185054,
            2.3709067273343134,
        ],
        [
            0.588865001425803,
            0.9764157390612018,
            0.09025992639485987,
            -0.9768341560836314,
            0.24981553257671393,
            1.9628999630758577,
            2.37552224014008,
        ],
        [
            0.5886708991118623,
            0.96616642612521,
            0.09002503621522362,
            -0.9696870508378043,
            0.24885326354895626,
            1.9461043284446375,
            2.380295345043367,
        ],
        [
            0.5885095062200899,
            0.9568832665678054,
            0.08981504411427656,
            -0.9608417756165711,
            0.2478380066914131,
            1.9285948757377125,
            2.3852182264951143,
        ],
        [
            0.5883827466173777,
            0.9486143516327235,
            0.08963315221578082,
            -0.95022038001297,
            0.24677124403122638,
            1.9103427228792844,
            2.3902969405192183,
        ],
        [
            0.5882936232064306,
            0.9414225902422599,
            0.0894828448077359,
            -0.9377176437095162,
            0.24565338155647157,
            1.8913068339402626,
            2.395540512780865,
        ],
        [
            0.5882463120340969,
            0.9353872678151195,
            0.08936809319933671,
            -0.9231981851055375,
            0.24448374745022997,
            1.8714327652165708,
            2.400961184705157,
        ],
        [
            0.5882464558145304,
            0.9306088259580623,
            0.0892935941043994,
            -0.9064877136876699,
            0.24326028633778,
            1.8506488123754483,
            2.4065752847229045,
        ],
        [
            0.588301597599575,
            0.9272159184795159,
            0.0892651302080628,
            -0.887360127894711,
            0.24197909546441454,
            1.8288603342655434,
            2.4124045121577993,
        ],
        [
            0.5884713275345351,
            0.9262472691824152,
            0.0892866107521653,
            -0.8639354105527101,
            0.24054849608201662,
            1.805233880553722,
            2.4186468693747756,
        ],
        [
            0.5886897225484005,
            0.9265270909116519,
            0.08937733315790929,
            -0.8383545289978803,
            0.23909901264146588,
            1.7807343687313484,
            2.425068449677068,
        ],
    ]
)


@pytest.mark.parametrize("grid_per_segment", [8, 16, 17])
def test_straight_retract_with_near_flat_joints_is_timed_within_limits(grid_per_segment):
    """Joint 0 turns round between waypoints 6 and 7 (a step of 1.4e-7 rad): PCHIP's q' is nearly zero
    there and its q'' jumps at the waypoints. Timed at the execution's 250 Hz within the Panda's limits."""
    Q = np.hstack([RETRACT, np.full((len(RETRACT), 2), 0.04)])
    limits = panda_limits()
    timed = time_parameterize(Q, 250.0, limits, grid_per_segment=grid_per_segment)
    check_within_limits(timed, limits)
    assert np.all(in_some_segment_box(timed.q, Q))
    assert np.all(timed.qd[0] == 0) and np.all(timed.qd[-1] == 0)
    assert np.array_equal(timed.q[0], Q[0]) and np.array_equal(timed.q[-1], Q[-1])
    # Near the time optimum: the acceleration limit of some joint is reached (at most the last stretch).
    assert np.max(np.abs(timed.qdd) / limits.acceleration) > 0.95
    assert timed.slowdown < 1.05


# A lift the pick-and-place planner made (built-in scene 10 from 3 views): joint 1 turns back at the third
# waypoint (a step of 1e-6 rad), where PCHIP's q' is exactly 0. With the path on s in [0, 1] its s' ran to
# hundreds, TOPP-RA's LP came out empty on 6 or more grid points per segment and the unit ended with an
# exception.
TURN = np.array(
    [
        [-0.204577, 0.104171, -0.442874, -2.130783, 0.313930, 2.018794, 1.540561, 0.04, 0.04],
        [-0.203547, 0.104074, -0.442071, -2.122834, 0.313065, 2.011574, 1.544928, 0.04, 0.04],
        [-0.202534, 0.104073, -0.441267, -2.114796, 0.312262, 2.004343, 1.549244, 0.04, 0.04],
        [-0.201538, 0.104171, -0.440463, -2.106669, 0.311522, 1.997101, 1.553512, 0.04, 0.04],
        [-0.200561, 0.104365, -0.439659, -2.098454, 0.310842, 1.989847, 1.557731, 0.04, 0.04],
        [-0.199602, 0.104656, -0.438856, -2.090149, 0.310222, 1.982582, 1.561903, 0.04, 0.04],
        [-0.198661, 0.105043, -0.438055, -2.081754, 0.309660, 1.975304, 1.566028, 0.04, 0.04],
        [-0.197739, 0.105526, -0.437256, -2.073269, 0.309157, 1.968013, 1.570109, 0.04, 0.04],
        [-0.196836, 0.106106, -0.436459, -2.064694, 0.308710, 1.960710, 1.574145, 0.04, 0.04],
        [-0.195951, 0.106781, -0.435666, -2.056027, 0.308319, 1.953393, 1.578138, 0.04, 0.04],
        [-0.195086, 0.107552, -0.434875, -2.047269, 0.307984, 1.946062, 1.582088, 0.04, 0.04],
    ]
)


@pytest.mark.parametrize("grid_per_segment", [4, 8, 16, 32, 64])
@pytest.mark.parametrize("first", [0, 1])
def test_a_short_path_turning_a_joint_back_is_timed_on_every_grid(grid_per_segment, first):
    """Rest to rest is always feasible. The path runs over its joint-space length, so the LP is solved on
    path speeds of the joints' order; from the second waypoint the turn is the first waypoint inside the
    path, where q'' from both of its sides gave the LP a NaN and toppra's own constraint times it. Within
    the limits, on the path."""
    Q = TURN[first:]
    limits = panda_limits()
    timed = time_parameterize(Q, 250.0, limits, grid_per_segment=grid_per_segment)
    check_within_limits(timed, limits)
    assert np.all(in_some_segment_box(timed.q, Q, tol=1e-6))
    assert np.array_equal(timed.q[0], Q[0]) and np.array_equal(timed.q[-1], Q[-1])
    assert timed.slowdown < 1.1


@pytest.mark.parametrize("interpolation", list(Interpolation))
def test_path_left_derivatives_are_the_pieces_before_each_waypoint(interpolation):
    """The acceleration constraint bounds q'' from both sides of a waypoint: the left one is the limit of
    the piece before it (scipy evaluates a knot on the piece after it)."""
    from pickplan.core.timing import _path

    Q = np.hstack([RETRACT, np.full((len(RETRACT), 2), 0.04)])
    path, ss = _path(Q, interpolation)
    for order in (1, 2):
        left = path.left(ss[1:], order)
        assert np.allclose(left, path(ss[1:] - 1e-9, order), rtol=1e-5, atol=1e-6)
        interior = ss[:-1] + np.diff(ss) * 0.37  # inside the pieces
        assert np.allclose(path.left(interior, order), path(interior, order), rtol=1e-9, atol=1e-12)
    jump = np.abs(path.left(ss[1:-1], 2) - path(ss[1:-1], 2)).max()
    assert (jump > 1e-3) if interpolation is Interpolation.PCHIP else (jump < 1e-6)


def test_export_round_trips(tmp_path, demo_plan):
    timed = demo_plan[1].timed(rate=250.0)
    for name in ("timed.json", "timed.npz"):
        timed.save(tmp_path / name)
        back = TimedTrajectory.load(tmp_path / name)
        for key in ("t", "q", "qd", "qdd"):
            assert np.array_equal(getattr(back, key), getattr(timed, key)), (name, key)
        assert back.rate == timed.rate and back.duration == timed.duration
    data = json.loads((tmp_path / "timed.json").read_text())
    assert data["format"] == "pickplan.timed_trajectory/1" and len(data["q"]) == len(timed.t)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["timed.json", "timed.npz"]  # no temporary files left


def test_resampled_keeps_the_motion(demo_plan):
    timed = demo_plan[1].timed(rate=RATE)
    coarse = timed.resampled(240.0)
    assert np.allclose(np.diff(coarse.t[:-1]), 1 / 240.0) and coarse.duration == pytest.approx(timed.duration)
    idx = np.round(coarse.t * RATE).astype(int)
    near = np.abs(coarse.t * RATE - idx) < 1e-6  # the times both sample
    assert near.sum() > 10 and np.allclose(coarse.q[near], timed.q[idx[near]], atol=1e-9)


def test_degenerate_paths():
    q = np.array(PANDA.ready)
    single = time_parameterize(q[None], RATE)
    assert single.duration == 0.0 and np.array_equal(single.q[0], q)
    repeated = time_parameterize(np.array([q, q, q + 0.1, q + 0.1]), RATE)  # repeated waypoints add no path
    assert repeated.duration > 0 and np.allclose(repeated.q[-1], q + 0.1)


def test_bad_input_is_a_clear_error(tmp_path):
    q = np.array(PANDA.ready)
    with pytest.raises(ValueError, match="NaN or infinity"):
        time_parameterize(np.array([q, q * np.nan]))
    with pytest.raises(ValueError, match=r"shape \(T, dof\)"):
        time_parameterize(q)
    with pytest.raises(ValueError, match="rate must be a positive"):
        time_parameterize(np.array([q, q + 0.1]), rate=0.0)
    with pytest.raises(ValueError, match="expected 9 joints"):
        time_parameterize(np.array([q, q + 0.1]), limits=KinematicLimits(np.ones(7), np.ones(7)))
    with pytest.raises(ValueError, match="positive finite"):
        KinematicLimits(np.ones(3), -np.ones(3))
    with pytest.raises(ValueError, match="Interpolation"):
        time_parameterize(np.array([q, q + 0.1]), interpolation="pchip")
    timed = time_parameterize(np.array([q, q + 0.1]), RATE)
    with pytest.raises(ValueError, match=".json or .npz"):
        timed.save(tmp_path / "timed.csv")
    (tmp_path / "other.json").write_text('{"format": "something else"}')
    with pytest.raises(ValueError, match="not a timed trajectory"):
        TimedTrajectory.load(tmp_path / "other.json")


def test_executing_the_timed_plan_lifts_on_its_schedule(demo_plan):
    """The demo scene lifts with the waypoints (the existing behaviour) and with the timed trajectory,
    which PyBullet follows at its own times: the simulated time is the timed duration plus the fixed
    settle, close, lift and hold phases."""
    from pickplan.sim.execution import ExecutionSettings, execute_plan

    scene, result = demo_plan
    timed = result.timed(rate=RATE)  # 1 kHz: resampled to the 240 Hz control rate by execute_plan
    s = ExecutionSettings()
    by_waypoints = execute_plan(scene, result.trajectory, s)
    by_time = execute_plan(scene, timed, s)
    assert by_waypoints.success
    assert by_time.success and by_time.status == "lifted" and by_time.target_lift > 0.8 * s.lift_height
    assert not by_time.collided and by_time.tracking_error < 0.05
    fixed = s.start_settle + s.approach_settle + s.closing_time(robot_info("panda")) + s.lift_duration + s.hold_duration
    assert by_time.sim_time == pytest.approx(fixed + timed.duration, abs=3 * s.time_step)
    assert by_time.sim_time < by_waypoints.sim_time  # the limits allow a faster approach than 0.1 s per waypoint


def test_demo_table_reports_duration_and_a_run_that_did_not_happen(demo_plan):
    from pickplan.eval.demo import metrics_table

    _, result = demo_plan
    timed = result.timed(rate=RATE)
    rows = {
        line.split("|")[1].strip(): line.split("|")[2].strip()
        for line in metrics_table(result, None, timed).splitlines()
        if line.startswith("| ")
    }
    assert rows["Execution (target lifted)"] == "not run"
    duration = rows["Trajectory duration (s, timed within the Panda's velocity and acceleration limits)"]
    assert float(duration) == pytest.approx(timed.duration, abs=1e-3)


@pytest.mark.parametrize("delta, min_duration", [(0.04, 0.0), (0.04, 0.5), (1.2, 0.0), (0.0, 0.2)])
def test_joint_move_is_a_rest_to_rest_quintic_at_the_limits(delta, min_duration):
    limits = panda_limits()
    a = np.array(PANDA.ready, float)
    b = a.copy()
    b[3] += delta
    m = joint_move(a, b, limits, RATE, min_duration)
    np.testing.assert_allclose(m.q[[0, -1]], [a, b], atol=1e-12)
    np.testing.assert_allclose(m.qd[[0, -1]], 0.0, atol=1e-12)
    assert np.all(np.abs(m.qd) <= limits.velocity * (1 + 1e-9)) and np.all(
        np.abs(m.qdd) <= limits.acceleration * (1 + 1e-9)
    )
    # the closed form's shortest duration (peak speed 15/8 d/T, peak acceleration 10/sqrt(3) d/T^2), whole samples
    need = max(
        min_duration,
        1.875 * delta / limits.velocity[3],
        math.sqrt(10 / math.sqrt(3) * delta / limits.acceleration[3]),
        1 / RATE,
    )
    assert need <= m.duration < need + 1.0 / RATE
    # the velocities and accelerations are the positions' derivatives (central differences)
    np.testing.assert_allclose(np.gradient(m.q[:, 3], m.t)[1:-1], m.qd[1:-1, 3], atol=1e-12 + 1e-3 * np.abs(m.qd).max())
    np.testing.assert_allclose(
        np.gradient(m.qd[:, 3], m.t)[1:-1], m.qdd[1:-1, 3], atol=1e-12 + 1e-2 * np.abs(m.qdd).max()
    )
    others = np.delete(np.arange(len(a)), 3)
    assert np.all(m.q[:, others] == a[others])


def test_concatenate_joins_at_rest_and_reports_each_part():
    limits = panda_limits()
    paths = list(random_paths(count=2, waypoints=6, seed=3))
    first = time_parameterize(paths[0], RATE, limits)
    hold = joint_move(first.q[-1], first.q[-1] + np.r_[np.zeros(7), -0.02, -0.02], limits, RATE, 0.3)
    second = time_parameterize(np.vstack([hold.q[-1], paths[1][1:] + (hold.q[-1] - paths[1][0])]), RATE, limits)
    whole, spans = concatenate([first, hold, second])
    assert len(whole.t) == len(first.t) + len(hold.t) + len(second.t) - 2
    np.testing.assert_allclose(np.diff(whole.t), 1.0 / RATE, atol=1e-9)
    np.testing.assert_allclose(
        spans,
        [
            (0, first.duration),
            (first.duration, first.duration + hold.duration),
            (first.duration + hold.duration, whole.duration),
        ],
        atol=1e-9,
    )
    for part, (t0, t1) in zip((first, hold, second), spans):
        k0 = int(round(t0 * RATE))
        np.testing.assert_array_equal(whole.q[k0 : k0 + len(part.t)], part.q)
    with pytest.raises(ValueError, match="starts .* away"):
        concatenate([first, second])
    with pytest.raises(ValueError, match="Hz"):
        concatenate([first, hold.resampled(500.0)])
