import os

import numpy as np
import pytest

YCB_DIR = os.environ.get(
    "PICKPLAN_YCB_DIR", os.path.join(os.path.dirname(__file__), "..", "..", "..", "shared", "data", "ycb")
)

MBM_DIR = os.environ.get(
    "PICKPLAN_MBM_DIR", os.path.join(os.path.dirname(__file__), "..", "..", "..", "shared", "data", "mbm")
)


@pytest.fixture(scope="session")
def panda():
    from pickplan.core import robots

    return robots.panda()


@pytest.fixture
def bullet():
    """A private PyBullet DIRECT client, disconnected afterwards."""
    import pybullet as pb

    cid = pb.connect(pb.DIRECT)
    try:
        yield cid
    finally:
        pb.disconnect(cid)


def in_ci() -> bool:
    """CI (``CI=true``) has the shared data: there, a missing folder is a failure, not a skip."""
    return os.environ.get("CI", "").strip().lower() in ("true", "1", "yes")


def ycb_dir_or_none():
    """The YCB data folder; None where it is absent (a user's machine); absent in CI: the test fails."""
    path = os.path.abspath(YCB_DIR)
    if os.path.isdir(path):
        return path
    if in_ci():
        pytest.fail(f"YCB data folder not found at {path}: CI must have it (set PICKPLAN_YCB_DIR)")
    return None


def ycb_dir_or_skip():
    path = ycb_dir_or_none()
    if path is None:
        pytest.skip(
            f"YCB data folder not found at {os.path.abspath(YCB_DIR)} (set PICKPLAN_YCB_DIR); "
            "real-object checks skipped"
        )
    return path


def mbm_dir_or_skip():
    """The MotionBenchMaker data folder; a skip where it is absent, a failure in CI (as for YCB)."""
    path = os.path.abspath(MBM_DIR)
    if not os.path.isfile(os.path.join(path, "problems_panda.tar.bz2")):
        if in_ci():
            pytest.fail(f"MotionBenchMaker data not found at {path}: CI must have it (set PICKPLAN_MBM_DIR)")
        pytest.skip(f"MotionBenchMaker data not found at {path} (set PICKPLAN_MBM_DIR); MBM checks skipped")
    return path


def rng(seed=0):
    return np.random.default_rng(seed)


def pytest_configure(config):
    config.addinivalue_line(
        "markers",
        "ray: starts a local Ray cluster (slow to start); CI runs these, "
        "`-m 'not ray'` leaves them out of a quick local run",
    )


def standing_pose(model, xy):
    """``model``'s most upright resting pose, moved to ``xy`` on the table."""
    T = model.resting_poses[int(np.argmax([p[2, 2] for p in model.resting_poses]))].copy()
    T[:2, 3] += xy
    return T


def standing_scene(placements, target):
    """A scene of built-in objects standing upright at (name, xy) placements, and the library."""
    from pickplan.core import objects
    from pickplan.sim import scenes

    lib = objects.library("builtin")
    objs = [scenes.SceneObject(name, f"builtin:{name}", standing_pose(lib.get(name), xy)) for name, xy in placements]
    return scenes.Scene(np.eye(4), scenes.default_table(), objs, target, seed=0), lib


def known_scene():
    """A sugar box (the target) standing in front of the robot and a soup can beside it (built-ins),
    with the object library: the perception tests' known scene."""
    return standing_scene((("004_sugar_box", (0.55, 0.0)), ("005_tomato_soup_can", (0.55, 0.2))), "004_sugar_box")


def socket_inodes(pid: int) -> set:
    """The inodes of process ``pid``'s sockets (its /proc fd links), to find them in /proc/net's tables."""
    inodes = set()
    for fd in os.listdir(f"/proc/{pid}/fd"):
        try:
            link = os.readlink(f"/proc/{pid}/fd/{fd}")
        except OSError:
            continue
        if link.startswith("socket:["):
            inodes.add(link[8:-1])
    return inodes
