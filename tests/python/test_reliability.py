"""Regression tests for issue 26's bad-input cases, each named after the case it pins. Every
case must end in a clear exception (a ValueError / InputError naming the field) or, for caches,
a warning and a rebuild: never a crash, a silent repair of nonsense, or a confident wrong result."""

import json
import subprocess
import sys
import textwrap
import warnings

import numpy as np
import pytest
import trimesh

from pickplan.core import robots, sdf
from pickplan.core.collision import CollisionChecker, SceneMesh
from pickplan.core.errors import InputError
from pickplan.core.io import read_json
from pickplan.core.poses import RIGID_CLEAN_TOLERANCE, clean_poses
from pickplan.omg import grasps as G
from pickplan.sim import scenes

from conftest import ycb_dir_or_skip

URDF_ONE_JOINT = """<robot name="r">
  <link name="base"><collision><geometry>{geometry}</geometry></collision></link>
  <link name="arm"><collision><geometry><box size="0.1 0.1 0.1"/></geometry></collision></link>
  <joint name="j" type="revolute"><parent link="base"/><child link="arm"/><axis xyz="0 0 1"/>
    <limit lower="{lower}" upper="{upper}" effort="1" velocity="1"/></joint>
</robot>"""


def _urdf(tmp_path, geometry='<box size="0.1 0.1 0.1"/>', lower=-1.0, upper=1.0):
    path = tmp_path / "r.urdf"
    path.write_text(URDF_ONE_JOINT.format(geometry=geometry, lower=lower, upper=upper))
    return str(path)


def _rotated(angle=0.3):
    T = np.eye(4)
    T[:3, :3] = trimesh.transformations.rotation_matrix(angle, [0.2, 0.5, 1.0])[:3, :3]
    T[:3, 3] = [0.1, -0.2, 0.3]
    return T


# --- URDF -------------------------------------------------------------------------------------------
def test_urdf_nested_100000_deep_is_an_error_not_a_crash(tmp_path):
    path = tmp_path / "deep.urdf"
    depth = 100_000
    path.write_text('<robot name="r"><link name="base"/>' + "<a>" * depth + "</a>" * depth + "</robot>")
    # In a child process: before the fix the XML parser's recursion killed the interpreter (SIGSEGV).
    code = textwrap.dedent(f"""
        from pickplan.core import robots
        try:
            robots.Robot.from_urdf({str(path)!r})
        except ValueError as exc:
            print("ValueError:", exc)
    """)
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr[-2000:]
    assert "nested 100001 deep" in run.stdout and "at most 64" in run.stdout


def test_urdf_nesting_within_the_bound_still_loads(tmp_path):
    robot = robots.Robot.from_urdf(_urdf(tmp_path))
    assert robot.dof == 1 and robot.link_names == ["base", "arm"]


def test_urdf_sphere_of_radius_minus_one_is_refused(tmp_path):
    with pytest.raises(ValueError, match=r"link 'base': collision sphere radius must be a finite number > 0, got -1"):
        robots.Robot.from_urdf(_urdf(tmp_path, '<sphere radius="-1"/>'))
    with pytest.raises(ValueError, match="box size must be a finite number > 0"):
        robots.Robot.from_urdf(_urdf(tmp_path, '<box size="0.1 0 0.1"/>'))
    with pytest.raises(ValueError, match="cylinder length must be"):
        robots.Robot.from_urdf(_urdf(tmp_path, '<cylinder radius="0.1" length="-0.2"/>'))
    robot = robots.Robot.from_urdf(_urdf(tmp_path, '<sphere radius="0.05"/>'))
    assert robot.collision_meshes("base").bounding_sphere.primitive.radius == pytest.approx(0.05, rel=0.05)


def test_urdf_inverted_joint_limits_are_refused(tmp_path):
    with pytest.raises(ValueError, match=r"joint 'j' has limits lower 1\.0+ > upper -1\.0+"):
        robots.Robot.from_urdf(_urdf(tmp_path, lower=1.0, upper=-1.0))
    locked = robots.Robot.from_urdf(_urdf(tmp_path, lower=0.5, upper=0.5))  # equal: a locked joint
    assert locked.lower_limits[0] == locked.upper_limits[0] == 0.5


def test_link_index_2_pow_32_plus_3_is_out_of_range_not_link_3(panda):
    q = panda.ready_configuration
    huge = 2**32 + 3
    with pytest.raises(ValueError, match="out of range"):
        panda.jacobian(q, huge)
    with pytest.raises(ValueError, match="out of range"):
        panda.native.jacobian(q, huge, None)
    with pytest.raises(ValueError, match=r"link index 4294967299 out of range"):
        panda.link_pose(q, huge)
    body = robots.BodyPoints(np.array([huge], np.int64), np.zeros((1, 3)), np.array([[0, 0, 1.0]]))
    with pytest.raises(ValueError, match=r"link index 4294967299 out of range \[0, 13\)"):
        panda.transform_points(q[None], body)
    np.testing.assert_allclose(panda.jacobian(q, 3), panda.jacobian(q, "panda_link3"))


# --- poses ------------------------------------------------------------------------------------------
def test_rigidity_cleaning_passes_float32_data_and_rejects_real_errors():
    T = np.stack([_rotated(a) for a in np.linspace(0.1, 3.0, 20)])
    noisy = T.astype(np.float32).astype(float)  # how stored grasp sets are off: ~1e-7 .. 1e-6
    noisy[:, :3, :3] *= 1 + 1.5e-6
    clean = clean_poses(noisy)
    R = clean[:, :3, :3]
    assert np.abs(R @ R.transpose(0, 2, 1) - np.eye(3)).max() < 1e-14
    assert np.abs(clean - T).max() < 1e-5  # projected, not moved
    exact = clean_poses(T)
    assert np.array_equal(exact, T)  # rigid to double precision: left bit-identical
    skewed = T.copy()
    skewed[7, :3, :3] *= 1 + 10 * RIGID_CLEAN_TOLERANCE
    with pytest.raises(ValueError, match=r"grasps: pose 7 is not a rigid transform .*1 of 20 bad"):
        clean_poses(skewed, "grasps")


def test_bindings_rigidity_check_uses_the_same_tolerance(panda):
    T = _rotated()
    T[:3, :3] *= 1 + 2e-6  # rejected by the old 1e-6 check
    moved = panda.with_base(T)
    R = moved.base_pose[:3, :3]
    assert np.abs(R @ R.T - np.eye(3)).max() < 1e-12
    T[:3, :3] *= 1 + 10 * RIGID_CLEAN_TOLERANCE
    with pytest.raises(ValueError, match="not a rigid transform"):
        panda.with_base(T)


def test_graspit_grasps_of_the_shared_ycb_objects_load_and_give_goals(panda):
    """`pickplan plan --grasps graspit` failed: 'not a rigid transform (orthonormality error 1.0e-06)'."""
    from pickplan.core import objects
    from pickplan.core.ik import IkSettings  # noqa: F401
    from pickplan.omg.goals import GoalSetSettings, build_goal_set  # noqa: F401
    from pickplan.omg.planner import OMGPlanner, OMGSettings

    lib = objects.library(ycb_dir_or_skip())
    model = next(lib.get(n) for n in lib.names if "graspit" in lib.get(n).grasps)
    stored = np.asarray(model.grasps["graspit"], dtype=float)
    R = stored[:, :3, :3]
    assert np.abs(R @ R.transpose(0, 2, 1) - np.eye(3)).max() > 1e-7  # the data is only float-rigid
    gs = G.grasp_set(model, "graspit")
    assert len(gs) == len(stored)
    scene = scenes.generate_scene(seed=3, library=lib)
    settings = OMGSettings(grasp_kind="graspit", iterations=10)
    result = OMGPlanner(None, scene, settings).plan()  # raised ValueError before the fix
    assert result.status in ("success", "in_collision", "not_smooth", "no_goals")
    assert np.all(np.isfinite(result.trajectory))


# --- meshes and the SDF cache -----------------------------------------------------------------------
def test_degenerate_zero_volume_collision_mesh_is_refused(panda):
    flat = trimesh.Trimesh(
        vertices=[[0, 0, 0], [0.1, 0, 0], [0, 0.1, 0], [0.1, 0.1, 0]], faces=[[0, 1, 2], [1, 3, 2]], process=False
    )
    with pytest.raises(InputError, match="object 'plate': degenerate mesh: it encloses no volume"):
        CollisionChecker(panda, [SceneMesh("plate", flat, np.eye(4))])
    with pytest.raises(InputError, match="degenerate mesh"):
        sdf.mesh_sdf(flat, sdf.SdfSettings(cache_dir=""))


def test_empty_collision_mesh_is_refused(panda):
    empty = trimesh.Trimesh(vertices=np.zeros((0, 3)), faces=np.zeros((0, 3), int), process=False)
    with pytest.raises(InputError, match="object 'nothing': empty mesh"):
        CollisionChecker(panda, [SceneMesh("nothing", empty, np.eye(4))])
    with pytest.raises(InputError, match="empty mesh"):
        sdf.mesh_sdf(empty, sdf.SdfSettings(cache_dir=""))


def test_mesh_face_index_2_pow_32_plus_3_is_refused_not_wrapped(panda):
    box = trimesh.creation.box(extents=[0.1, 0.1, 0.1])
    F = np.asarray(box.faces, dtype=np.int64)
    F[0, 0] = 2**32 + 3  # int32 narrowing would turn this into vertex 3
    bad = trimesh.Trimesh(vertices=box.vertices, faces=box.faces, process=False)
    with pytest.raises(InputError, match="face index out of range"):
        CollisionChecker(panda, [SceneMesh("box", type("M", (), {"vertices": bad.vertices, "faces": F})(), np.eye(4))])


def _cache_entry(tmp_path, mesh, settings):
    grid = sdf.mesh_sdf(mesh, settings)
    (entry,) = list((tmp_path / "sdf").iterdir())
    return grid, str(entry)


def _rewrite(path, **changes):
    with np.load(path) as z:
        data = {k: z[k] for k in z.files}
    data.update(changes)
    with open(path, "wb") as f:
        np.savez(f, **data)


@pytest.mark.parametrize(
    "damage",
    [
        "nan_values_with_a_matching_checksum",
        "inf_values",
        "checksum_mismatch",
        "truncated_file",
        "other_code_version",
        "old_format_without_checksum",
    ],
)
def test_sdf_cache_damaged_entry_is_rebuilt_with_a_warning_never_used(tmp_path, damage):
    mesh = trimesh.creation.box(extents=[0.06, 0.08, 0.1])
    settings = sdf.SdfSettings(resolution=0.01, margin=0.05, cache_dir=str(tmp_path))
    fresh, path = _cache_entry(tmp_path, mesh, settings)
    truth = np.asarray(fresh.values).copy()
    with np.load(path) as z:
        values, origin, resolution = z["values"].copy(), z["origin"], z["resolution"]
    if damage == "nan_values_with_a_matching_checksum":
        values[values.size // 2 if values.ndim == 1 else 0] = np.nan
        _rewrite(path, values=values, checksum=sdf._checksum(origin, resolution, values))
    elif damage == "inf_values":
        values.flat[:10] = np.inf
        _rewrite(path, values=values, checksum=sdf._checksum(origin, resolution, values))
    elif damage == "checksum_mismatch":
        values.flat[3] += 0.05  # a flipped bit on disk: plausible numbers, wrong checksum
        _rewrite(path, values=values)
    elif damage == "truncated_file":
        data = open(path, "rb").read()
        open(path, "wb").write(data[: len(data) // 2])
    elif damage == "other_code_version":
        _rewrite(path, code_version=np.array("0.0.0-other"))
    else:
        with open(path, "wb") as f:
            np.savez(f, origin=origin, resolution=resolution, values=values)
    with pytest.warns(UserWarning, match="rebuilding SDF cache entry"):
        grid = sdf.mesh_sdf(mesh, settings)
    np.testing.assert_array_equal(np.asarray(grid.values), truth)
    with warnings.catch_warnings():  # the rebuilt entry is whole again
        warnings.simplefilter("error")
        again = sdf.mesh_sdf(mesh, settings)
    np.testing.assert_array_equal(np.asarray(again.values), truth)


# --- scenes -----------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def scene_dict():
    return scenes.generate_scene(seed=2).to_dict()


def _moved(d, dz):
    d = json.loads(json.dumps(d))
    d["objects"][0]["pose"][2][3] += dz
    return d


def test_object_3cm_into_the_table_is_refused(scene_dict):
    with pytest.raises(
        ValueError, match=r"objects\[0\]\.pose: object .* reaches (2\.[5-9]|3\.[0-4]) cm below the table top"
    ):
        scenes.Scene.from_dict(_moved(scene_dict, -0.03))
    scenes.Scene.from_dict(_moved(scene_dict, -0.002))  # settling contact depth: accepted


def test_object_50cm_under_the_table_is_refused(scene_dict):
    with pytest.raises(ValueError, match=r"objects\[0\]\.pose: .* (49|50)\.\d cm below the table top"):
        scenes.Scene.from_dict(_moved(scene_dict, -0.5))


def test_scene_poses_given_as_strings_are_refused(scene_dict):
    d = json.loads(json.dumps(scene_dict))
    d["objects"][1]["pose"] = [[str(v) for v in row] for row in d["objects"][1]["pose"]]
    with pytest.raises(
        ValueError,
        match=r"objects\[1\]\.pose: expected numbers, got str '1\.0'|objects\[1\]\.pose: expected numbers, got str",
    ):
        scenes.Scene.from_dict(d)
    d = json.loads(json.dumps(scene_dict))
    d["robot_base"] = json.dumps(d["robot_base"])
    with pytest.raises(ValueError, match="robot_base: expected numbers, got str"):
        scenes.Scene.from_dict(d)
    d = json.loads(json.dumps(scene_dict))
    d["table"]["size"] = [True, 1.0, 0.05]
    with pytest.raises(ValueError, match="table.size: expected numbers, got bool"):
        scenes.Scene.from_dict(d)


def test_robot_configuration_of_5_is_a_clear_error(scene_dict):
    d = json.loads(json.dumps(scene_dict))
    d["robot_configuration"] = 5
    with pytest.raises(ValueError, match="robot_configuration: expected a list of joint values, got int 5"):
        scenes.Scene.from_dict(d)


def test_deeply_nested_json_is_a_clear_error(tmp_path):
    nested = "[" * 100_000 + "]" * 100_000
    with pytest.raises(ValueError, match="nested too deeply"):
        scenes.Scene.from_json(nested)
    path = tmp_path / "deep.json"
    path.write_text(nested)
    with pytest.raises(InputError, match=r"deep\.json: malformed scene JSON: nested too deeply"):
        scenes.Scene.load(str(path))
    with pytest.raises(InputError, match="nested too deeply"):
        read_json(str(path))


# --- meta-model files -------------------------------------------------------------------------------
def _metamodel():
    from pickplan.pickup.metamodel.model import FORMAT, VERSION

    lv = {
        "name": "low",
        "sigma_r": 0.002,
        "sigma_phi": 0.087,
        "rho_grid": [[0.9, 0.8], [0.7, 0.6]],
        "surface": {"coeffs": [[0.9, 0.8], [0.7, 0.6]], "sg_range": [0.1, 1.0], "sc_range": [0.05, 0.15]},
    }
    b = {
        "i": 0,
        "j": 0,
        "s_g": 0.1,
        "s_c": 0.05,
        "X": [[0.1, 0.2, 0.3], [0.0, -0.1, 0.5]],
        "y": [1, 0],
        "simulated": [1, 1],
        "svm_c": 10.0,
        "svm_gamma": 2.0,
    }
    return {
        "format": FORMAT,
        "version": VERSION,
        "part": "box",
        "sg_grid": [0.1, 1.0],
        "sc_grid": [0.05, 0.15],
        "domain": {"r_max": 0.05, "phi_max": 1.0},
        "n_queries": 100,
        "surface_degree": [3, 2],
        "lapse": 0.01,
        "levels": [lv],
        "boundaries": [b],
    }


def test_metamodel_validation_constants_match_the_reader():
    from pickplan.pickup.metamodel import model, validate

    assert validate.FORMAT == model.FORMAT and validate.READABLE_VERSIONS == model.READABLE_VERSIONS


def test_nan_sigma_r_in_a_metamodel_is_refused():
    from pickplan.pickup.metamodel.validate import validate_metamodel

    d = _metamodel()
    assert validate_metamodel(d, "m.json") is d
    d["levels"][0]["sigma_r"] = float("nan")
    with pytest.raises(InputError, match=r"m\.json: levels\[0\]\.sigma_r: expected a finite number, got nan"):
        validate_metamodel(d, "m.json")


@pytest.mark.parametrize(
    "mutate, message",
    [
        (lambda d: [d], r"\(top level\): expected an object \(a table of keys\), got list"),
        (lambda d: {**d, "n_queries": "100"}, r"n_queries: expected an integer, got str"),
        (lambda d: {**d, "sg_grid": [0.1, "1.0"]}, r"sg_grid: expected numbers, got str"),
        (lambda d: {**d, "lapse": 1.5}, r"lapse: 1\.5 is outside \[0\.0, 1\.0\]"),
        (lambda d: {**d, "boundaries": [{**d["boundaries"][0], "y": [1]}]}, r"boundaries\[0\]\.y: expected 2 labels"),
        (
            lambda d: {**d, "levels": [{**d["levels"][0], "rho_grid": [[0.5, 2.0], [0.1, 0.1]]}]},
            r"levels\[0\]\.rho_grid: values must lie in \[0\.0, 1\.0\]",
        ),
    ],
)
def test_metamodel_wrong_types_and_ranges_name_the_field(mutate, message):
    from pickplan.pickup.metamodel.validate import validate_metamodel

    with pytest.raises(InputError, match=message):
        validate_metamodel(mutate(_metamodel()), "m.json")


# --- settings ---------------------------------------------------------------------------------------
def test_check_every_0_is_a_clear_error_not_zero_division():
    from pickplan.omg.planner import OMGSettings

    with pytest.raises(ValueError, match="OMGSettings.check_every: expected an integer >= 1, got 0"):
        OMGSettings(check_every=0)


def test_object_mesh_that_is_not_watertight_loads_from_its_convex_hull(tmp_path):
    """Found by the fuzz suite: trimesh's convex hull of an open mesh needs networkx, which was not
    a dependency (ModuleNotFoundError for any object folder whose mesh has a hole)."""
    from pickplan.core import objects

    box = trimesh.creation.box(extents=[0.05, 0.04, 0.1])
    open_box = trimesh.Trimesh(box.vertices, box.faces[:-1], process=False)
    folder = tmp_path / "open_box"
    folder.mkdir()
    open_box.export(str(folder / "mesh.stl"))
    with pytest.warns(UserWarning, match="not watertight"):
        model = objects.load_ycb_object(str(folder))
    assert model.mass > 0 and np.all(np.isfinite(model.com))
    np.testing.assert_allclose(model.com, box.center_mass, atol=1e-9)  # the hull is the full box


def test_grasp_array_with_a_broken_npy_header_is_a_clear_error(tmp_path):
    """Found by the fuzz suite: numpy parses the .npy header with the tokenizer, and a damaged
    header escaped as tokenize.TokenError."""
    import io

    from pickplan.core.objects import read_grasp_array

    buf = io.BytesIO()
    np.save(buf, np.tile(np.eye(4), (3, 1, 1)))
    data = buf.getvalue().replace(b"(3, 4, 4)", b"(3, 4, 4 ")
    path = tmp_path / "grasps_graspit.npy"
    path.write_bytes(data)
    with pytest.raises(ValueError, match=r"grasps_graspit\.npy: not a readable \.npy grasp array \(TokenError"):
        read_grasp_array(str(path))
    path.write_bytes(buf.getvalue())
    assert read_grasp_array(str(path)).shape == (3, 4, 4)


def test_mesh_43_km_across_is_refused_before_building_its_sdf():
    """Found by the fuzz suite: one corrupt vertex at 42,949 m made the SDF builder run for minutes
    (a hang past the time limit); at 4.3e9 m it would exhaust memory."""
    box = trimesh.creation.box(extents=[0.05, 0.04, 0.1])
    V = np.asarray(box.vertices).copy()
    V[0, 0] = 42949.0
    far = trimesh.Trimesh(V, box.faces, process=False)
    with pytest.raises(InputError, match=r"mesh: mesh is \[42949\.\d+, 0\.04, 0\.1\] m across: its SDF grid"):
        sdf.mesh_sdf(far, sdf.SdfSettings(cache_dir=""))
    grid = sdf.mesh_sdf(box, sdf.SdfSettings(resolution=0.01, margin=0.05, cache_dir=""))
    assert np.asarray(grid.values).size < sdf.MAX_GRID_CELLS
