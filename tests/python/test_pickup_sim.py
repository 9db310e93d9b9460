"""Moving-gripper simulation: determinism, obvious labels, physics trends, bad input."""

import os

import numpy as np
import pytest

from pickplan.pickup.metamodel.parallel import run_batch, sample_seeds
from pickplan.pickup.metamodel.parts import PARTS, get_part
from pickplan.pickup.metamodel.sim import SimConfig, closing_time, nominal_part_pose, simulate_grasp


def test_same_seed_same_result_and_seed_matters():
    a = simulate_grasp("box", (0.004, -0.003, 0.05), 0.3, 0.1, seed=5)
    b = simulate_grasp("box", (0.004, -0.003, 0.05), 0.3, 0.1, seed=5)
    assert (a.success, a.reason, a.drift, a.lift, a.steps) == (b.success, b.reason, b.drift, b.lift, b.steps)
    # The seed drives the friction jitter, so the trajectory of the part changes with it.
    c = simulate_grasp("box", (0.004, -0.003, 0.05), 0.3, 0.1, seed=6)
    assert (c.drift, c.lift) != (a.drift, a.lift)


@pytest.mark.parametrize("part", sorted(PARTS))
def test_zero_offset_at_low_speed_succeeds(part):
    out = simulate_grasp(part, (0.0, 0.0, 0.0), 0.1, 0.1, seed=0)
    assert out.success, out
    assert out.lift > 0.02  # carried up with the gripper (lift ~0.03 m during the hold)


@pytest.mark.parametrize("part", sorted(PARTS))
@pytest.mark.parametrize("offset", [(0.0, 0.045, 0.0), (0.06, 0.0, 0.0)])
def test_large_offset_fails(part, offset):
    # 45 mm sideways puts the part under a finger; 60 mm ahead means the fingers close
    # before the part arrives.
    out = simulate_grasp(part, offset, 0.1, 0.1, seed=0)
    assert not out.success, out


def test_faster_gripper_tolerates_less_lateral_offset():
    # Contact timing: with y offset d a finger touches the part d / S_c before t', when the
    # part is still S_g * d / S_c ahead of the pads.
    slow = simulate_grasp("box", (0.0, 0.008, 0.0), 0.1, 0.05, seed=1)
    fast = simulate_grasp("box", (0.0, 0.008, 0.0), 0.5, 0.05, seed=1)
    assert slow.success and not fast.success


def test_nominal_pose_puts_grasp_point_at_origin():
    part = get_part("l_bracket")
    xy, yaw = nominal_part_pose(part)
    c, s = np.cos(yaw), np.sin(yaw)
    gx, gy = part.strategy.tcp_xyz[:2]
    np.testing.assert_allclose([xy[0] + c * gx - s * gy, xy[1] + s * gx + c * gy], [0, 0], atol=1e-12)
    assert closing_time(part, 0.1) == pytest.approx((0.085 - 0.015) / 0.2)


def test_bad_input():
    with pytest.raises(ValueError, match="S_g"):
        simulate_grasp("box", (0, 0, 0), 1.5, 0.1)  # the modelled range ends at 1.2 m/s
    with pytest.raises(ValueError, match="S_c"):
        simulate_grasp("box", (0, 0, 0), 0.2, 0.01)
    with pytest.raises(ValueError, match="shape"):
        simulate_grasp("box", (0, 0), 0.2, 0.1)
    with pytest.raises(ValueError, match="unknown part"):
        simulate_grasp("teapot", (0, 0, 0), 0.2, 0.1)
    missing = os.path.join("/nonexistent", "gripper.urdf")
    with pytest.raises(FileNotFoundError, match="gripper.urdf"):
        simulate_grasp("box", (0, 0, 0), 0.2, 0.1, SimConfig(urdf_path=missing))
    with pytest.raises(ValueError, match="shape"):
        run_batch("box", np.zeros((3, 2)), 0.2, 0.1)


def test_batch_is_the_same_in_worker_processes():
    offsets = np.array([[0.0, 0.0, 0.0], [0.0, 0.045, 0.0], [0.01, 0.004, 0.1], [0.06, 0.0, 0.0], [-0.01, 0.0, -0.05]])
    serial = run_batch("cylinder", offsets, 0.3, 0.1, seed=3, workers=1)
    parallel = run_batch("cylinder", offsets, 0.3, 0.1, seed=3, workers=2)
    np.testing.assert_array_equal(serial, parallel)
    seeds = sample_seeds(3, 0, len(offsets))
    direct = [simulate_grasp("cylinder", o, 0.3, 0.1, seed=int(s)).success for o, s in zip(offsets, seeds)]
    np.testing.assert_array_equal(serial, direct)
    assert serial[0] and not serial[1] and not serial[3]
