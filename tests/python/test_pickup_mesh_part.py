"""A user's own part from a closed mesh (issue 23): validation of the mesh, the part's mass and grasp
from exact geometry, a simulated grasp, and `pickplan metamodel build --part` (quick setting)."""

import math

import numpy as np
import pytest
import trimesh

from pickplan.cli.main import main as cli_main
from pickplan.core.errors import InputError
from pickplan.pickup.metamodel.mesh_part import part_from_mesh
from pickplan.pickup.metamodel.model import MetaModel
from pickplan.pickup.metamodel.sim import simulate_grasp
from pickplan.pickup.nlp import planner

# A regular pentagon of circumradius R extruded by H, lifted off the origin (the loader rests it).
R, H = 0.018, 0.045


def pentagon_prism(path, radius=R, height=H):
    angles = np.arange(5) * 2 * math.pi / 5
    ring = np.c_[radius * np.cos(angles), radius * np.sin(angles)]
    points = np.r_[np.c_[ring, np.zeros(5)], np.c_[ring, np.full(5, height)]]
    mesh = trimesh.convex.convex_hull(points)  # the prism is convex: its hull is the prism
    mesh.apply_translation([0.3, -0.2, 0.1])
    mesh.export(path)
    return mesh


def test_a_mesh_part_has_the_exact_mass_and_a_grasp_across_its_narrow_side(tmp_path):
    path = str(tmp_path / "pentagon.stl")
    pentagon_prism(path)
    part = part_from_mesh(path, density=800.0, friction=0.7)
    area = 5 / 2 * R * R * math.sin(2 * math.pi / 5)  # closed form of the pentagon's area
    assert part.mass == pytest.approx(800.0 * area * H, rel=1e-5)  # STL stores float32 vertices
    assert part.height == pytest.approx(H, rel=1e-5) and part.lateral_friction == 0.7
    # x extent R (1 + cos 36 deg), y extent 2 R sin 72 deg: x is narrower, so grasp across x.
    assert part.strategy.grasp_width == pytest.approx(R * (1 + math.cos(math.pi / 5)), rel=1e-5)
    assert part.strategy.tcp_yaw == pytest.approx(math.pi / 2)
    hull = np.asarray(part.shapes[0].size)
    assert hull[:, 2].min() == pytest.approx(0.0, abs=1e-12)  # rests on the table
    assert part.footprint_radius == pytest.approx(np.max(np.hypot(hull[:, 0], hull[:, 1])))
    assert part_from_mesh(path, mass=0.2).mass == 0.2


def test_a_mesh_part_is_grasped_in_simulation(tmp_path):
    path = str(tmp_path / "pentagon.obj")
    pentagon_prism(path)
    part = part_from_mesh(path, mass=0.1)
    assert simulate_grasp(part, [0.0, 0.0, 0.0], 0.1, 0.15, seed=0).success
    missed = simulate_grasp(part, [0.0, 0.06, 0.0], 0.1, 0.15, seed=0)  # 6 cm aside: between no fingers
    assert not missed.success and missed.reason == "missed"


def test_bad_meshes_are_named(tmp_path):
    mesh = trimesh.creation.box(extents=[0.03, 0.05, 0.04])
    open_mesh = trimesh.Trimesh(mesh.vertices, mesh.faces[:-2])
    open_mesh.export(tmp_path / "open.stl")
    with pytest.raises(InputError, match="open.stl: mesh: not closed"):
        part_from_mesh(str(tmp_path / "open.stl"), mass=0.1)
    inverted = mesh.copy()
    inverted.invert()
    inverted.export(tmp_path / "inverted.obj")
    with pytest.raises(InputError, match="volume .* is not positive"):
        part_from_mesh(str(tmp_path / "inverted.obj"), mass=0.1)
    trimesh.creation.box(extents=[0.2, 0.3, 0.1]).export(tmp_path / "wide.stl")
    with pytest.raises(InputError, match="does not fit between the open fingers"):
        part_from_mesh(str(tmp_path / "wide.stl"), mass=0.1)
    trimesh.creation.box(extents=[30, 50, 40]).export(tmp_path / "millimetres.stl")
    with pytest.raises(InputError, match="must be in metres"):
        part_from_mesh(str(tmp_path / "millimetres.stl"), mass=0.1)
    mesh.export(tmp_path / "ok.stl")
    with pytest.raises(InputError, match="exactly one of mass and density"):
        part_from_mesh(str(tmp_path / "ok.stl"), mass=0.1, density=500)
    with pytest.raises(InputError, match="--density: expected a positive finite number"):
        part_from_mesh(str(tmp_path / "ok.stl"), density=-5)
    (tmp_path / "junk.stl").write_bytes(b"solid nothing\nendsolid\n")
    with pytest.raises(InputError, match="junk.stl"):
        part_from_mesh(str(tmp_path / "junk.stl"), mass=0.1)
    with pytest.raises(FileNotFoundError):
        part_from_mesh(str(tmp_path / "none.stl"), mass=0.1)


def test_metamodel_build_for_a_user_mesh_quick(tmp_path, capsys):
    path = str(tmp_path / "pentagon.stl")
    pentagon_prism(path)
    out = tmp_path / "mm"
    assert (
        cli_main(["metamodel", "build", "--part", path, "--density", "800", "--smoke", "--out", str(out), "--quiet"])
        == 0
    )
    mm = MetaModel.load(str(out / "metamodel_pentagon.json"))
    assert mm.part_name == "pentagon" and (out / "pentagon_rho.md").exists()
    for level in mm.levels:
        rho = planner.load_rho(str(out / "metamodel_pentagon.json"), level.sigma_r, level.sigma_phi)
        values = [rho.value(sg, sc) for sg in np.linspace(*rho.sg_range, 5) for sc in np.linspace(*rho.sc_range, 3)]
        assert all(0.0 <= v <= 1.0 for v in values)
    # Slow grasps of a part this size succeed more often than fast ones at low uncertainty.
    low = planner.load_rho(str(out / "metamodel_pentagon.json"), *[(lv.sigma_r, lv.sigma_phi) for lv in mm.levels][0])
    assert low.value(0.1, 0.15) >= low.value(0.5, 0.05)
    assert cli_main(["metamodel", "build", "--density", "800", "--out", str(out)]) == 2
    assert "give --part MESH" in capsys.readouterr().err
