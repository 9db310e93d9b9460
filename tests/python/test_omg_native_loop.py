"""Issue 24: Algorithm 2's loop in C++ plans what the Python loop plans. The native selection
policies against omg.selection's (the research reference) on random inputs, and whole plans of the
native loop against the Python loop (the oracle in omg_reference_loop.py): same goals chosen at
every iteration, same grasp and goal, trajectories equal to 1e-9, on several scenes, every policy,
with and without ISF and pre-termination."""

import json
import os
import threading
import zlib

import numpy as np
import pytest

from pickplan import _core
from pickplan.omg import planner as omg
from pickplan.omg import selection
from pickplan.omg.chomp import Chomp
from pickplan.omg.model_cache import ModelCache
from pickplan.omg.goals import build_goal_set
from pickplan.omg.native_loop import native_policy, run_native
from pickplan.omg.world import World
from pickplan.sim.scenes import Scene

from omg_reference_loop import ReferencePlanner

REFERENCE = os.path.join(os.path.dirname(__file__), "..", "data", "omg_reference.npz")
POLICIES = [s.value for s in selection.Selection]


def _python_policies():
    yield from (selection.make_policy(name) for name in POLICIES)
    yield selection.EXP(eta=0.7)
    yield selection.MirrorDescent(exponents=(-1, 1, 3), shift=0.02)
    yield selection.MirrorDescent(exponents=(0,), shift=0.0)


@pytest.mark.parametrize("policy", list(_python_policies()), ids=lambda p: f"{p.name}")
def test_native_policy_updates_equal_the_python_policy(policy):
    """Random goal counts, horizons and normalized cost vectors, with goals joining (ISF's refined
    copies) at random iterations: the same distribution after every update and add_goal (to
    round-off: exp and log may differ in the last bit) and the same selected goal."""
    rng = np.random.default_rng(zlib.crc32(policy.name.encode()))  # the same draws in every process
    native = native_policy(policy)
    assert native.kind.name == selection.Selection.parse(policy.name).name
    for trial in range(25):
        goals, horizon = int(rng.integers(1, 40)), int(rng.integers(1, 60))
        c0 = rng.uniform(size=goals)
        policy.reset(goals, horizon, c0)
        native.reset(goals, horizon, c0)
        np.testing.assert_allclose(native.p, policy.p, rtol=0, atol=1e-12)
        for i in range(horizon):
            if rng.uniform() < 0.15:
                policy.add_goal()
                native.add_goal()
                np.testing.assert_allclose(native.p, policy.p, rtol=0, atol=1e-12)
            c = rng.uniform(size=len(policy.p)) * rng.choice([1e-3, 1.0, 30.0])
            c /= np.linalg.norm(c)
            np.testing.assert_allclose(native.update(c), policy.update(c), rtol=0, atol=1e-12)
            assert native.select() == policy.select()
        assert native.regret() == pytest.approx(policy.regret(), rel=1e-9, abs=1e-12)


def test_native_policy_rejects_bad_costs():
    native = native_policy("MD")
    with pytest.raises(RuntimeError, match="before reset"):
        native.update(np.ones(3))
    native.reset(3, 10)
    with pytest.raises(ValueError, match="expected 3 entries"):
        native.update(np.ones(4))
    with pytest.raises(ValueError, match="finite"):
        native.update(np.array([0.1, np.nan, 0.2]))
    with pytest.raises(ValueError, match="at least one goal"):
        native.reset(0, 10)
    with pytest.raises(ValueError, match="unknown selection policy"):
        native_policy("greedy")


@pytest.fixture(scope="module")
def reference_cases():
    """The five built-in scenes of the issue-24 reference (switches, ISF refinements, plans that run
    all 50 iterations) with their stored grasps, worlds sharing one cache."""
    with np.load(REFERENCE, allow_pickle=False) as z:
        ref = {k: z[k] for k in z.files}
    cache = ModelCache()
    out = []
    for prefix in ("s1", "s2", "s3", "s4full"):
        scene = Scene.from_dict(json.loads(str(ref[prefix + "_scene"])))
        out.append((prefix, scene, World(scene, omg.OMGSettings().world, cache=cache), ref[prefix + "_grasps"]))
    return out


def _plan(scene, world, grasps, settings, planner=omg.OMGPlanner):
    return planner(None, scene, settings, world=world).plan(grasps=grasps)


def _check_same(python, native):
    assert native.status == python.status
    assert native.history["goal"] == python.history["goal"]  # the same goal chosen at every iteration
    assert (native.grasp_index, native.goal_source, native.refined, native.iterations, native.goal_set_size) == (
        python.grasp_index,
        python.goal_source,
        python.refined,
        python.iterations,
        python.goal_set_size,
    )
    assert (native.history["switches"], native.history["initial_grasp"]) == (
        python.history["switches"],
        python.history["initial_grasp"],
    )
    np.testing.assert_allclose(native.trajectory, python.trajectory, rtol=0, atol=1e-9)
    np.testing.assert_allclose(native.history["objective"], python.history["objective"], rtol=1e-12)
    for cn, cp in zip(native.history["costs"], python.history["costs"]):
        np.testing.assert_allclose(cn, cp, rtol=0, atol=1e-12)
    for pn, pp in zip(native.history["p"], python.history["p"]):
        np.testing.assert_allclose(pn, pp, rtol=0, atol=1e-12)
    for key in ("smoothness", "collision", "min_clearance", "min_table_clearance"):
        assert getattr(native.metrics, key) == pytest.approx(getattr(python.metrics, key), rel=1e-9, abs=1e-12)
    assert native.grasp_cost == pytest.approx(python.grasp_cost, rel=1e-9, nan_ok=True)
    np.testing.assert_allclose(native.hand_pose, python.hand_pose, rtol=0, atol=1e-12)


@pytest.mark.parametrize("policy", POLICIES)
def test_native_loop_plans_what_the_python_loop_plans(reference_cases, policy):
    seen = {"switches": 0, "grown": 0, "full": 0}
    for prefix, scene, world, grasps in reference_cases:
        for refine, pre_terminate in ((True, True), (True, False), (False, False)):
            settings = omg.OMGSettings(selection=policy, refine=refine, pre_terminate=pre_terminate)
            python = _plan(scene, world, grasps, settings, ReferencePlanner)
            native = _plan(scene, world, grasps, settings)  # the library's loop is the native one
            _check_same(python, native)
            seen["switches"] += python.history["switches"]
            seen["grown"] += python.goal_set_size > len(python.goal_set)
            seen["full"] += python.iterations == settings.iterations
    # the cases exercise what could differ: switches, refined goals joining the set, full runs
    assert seen["grown"] > 0 and seen["full"] > 0
    if policy != "Fixed":
        assert seen["switches"] > 0


def test_native_loop_runs_beside_other_threads(reference_cases):
    """The loop releases the GIL: plans on two threads give the single-thread plans."""
    _, scene, world, grasps = reference_cases[1]
    settings = omg.OMGSettings()
    alone = _plan(scene, world, grasps, settings)
    results = [None, None]

    def run(k):
        results[k] = _plan(scene, world, grasps, settings)

    threads = [threading.Thread(target=run, args=(k,)) for k in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for r in results:
        assert r.history["goal"] == alone.history["goal"]
        np.testing.assert_array_equal(r.trajectory, alone.trajectory)


def test_native_loop_rejects_bad_input(reference_cases):
    _, scene, world, grasps = reference_cases[0]
    chomp = Chomp(world.robot, world.sdf, world.body)
    q0 = world.start
    goals = np.tile(q0, (2, 1))
    tails = np.tile(q0, (2, 5, 1))
    blend = np.linspace(0.1, 1.0, chomp.settings.n)
    args = (chomp.problem, None, world.robot.hand_link, q0)
    with pytest.raises(ValueError, match="tails"):
        _core.run_omg_loop(*args, goals, tails[:1], [0, 1], blend, _core.OmgLoopSettings())
    with pytest.raises(ValueError, match="grasp_index"):
        _core.run_omg_loop(*args, goals, tails, [0], blend, _core.OmgLoopSettings())
    with pytest.raises(ValueError, match="blend"):
        _core.run_omg_loop(*args, goals, tails, [0, 1], blend[:-1], _core.OmgLoopSettings())
    with pytest.raises(ValueError, match="goals"):
        _core.run_omg_loop(*args, goals[:, :3], tails, [0, 1], blend, _core.OmgLoopSettings())
    bad = _core.OmgLoopSettings()
    bad.check_every = 0
    with pytest.raises(ValueError, match="check_every"):
        _core.run_omg_loop(*args, goals, tails, [0, 1], blend, bad)


def test_native_loop_stops_early_only_on_plans_the_check_passes(reference_cases):
    """``check`` (the exact test among furniture, ``omg.furniture_check.LoopCheck``) is asked only about
    plans the metrics pass, at the pre-termination checks; the loop stops on the first it accepts and returns
    that plan, and runs to the horizon when it accepts none."""
    _, scene, world, grasps = reference_cases[1]
    settings = omg.OMGSettings()
    gs = build_goal_set(world, grasps, world.start, settings.goals, settings.ik)
    parts = omg.LoopInputs.of(settings, world, gs.tails.shape[1])

    def run(exact):
        args = (world.robot, world.start, gs.goals, gs.tails, gs.grasp_index, settings)
        return run_native(
            parts.chomp, parts.refiner, *args, selection.make_policy("MD"), parts.metric_settings, None, exact
        )

    alone = run(None)
    assert alone.metrics.success and alone.iterations < settings.iterations  # the metrics alone stop it early
    asked = []

    def second(xi):
        asked.append(np.array(xi))
        return len(asked) == 2

    out = run((0, second))
    np.testing.assert_array_equal(asked[0], alone.xi)  # the plan the metrics alone stopped on, refused
    assert len(asked) == 2 and out.iterations > alone.iterations and out.metrics.success
    np.testing.assert_array_equal(out.xi, asked[1])
    assert run((0, lambda xi: False)).iterations == settings.iterations
