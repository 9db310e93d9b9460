import os

import numpy as np
import pytest

YCB_DIR = os.environ.get("PICKPLAN_YCB_DIR",
                         os.path.join(os.path.dirname(__file__), "..", "..", "..", "shared", "data", "ycb"))


@pytest.fixture(scope="session")
def panda():
    import pickplan.core.robots

    return pickplan.robots.panda()


@pytest.fixture
def bullet():
    """A private PyBullet DIRECT client, disconnected afterwards."""
    import pybullet as pb

    cid = pb.connect(pb.DIRECT)
    try:
        yield cid
    finally:
        pb.disconnect(cid)


def ycb_dir_or_skip():
    path = os.path.abspath(YCB_DIR)
    if not os.path.isdir(path):
        pytest.skip(f"YCB data folder not found at {path} (set PICKPLAN_YCB_DIR); real-object checks skipped")
    return path


def rng(seed=0):
    return np.random.default_rng(seed)


def pytest_configure(config):
    config.addinivalue_line("markers", "ray: starts a local Ray cluster (slow to start); CI runs these, "
                                       "`-m 'not ray'` leaves them out of a quick local run")
