"""The place test waits for the object to come to rest (``pickplace_exec._settle``), in PyBullet: a tall
box let go tilted rocks on its edges past the shortest wait and then stands still; a ball rolling on a
plane without rolling friction never stops, and the wait ends at its cap with the ball still moving."""

from types import SimpleNamespace

import numpy as np
import pybullet as pb
import pytest

from pickplan.sim.pickplace_exec import PickPlaceExecSettings, PlaceCheck, _settle

STEP = 1.0 / 240.0
CHECK = PlaceCheck((-1.0, -1.0, 0.0), (1.0, 1.0, 1.0), np.eye(4))


class _World:
    """The part of an ``ArmSim`` that settling reads: a client with a plane and one body (no robot)."""

    def __init__(self, shape: dict, position, tilt: float, velocity=(0.0, 0.0, 0.0)):
        self.pb, self.c = pb, pb.connect(pb.DIRECT)
        pb.setGravity(0, 0, -9.81, physicsClientId=self.c)
        pb.setTimeStep(STEP, physicsClientId=self.c)
        plane = pb.createCollisionShape(pb.GEOM_PLANE, physicsClientId=self.c)
        pb.createMultiBody(0.0, plane, physicsClientId=self.c)
        body = pb.createMultiBody(
            0.2,
            pb.createCollisionShape(physicsClientId=self.c, **shape),
            -1,
            position,
            pb.getQuaternionFromEuler([tilt, 0.0, 0.0]),
            physicsClientId=self.c,
        )
        pb.changeDynamics(body, -1, rollingFriction=0.0, spinningFriction=0.0, physicsClientId=self.c)
        pb.resetBaseVelocity(body, velocity, physicsClientId=self.c)
        self.bodies, self.target, self.s = {"object": body}, "object", SimpleNamespace(time_step=STEP)
        self.seconds = 0.0

    def joint_positions(self):
        return np.zeros(0)

    def command_arm(self, q, qd):
        pass

    def step(self, watch=False):
        pb.stepSimulation(physicsClientId=self.c)
        self.seconds += STEP


def _settled(world: _World, settings: PickPlaceExecSettings) -> bool:
    try:
        v, w = _settle(world, CHECK, settings)
    finally:
        pb.disconnect(world.c)
    assert world.seconds <= settings.settle_max + STEP
    return bool(np.linalg.norm(v) <= CHECK.rest_speed and np.linalg.norm(w) <= CHECK.rest_spin)


def test_a_rocking_box_is_waited_for_until_it_stands_still():
    """A 6 x 6 x 24 cm box let go 7 deg from upright 8 mm above the plane: still rocking after the 1 s the
    test waited before, at rest (and read so) before the 5 s cap."""
    box = dict(shapeType=pb.GEOM_BOX, halfExtents=[0.03, 0.03, 0.12])
    assert not _settled(_World(box, [0.0, 0.0, 0.128], 0.12), PickPlaceExecSettings(settle_max=1.0))
    world = _World(box, [0.0, 0.0, 0.128], 0.12)
    assert _settled(world, PickPlaceExecSettings()) and 1.0 < world.seconds < 5.0


def test_a_ball_that_keeps_rolling_is_moving_at_the_cap():
    ball = dict(shapeType=pb.GEOM_SPHERE, radius=0.03)
    world = _World(ball, [0.0, 0.0, 0.03], 0.0, velocity=(0.3, 0.0, 0.0))
    assert not _settled(world, PickPlaceExecSettings(settle_max=2.0))
    assert abs(world.seconds - 2.0) <= STEP


@pytest.mark.parametrize("bad", [dict(settle_check=0.0), dict(settle_max=0.5), dict(settle_duration=-1.0)])
def test_settling_settings_are_checked(bad):
    with pytest.raises(ValueError, match="settle"):
        PickPlaceExecSettings(**bad)
