"""`pickplan pickup cases` output (Tables I-IV beside the paper's numbers, Fig. 5 plot, trajectories as
JSON/NPZ) and the PyBullet replay. The solves are replaced by one real solved plan (case 4, m = 6)
so the test checks the writing, not the (benchmarked) solver."""

import copy
import json
import os

import numpy as np
import pytest

from pickplan.pickup.nlp import cases
from pickplan.cli import pickup as cases_cli
from pickplan.pickup.nlp import replay


@pytest.fixture(scope="module")
def plan_dict():
    return cases._solve_job((4, "successive", 0, {"sigma": "medium"}, {"samples_per_interval": 6}))


def test_cases_cli_writes_tables_plot_trajectories_and_replays(tmp_path, monkeypatch, plan_dict, capsys):
    assert plan_dict["success"], plan_dict["status"]
    failed = {**copy.deepcopy(plan_dict), "success": False, "status": "infeasible", "seed": 1}
    one = lambda c, **kw: {**copy.deepcopy(plan_dict), "case": c, **kw}  # noqa: E731
    monkeypatch.setattr(
        cases,
        "run_main_cases",
        lambda cfg: {
            c: {
                "successive": one(c, direct_chosen=c == 5),
                "single_shot": one(c, method="single_shot"),
                "single_shot_all": [one(c, method="single_shot"), {**failed, "case": c}],
            }
            for c in range(1, 7)
        },
    )
    monkeypatch.setattr(
        cases, "run_table4", lambda cfg: {(c, lv): one(c) for c in cases.TABLE4_CASES for lv in ("low", "high")}
    )
    monkeypatch.setattr(cases, "run_fig5", lambda cfg: {"high (3 pi rad/s)": one(1), "low (pi/2 rad/s)": one(1)})
    out = tmp_path / "out"
    assert (
        cases_cli.main(
            ["cases", "--out", str(out), "--quick", "--metamodel", "standin", "--replay", "case4_sequential"]
        )
        == 0
    )
    md = (out / "tables.md").read_text()
    assert "rho_sigma source: STAND-IN surface" in md
    for title in ("Table I", "Table II", "Table III", "Table IV"):
        assert f"## {title}" in md
    # The paper's numbers beside ours, e.g. Table III case 5 execution times 17.54 / 19.54 s.
    assert f"17.54 / {plan_dict['T']:.2f}" in md and f"19.54 / {plan_dict['T']:.2f}" in md
    assert "Single-shot seeds solved per case: [1, 1, 1, 1, 1, 1]" in md
    assert "direct track (all constraints from the stage-1 solution, shorter than the five stages'): cases [5]" in md
    assert (out / "fig5_speeds.png").stat().st_size > 1000
    names = sorted(os.listdir(out / "trajectories"))
    assert "case4_sequential.json" in names and "case4_sequential.npz" in names
    assert "case6_single_shot_seed1.json" in names and "fig5_case1_low_rates.npz" in names
    z = np.load(out / "trajectories" / "case4_low_uncertainty.npz")
    assert z["q"].shape[1] == 9
    assert "replayed" in capsys.readouterr().out
    # Replay alone, from the files written above.
    assert cases_cli.main(["cases", "--out", str(out), "--replay", "case4_sequential", "--replay-only"]) == 0
    with pytest.raises(FileNotFoundError, match="no trajectory"):
        cases_cli.main(["cases", "--out", str(out), "--replay", "case9_nothing", "--replay-only"])


def test_replay_checks_pose_and_finds_a_collision(plan_dict):
    r = replay.replay(plan_dict, 4, frames=80)
    # PyBullet's own FK (float32 link states) agrees with the grasp pose at T2.
    assert r["tool_error_T2"][0] < 1e-5 and r["tool_error_T2"][1] < 1e-4
    assert r["min_distance"] > 0.0  # the planned trajectory clears the obstacles (URDF shapes)
    # The same plan with the base parked on the pillar beside the route must collide.
    bad = copy.deepcopy(plan_dict)
    x, deg = np.asarray(bad["x"]), bad["degrees"]
    for i, v in enumerate((5.2, 0.9)):
        off = sum(d + 1 for d in deg[:i])
        x[off : off + deg[i] + 1] = 0.0
        x[off] = v
    bad["x"] = x.tolist()
    assert replay.replay(bad, 4, frames=10)["min_distance"] < 0.0
    with pytest.raises(ValueError, match="no solution"):
        replay.replay({**plan_dict, "stages_completed": 0}, 4)


def test_ensure_metamodel_builds_once_from_simulation_and_the_nlp_reads_it(tmp_path, monkeypatch):
    from pickplan.pickup.metamodel import model as metamodel
    from pickplan.pickup.metamodel.active import ActiveConfig

    tiny = metamodel.BuildConfig(
        sg_grid=(0.1, 0.5),
        sc_grid=(0.05, 0.15),
        n_queries=2000,
        active=ActiveConfig(n_init=12, n_holdout=12, batch_size=10, budget=30),
    )
    path = tmp_path / "mm" / "metamodel_box.json"
    assert cases.ensure_metamodel(path, tiny, seed=3, progress=False) == str(path)
    mm = metamodel.MetaModel.load(path)
    assert mm.part_name == "box" and all(bm.n_simulations <= 30 for bm in mm.boundaries.values())
    # The trajectory NLP's native surface is the file's: same value as the part-1 surface.
    rho = cases.rho_for("medium", str(path))
    assert rho.value(0.3, 0.1) == pytest.approx(float(mm.surfaces["medium"](0.3, 0.1)), abs=1e-12)
    # A second call reuses the file and builds nothing.
    mtime = path.stat().st_mtime_ns
    monkeypatch.setattr(cases, "build_metamodel", lambda *a, **k: pytest.fail("rebuilt a cached model"))
    assert cases.ensure_metamodel(path, tiny, progress=False) == str(path)
    assert path.stat().st_mtime_ns == mtime
    # Not a meta-model, or another part's: clear errors, nothing overwritten.
    bad = tmp_path / "bad.json"
    bad.write_text('{"format": "something else"}')
    with pytest.raises(ValueError, match="not a pickplan meta-model"):
        cases.ensure_metamodel(bad, tiny, progress=False)
    other = json.loads(path.read_text())
    other["part"] = "cylinder"
    (tmp_path / "cyl.json").write_text(json.dumps(other))
    with pytest.raises(ValueError, match="expected 'box'"):
        cases.ensure_metamodel(tmp_path / "cyl.json", tiny, progress=False)
    assert bad.read_text() == '{"format": "something else"}'


def test_cases_cli_uses_the_built_meta_model_by_default(tmp_path, monkeypatch, plan_dict):
    seen = {}
    monkeypatch.setattr(cases, "ensure_metamodel", lambda path, **kw: seen.setdefault("path", path))

    def main_cases(cfg):
        seen["metamodel"] = cfg.metamodel
        raise KeyboardInterrupt  # stop after the wiring: the solves are benchmarked, not unit-tested

    monkeypatch.setattr(cases, "run_main_cases", main_cases)
    with pytest.raises(KeyboardInterrupt):
        cases_cli.main(["cases", "--out", str(tmp_path)])
    assert seen["path"] == os.path.join(str(tmp_path), "metamodel_box.json") == seen["metamodel"]
    with pytest.raises(FileNotFoundError, match="meta-model file not found"):
        cases_cli.main(["cases", "--out", str(tmp_path), "--metamodel", str(tmp_path / "none.json")])
