"""Scene families beyond the tabletop (sim.layouts): objects stand exactly on their boards, inside the
furniture, named once (picks from them, planned and executed: test_shelf_picks.py)."""

import numpy as np
import pytest

from pickplan.core import objects
from pickplan.sim.layouts import Layout, generate_layout


@pytest.fixture(scope="module")
def lib():
    return objects.library("builtin")


SEEDS = {Layout.shelf: 3, Layout.bin: 5}


@pytest.fixture(scope="module")
def layouts(lib):
    return {kind: generate_layout(kind, seed=seed, library=lib) for kind, seed in SEEDS.items()}


def board_top(pose, size):
    """World height of a horizontal board's top face (its frame's z up)."""
    return float(pose[2, 3] + 0.5 * size[2] * pose[2, 2])


@pytest.mark.parametrize("kind", [Layout.shelf, Layout.bin])
def test_objects_stand_on_their_board_inside_the_furniture(kind, lib, layouts):
    scene = layouts[kind]
    names = [o.name for o in scene.objects]
    assert len(names) == len(set(names)) >= 2 and scene.target in names and scene.obstacles
    supports = [(np.asarray(scene.table.pose), np.asarray(scene.table.size))] + [
        (np.asarray(o.pose), np.asarray(o.shape.size)) for o in scene.obstacles if o.support
    ]
    tops = [board_top(T, s) for T, s in supports]
    for o in scene.objects:
        V = np.asarray(lib.get(o.name).mesh.vertices) @ o.pose[:3, :3].T + o.pose[:3, 3]
        low = V[:, 2].min()
        # resting exactly on one support's top face, within that board's footprint
        k = int(np.argmin([abs(low - t) for t in tops]))
        assert abs(low - tops[k]) < 1e-6, (o.name, low, tops)
        local = (V.mean(axis=0) - supports[k][0][:3, 3]) @ supports[k][0][:3, :3]
        assert np.all(np.abs(local[:2]) < 0.5 * supports[k][1][:2])
        # and clear of every wall and board (primitive boxes, exact distances)
        for ob in scene.obstacles:
            p = (V - ob.pose[:3, 3]) @ ob.pose[:3, :3]
            inside = np.all(np.abs(p) < 0.5 * np.asarray(ob.shape.size) - 1e-6, axis=1)
            assert not inside.any(), (o.name, ob.name)
    assert (
        generate_layout(kind, seed=SEEDS[kind], library=lib).objects[0].pose.tolist() == scene.objects[0].pose.tolist()
    )
