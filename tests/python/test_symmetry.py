"""Rotational symmetry (``core.meshes.symmetry_axes``) and the place test's tilt modulo it: a pen that
rolled on its side is where it was asked to be; one that stood up is not; a ball has no tilt."""

import numpy as np
import pytest
import trimesh

from pickplan.core import objects
from pickplan.core.meshes import symmetry_axes
from pickplan.sim.pickplace_exec import _tilt_and_yaw


def _turned(axis, deg, point=(0.0, 0.0, 0.0)) -> np.ndarray:
    return trimesh.transformations.rotation_matrix(np.radians(deg), axis, point)


def test_the_axis_of_a_turned_cylinder_and_of_a_pen_and_none_for_a_box_or_a_mug():
    T = _turned([1.0, 2.0, 0.5], 50.0)
    T[:3, 3] = [0.3, -0.1, 0.2]
    cylinder = trimesh.creation.cylinder(radius=0.03, height=0.12, sections=24, transform=T)
    axes = symmetry_axes(cylinder)
    assert len(axes) == 1 and abs(axes[0] @ T[:3, 2]) > 0.9999
    pen = objects.library("procedural").get("pen_00").mesh  # a body and a wider cap on one axis (x)
    (axis,) = symmetry_axes(pen)
    assert abs(axis @ [1.0, 0.0, 0.0]) > 0.9999
    assert symmetry_axes(trimesh.creation.box(extents=(0.12, 0.03, 0.03))) == []  # square: 90 deg only
    assert symmetry_axes(objects.library("builtin").get("025_mug").mesh) == []  # the handle
    assert symmetry_axes(trimesh.creation.box(extents=(0.03, 0.03, 0.03))) == []  # a cube: 90 deg only


@pytest.mark.parametrize("deg", [40.0, 90.0, 150.0])
def test_a_pen_rolled_about_its_axis_is_not_tilted_and_one_tipped_is(deg):
    pen = objects.library("procedural").get("pen_00").mesh
    axes = symmetry_axes(pen)
    planned = np.eye(4)  # lying along x, as generated
    rolled = planned @ _turned([1.0, 0.0, 0.0], deg)
    tipped = _turned([0.0, 1.0, 0.0], 30.0) @ planned  # its axis tilted 30 deg out of the horizontal
    assert _tilt_and_yaw(rolled, planned, axes)[0] == pytest.approx(0.0, abs=1e-6)
    assert _tilt_and_yaw(rolled, planned)[0] == pytest.approx(deg, abs=1e-6)  # without the symmetry
    assert _tilt_and_yaw(tipped @ _turned([1.0, 0.0, 0.0], deg), planned, axes)[0] == pytest.approx(30.0, abs=1e-6)


def test_a_ball_has_three_axes_and_no_tilt_or_heading_however_it_rolled():
    ball = trimesh.creation.icosphere(subdivisions=2, radius=0.012)  # faceted, as the procedural small balls
    ball.apply_translation((0.0, 0.0, 0.012))
    axes = symmetry_axes(ball)
    assert len(axes) == 3 and np.allclose(np.array(axes) @ np.array(axes).T, np.eye(3), atol=1e-9)
    rolled = _turned([1.0, 1.0, 0.0], 70.0) @ _turned([0.0, 0.0, 1.0], 40.0)
    assert _tilt_and_yaw(rolled, np.eye(4), axes) == (0.0, 0.0)
    assert _tilt_and_yaw(rolled, np.eye(4))[0] == pytest.approx(70.0, abs=1e-6)
