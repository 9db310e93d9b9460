"""Rotational symmetry (``core.meshes.symmetry_axis``) and the place test's tilt modulo it: a pen that
rolled on its side is where it was asked to be; one that stood up is not."""

import numpy as np
import pytest
import trimesh

from pickplan.core import objects
from pickplan.core.meshes import symmetry_axis
from pickplan.sim.pickplace_exec import _tilt_and_yaw


def _turned(axis, deg, point=(0.0, 0.0, 0.0)) -> np.ndarray:
    return trimesh.transformations.rotation_matrix(np.radians(deg), axis, point)


def test_the_axis_of_a_turned_cylinder_and_of_a_pen_and_none_for_a_box_or_a_mug():
    T = _turned([1.0, 2.0, 0.5], 50.0)
    T[:3, 3] = [0.3, -0.1, 0.2]
    cylinder = trimesh.creation.cylinder(radius=0.03, height=0.12, sections=24, transform=T)
    axis = symmetry_axis(cylinder)
    assert axis is not None and abs(axis @ T[:3, 2]) > 0.9999
    pen = objects.library("procedural").get("pen_00").mesh  # a body and a wider cap on one axis (x)
    assert abs(symmetry_axis(pen) @ [1.0, 0.0, 0.0]) > 0.9999
    assert symmetry_axis(trimesh.creation.box(extents=(0.12, 0.03, 0.03))) is None  # square: 90 deg only
    assert symmetry_axis(objects.library("builtin").get("025_mug").mesh) is None  # the handle


@pytest.mark.parametrize("deg", [40.0, 90.0, 150.0])
def test_a_pen_rolled_about_its_axis_is_not_tilted_and_one_tipped_is(deg):
    pen = objects.library("procedural").get("pen_00").mesh
    axis = symmetry_axis(pen)
    planned = np.eye(4)  # lying along x, as generated
    rolled = planned @ _turned([1.0, 0.0, 0.0], deg)
    tipped = _turned([0.0, 1.0, 0.0], 30.0) @ planned  # its axis tilted 30 deg out of the horizontal
    assert _tilt_and_yaw(rolled, planned, axis)[0] == pytest.approx(0.0, abs=1e-6)
    assert _tilt_and_yaw(rolled, planned)[0] == pytest.approx(deg, abs=1e-6)  # without the symmetry
    assert _tilt_and_yaw(tipped @ _turned([1.0, 0.0, 0.0], deg), planned, axis)[0] == pytest.approx(30.0, abs=1e-6)
