"""pickplan.core.objects: built-in shapes, mass properties, resting poses, the YCB-layout loader, errors."""

import os

import numpy as np
import pytest
import trimesh
from scipy.spatial import ConvexHull

from pickplan.core import objects
from pickplan.core import objects_builtin
from conftest import ycb_dir_or_skip

YCB_TEN = [
    "002_master_chef_can",
    "003_cracker_box",
    "004_sugar_box",
    "005_tomato_soup_can",
    "006_mustard_bottle",
    "010_potted_meat_can",
    "019_pitcher_base",
    "021_bleach_cleanser",
    "024_bowl",
    "025_mug",
]


@pytest.fixture(scope="module")
def builtins():
    lib = objects.library("builtin")
    return {n: lib.get(n) for n in lib.names}


def _inside_convex(part, pts, tol):
    """Whether points lie within ``tol`` of a convex part (max over its face planes)."""
    n = part.face_normals
    d = np.einsum("ij,ij->i", n, part.triangles_center)
    return np.max(pts @ n.T - d, axis=1) <= tol


def test_builtin_library_has_the_ten_paper_objects_and_is_cached(builtins, monkeypatch):
    monkeypatch.delenv(objects.YCB_ENV, raising=False)
    lib = objects.library()
    assert lib.names == YCB_TEN
    assert objects.library("builtin") is lib
    assert lib.get("025_mug") is builtins["025_mug"]
    with pytest.raises(KeyError, match="999_nothing"):
        lib.get("999_nothing")


@pytest.mark.parametrize("name", YCB_TEN)
def test_builtin_is_watertight_with_spec_dimensions_and_covering_convex_parts(builtins, name):
    m = builtins[name]
    spec = objects_builtin.BUILTIN_SPECS[name]
    assert m.mesh.is_watertight and m.mesh.is_winding_consistent and m.mesh.volume > 0
    np.testing.assert_allclose(m.extents, spec.extents, atol=1e-6)
    assert m.mesh.bounds[0][2] == pytest.approx(0.0, abs=1e-12)  # object frame: bottom on z = 0
    assert m.source == f"builtin:{name}" and m.grasps == {}
    assert m.collision_parts and all(p.is_convex for p in m.collision_parts)
    # every surface point lies in (or within 1 mm of) some convex part ...
    pts, _ = trimesh.sample.sample_surface(m.mesh, 1500, seed=1)
    covered = np.zeros(len(pts), bool)
    for p in m.collision_parts:
        covered |= _inside_convex(p, pts, 1e-3)
    assert covered.all()
    # ... and the parts do not stick out of the object's bounding box by more than 1 mm
    allv = np.vstack([p.vertices for p in m.collision_parts])
    assert np.all(allv >= m.mesh.bounds[0] - 1e-3) and np.all(allv <= m.mesh.bounds[1] + 1e-3)


def test_bowl_and_mug_are_hollow_and_the_mug_has_a_handle(builtins):
    bowl, mug = builtins["024_bowl"], builtins["025_mug"]
    # a point just above the bowl's floor is outside the solid; a point in its wall is inside
    assert not bowl.mesh.contains([[0.0, 0.0, 0.02]])[0]
    assert not mug.mesh.contains([[0.0, 0.0, 0.04]])[0]
    R = objects_builtin.BUILTIN_SPECS["025_mug"].extents[1] / 2
    assert mug.mesh.contains([[R - 0.002, 0.0, 0.04]])[0]
    # the handle: material beyond the cup radius on +x only, at mid height
    far = mug.mesh.vertices[mug.mesh.vertices[:, 0] > R + 0.005]
    assert len(far) > 0 and far[:, 2].min() > 0.01 and far[:, 2].max() < 0.075
    assert mug.com[0] > 0.001  # the handle pulls the centre of mass towards +x


def test_builtin_masses_are_ycb_masses_and_inertias_physical(builtins):
    for name, m in builtins.items():
        assert m.mass == pytest.approx(objects_builtin.BUILTIN_SPECS[name].mass, rel=1e-9)
        np.testing.assert_allclose(m.inertia, m.inertia.T, atol=1e-15)
        I = np.linalg.eigvalsh(m.inertia)
        assert I.min() > 0 and I[0] + I[1] >= I[2] * (1 - 1e-9)  # triangle inequality of moments


def test_box_mass_properties_match_closed_form():
    a, b, c, mass = 0.07, 0.16, 0.21, 0.4
    box = trimesh.creation.box(extents=[a, b, c])
    box.apply_translation([0.01, -0.02, 0.3])
    m, com, I = objects.mass_properties(box, mass=mass)
    assert m == pytest.approx(mass)
    np.testing.assert_allclose(com, [0.01, -0.02, 0.3], atol=1e-12)
    expected = mass / 12 * np.diag([b * b + c * c, a * a + c * c, a * a + b * b])
    np.testing.assert_allclose(I, expected, rtol=1e-9, atol=1e-12)


def test_can_volume_and_inertia_match_the_prism_closed_form():
    # The built-in revolve is an inscribed n-gon prism: V = n/2 r^2 sin(2 pi / n) h exactly.
    r, h, n = 0.034, 0.102, objects_builtin.SECTIONS
    mesh = objects_builtin._revolve([(0, 0), (r, 0), (r, h), (0, h)])
    assert mesh.volume == pytest.approx(n / 2 * r * r * np.sin(2 * np.pi / n) * h, rel=1e-12)
    m, com, I = objects.mass_properties(mesh, density=1000.0)
    np.testing.assert_allclose(com, [0, 0, h / 2], atol=1e-12)
    # a fine prism is a cylinder: Izz = m r^2 / 2, Ixx = m (3 r^2 + h^2) / 12 (polygon error < 0.6 %)
    assert I[2, 2] == pytest.approx(m * r * r / 2, rel=6e-3)
    assert I[0, 0] == pytest.approx(m * (3 * r * r + h * h) / 12, rel=6e-3)
    assert m == pytest.approx(1000.0 * mesh.volume)


@pytest.mark.parametrize("name", YCB_TEN)
def test_resting_poses_touch_the_plane_and_hold_the_com_over_the_support(builtins, name):
    m = builtins[name]
    assert 1 <= len(m.resting_poses) == len(m.resting_barriers)
    assert list(m.resting_barriers) == sorted(m.resting_barriers, reverse=True)  # most stable first
    for T in m.resting_poses:
        np.testing.assert_allclose(T[:3, :3] @ T[:3, :3].T, np.eye(3), atol=1e-12)
        z = m.mesh.vertices @ T[:3, :3].T[:, 2] + T[2, 3]
        assert z.min() == pytest.approx(0.0, abs=1e-9)
        com = T[:3, :3] @ m.com + T[:3, 3]
        np.testing.assert_allclose(com[:2], 0.0, atol=1e-9)
        # the COM lies over the support: inside the convex hull of the points touching the plane
        verts = m.mesh.convex_hull.vertices @ T[:3, :3].T + T[:3, 3]
        touch = verts[verts[:, 2] < 1.5e-3, :2]
        assert len(touch) >= 3
        assert np.all(ConvexHull(touch).equations[:, 2] < 0)  # origin strictly inside every edge


def test_upright_can_barrier_matches_closed_form(builtins):
    # Tipping an upright can over its rim raises the COM by sqrt(h^2 + d^2) - h, d the distance from
    # the axis to the support polygon's edge: the rim ring (r minus the 4 mm chamfer) as an n-gon.
    m = builtins["005_tomato_soup_can"]
    d, h = (0.034 - 0.004) * np.cos(np.pi / objects_builtin.SECTIONS), 0.051
    assert m.resting_barriers[0] == pytest.approx(np.hypot(h, d) - h, rel=1e-6)
    assert abs(m.resting_poses[0][2, 2]) == pytest.approx(1.0)  # the axis stays vertical
    box = builtins["003_cracker_box"]  # flat on its largest face first
    up = np.abs(box.resting_poses[0][2, :3])
    assert np.argmax(up) == 0  # x is the 0.071 m thin axis


def test_resting_poses_are_stable_in_pybullet(builtins, bullet):
    """Each object at its most stable pose stays put for 0.5 s of simulation."""
    import pybullet as pb
    from pickplan.sim import scenes

    pb.setGravity(0, 0, -9.81, physicsClientId=bullet)
    plane = pb.createCollisionShape(pb.GEOM_PLANE, physicsClientId=bullet)
    pb.createMultiBody(0, plane, physicsClientId=bullet)
    bodies = []
    for i, (name, m) in enumerate(sorted(builtins.items())):
        T = m.resting_poses[0].copy()
        T[:2, 3] += [0.3 * (i % 5), 0.3 * (i // 5)]
        bodies.append((m, T, scenes.add_object_body(bullet, m, T)))
    for _ in range(120):
        pb.stepSimulation(physicsClientId=bullet)
    for m, T0, body in bodies:
        T = scenes.object_pose(bullet, body, m)
        assert np.linalg.norm(T[:3, 3] - T0[:3, 3]) < 3e-3, m.name
        assert T[:3, 2] @ T0[:3, 2] > np.cos(np.radians(2.0)), m.name


def test_resting_poses_are_deterministic(builtins):
    m = builtins["006_mustard_bottle"]
    poses, barriers = objects.compute_resting_poses(m.mesh, m.com)
    assert barriers == m.resting_barriers
    assert all(np.array_equal(a, b) for a, b in zip(poses, m.resting_poses))


def _write_object_folder(folder, mesh, parts=None, grasps=None):
    os.makedirs(folder, exist_ok=True)
    mesh.export(os.path.join(folder, "mesh.stl"))
    if parts is not None:
        with open(os.path.join(folder, "collision.obj"), "w") as f:
            f.write(open(objects._write_parts_obj(parts)).read())
    for key, arr in (grasps or {}).items():
        np.save(os.path.join(folder, f"grasps_{key}.npy"), arr)


def test_loader_reads_a_folder_in_the_ycb_layout(tmp_path, builtins, monkeypatch):
    src = builtins["025_mug"]
    g = np.tile(np.eye(4), (5, 1, 1))
    _write_object_folder(tmp_path / "025_mug", src.mesh, src.collision_parts, {"simulated": g})
    m = objects.load_ycb_object(tmp_path / "025_mug")
    assert m.name == "025_mug" and m.source == str(tmp_path / "025_mug")
    assert len(m.collision_parts) == len(src.collision_parts)
    for a, b in zip(m.collision_parts, src.collision_parts):
        np.testing.assert_allclose(np.sort(a.vertices, axis=0), np.sort(b.vertices, axis=0), atol=1e-8)
    assert set(m.grasps) == {"simulated"} and m.grasps["simulated"].shape == (5, 4, 4)
    assert m.mass == pytest.approx(0.118)  # a known YCB name gets its YCB mass
    np.testing.assert_allclose(m.com, src.com, atol=1e-6)
    assert m.collision_obj_path() == str(tmp_path / "025_mug" / "collision.obj")
    # the env var selects such a folder as the library
    monkeypatch.setenv(objects.YCB_ENV, str(tmp_path))
    assert objects.library().names == ["025_mug"]


def test_loader_errors_are_clear(tmp_path):
    with pytest.raises(FileNotFoundError, match="no_such_object"):
        objects.load_ycb_object(tmp_path / "no_such_object")
    (tmp_path / "no_mesh").mkdir()
    with pytest.raises(FileNotFoundError, match="mesh.stl"):
        objects.load_ycb_object(tmp_path / "no_mesh")
    (tmp_path / "empty").mkdir()
    (tmp_path / "empty" / "mesh.stl").write_bytes(b"")
    with pytest.raises(ValueError, match="empty|cannot read"):
        objects.load_ycb_object(tmp_path / "empty")
    flat = trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], [[0, 1, 2], [1, 3, 2]])
    _write_object_folder(tmp_path / "flat", flat)
    with pytest.raises(ValueError, match="degenerate"):
        objects.load_ycb_object(tmp_path / "flat")
    _write_object_folder(
        tmp_path / "badgrasps", trimesh.creation.box(extents=[0.05] * 3), grasps={"x": np.zeros((3, 3))}
    )
    with pytest.raises(ValueError, match=r"\(N, 4, 4\)"):
        objects.load_ycb_object(tmp_path / "badgrasps")
    with pytest.raises(FileNotFoundError, match="nowhere"):
        objects.library(tmp_path / "nowhere")
    with pytest.raises(ValueError, match="no object folders"):
        objects.library(tmp_path / "no_mesh")


def test_non_watertight_mesh_works_with_a_warning(tmp_path):
    box = trimesh.creation.box(extents=[0.05, 0.06, 0.08])
    open_box = trimesh.Trimesh(box.vertices, box.faces[:-1])
    _write_object_folder(tmp_path / "open_box", open_box)
    with pytest.warns(UserWarning, match="not watertight"):
        m = objects.load_ycb_object(tmp_path / "open_box", density=500.0)
    assert m.mass == pytest.approx(500.0 * 0.05 * 0.06 * 0.08, rel=1e-6)  # from the convex hull
    assert len(m.resting_poses) == 6


def test_obj_parts_reader_splits_objects_and_rejects_bad_lines(tmp_path):
    p = tmp_path / "two.obj"
    p.write_text(
        "o a\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 3 4\nf 1 4 2\nf 2 4 3\n"
        "o b\nv 2 0 0\nv 3 0 0\nv 2 1 0\nv 2 0 1\nf -4 -3 -2\nf 5 7 8\nf 5 8 6\nf 6 8 7\n"
    )
    parts = objects.read_obj_parts(str(p))
    assert len(parts) == 2 and all(len(q.faces) == 4 for q in parts)
    assert parts[1].vertices[:, 0].min() == 2.0
    p.write_text("v 0 0 zero\n")
    with pytest.raises(ValueError, match="two.obj:1"):
        objects.read_obj_parts(str(p))


def test_real_ycb_objects_load(tmp_path):
    root = ycb_dir_or_skip()
    lib = objects.library(root)
    assert set(YCB_TEN) <= set(lib.names)
    m = lib.get("006_mustard_bottle")
    assert m.mesh.is_watertight and len(m.mesh.faces) == 15728
    n_parts = sum(
        1 for line in open(os.path.join(root, "006_mustard_bottle", "collision.obj")) if line.startswith("o ")
    )
    assert len(m.collision_parts) == n_parts >= 2
    assert m.grasps["simulated"].shape == (100, 4, 4) and "graspit" in m.grasps
    assert m.mass == pytest.approx(0.603)
    T = m.resting_poses[0]
    assert (m.mesh.vertices @ T[:3, :3].T[:, 2] + T[2, 3]).min() == pytest.approx(0.0, abs=1e-9)
    # upright: the bottle's long axis (mesh z) stays vertical in its most stable pose
    assert abs(T[2, 2]) > 0.95
    assert "simulated" not in lib.get("002_master_chef_can").grasps
    # the built-in stand-in has the real object's size (within 12 % per axis, upright)
    np.testing.assert_allclose(
        np.sort(objects.library("builtin").get("006_mustard_bottle").extents), np.sort(m.extents), rtol=0.12
    )
