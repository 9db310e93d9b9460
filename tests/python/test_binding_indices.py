"""Index arrays given to the native core directly (issue 26): an int64 2**32 + 3 was narrowed to int
in the bindings without a check and became link 3 (or vertex 3); now every index array is checked
at full width and a bad one raises ValueError naming the argument."""

import numpy as np
import pytest
import trimesh

from pickplan import _core
from pickplan.core import sdf

HUGE = 2**32 + 3  # wraps to 3 as int32


@pytest.fixture(scope="module")
def scene():
    grid = sdf.mesh_sdf(trimesh.creation.box(extents=(0.1, 0.1, 0.1)), sdf.SdfSettings(cache_dir=""))
    pose = np.eye(4)
    pose[:3, 3] = [0.5, 0.0, 0.05]
    return sdf.SceneSdf([("box", grid, pose)])


def _links(panda, bad):
    """A valid link array with one bad entry (index 1), as numpy int64."""
    return np.array([3, bad, 5], dtype=np.int64)


@pytest.mark.parametrize("bad, shown", [(HUGE, "4294967299"), (-1, "-1")])
def test_chomp_body_links_are_range_checked_before_narrowing(panda, scene, bad, shown):
    points = np.zeros((3, 3))
    n = len(panda.link_names)
    with pytest.raises(ValueError, match=rf"^links: entry 1 = {shown} out of range \[0, {n}\)$"):
        _core.ChompProblem(panda.native, scene.native, _links(panda, bad), points, _core.ChompSettings())
    ok = _core.ChompProblem(panda.native, scene.native, np.array([3, 4, 5]), points, _core.ChompSettings())
    assert ok.dt > 0  # the same call with in-range links builds


@pytest.mark.parametrize("bad, shown", [(HUGE, "4294967299"), (-1, "-1")])
def test_isf_body_links_are_range_checked_before_narrowing(panda, scene, bad, shown):
    pts = np.array([[0.0, 0.0, 0.0], [0.01, 0.0, 0.0], [0.0, 0.01, 0.0]])
    args = [panda.native, panda.hand_link, pts, pts, scene.native, pts, pts, scene.native]
    tail = [np.zeros((3, 3)), 0, _core.IsfSettings()]
    with pytest.raises(ValueError, match=rf"^body_links: entry 1 = {shown} out of range"):
        _core.GraspRefiner(*args, _links(panda, bad), *tail)
    assert _core.GraspRefiner(*args, np.array([3, 4, 5]), *tail) is not None


def test_transform_points_links_and_other_index_kinds(panda):
    q = panda.ready_configuration[None]
    for bad, shown in ((HUGE, "4294967299"), (-1, "-1"), (np.uint64(2**64 - 1), "18446744073709551615")):
        links = np.array([0, bad], dtype=np.uint64 if isinstance(bad, np.uint64) else np.int64)
        with pytest.raises(ValueError, match=rf"^links: entry 1 = {shown} out of range"):
            panda.native.transform_points(q, links, np.zeros((2, 3)))
    with pytest.raises(ValueError, match="links: expected integer indices, got dtype float64"):
        panda.native.transform_points(q, np.array([0.0, 3.7]), np.zeros((2, 3)))
    # In range: the points are where forward kinematics puts the link origins.
    X = panda.native.transform_points(q, [0, 3], np.zeros((2, 3)))
    np.testing.assert_allclose(X[0, 1], panda.link_pose(q[0], 3)[:3, 3], atol=1e-12)


def test_mesh_faces_past_32_bits_are_refused_not_wrapped(panda):
    box = trimesh.creation.box(extents=(0.1, 0.1, 0.1))
    F = np.asarray(box.faces, dtype=np.int64)
    F[2, 1] = HUGE
    with pytest.raises(ValueError, match=r"^faces: entry 7 = 4294967299 out of range"):
        _core.SdfGrid.build(box.vertices, F, 0.01, 0.05)
    with pytest.raises(ValueError, match=r"^object 'box' faces: entry 7 = 4294967299 out of range"):
        _core.CollisionChecker(
            panda.native, [], [("box", box.vertices, F, np.eye(4))], None, None, _core.CollisionSettings()
        )
