"""``pickplan bench pickplace`` from the command line: one scene (its region a bin: the third kind in
turn), OMG and RRT-Connect on the place; runs.csv has one row per unit with the pick's and the place's
outcomes, and the table agrees with the records."""

import csv
import json
import os

from pickplan.cli.main import main

from conftest import standing_scene


def test_bench_pickplace_writes_one_row_per_unit(tmp_path):
    scene, _ = standing_scene(
        (("005_tomato_soup_can", (0.5, 0.0)), ("004_sugar_box", (0.6, 0.2))), "005_tomato_soup_can"
    )
    os.makedirs(tmp_path / "scenes")
    scene.save(str(tmp_path / "scenes" / "scene_0002.json"))
    out = tmp_path / "out"
    code = main(
        [
            "bench",
            "pickplace",
            "--scene-dir",
            str(tmp_path / "scenes"),
            "--methods",
            "OMG",
            "RRT-C",
            "--runs",
            "1",
            "--grasp-kind",
            "antipodal",
            "--workers",
            "0",
            "--no-progress",
            "--out",
            str(out),
        ]
    )
    assert code == 0
    with open(out / "runs.csv") as f:
        rows = list(csv.DictReader(f))
    assert sorted(r["method"] for r in rows) == ["OMG", "RRT-C"]
    for r in rows:
        assert r["region"] == "bin" and r["graspable"] == "True" and r["target"] == scene.target
        for field in ("pick_success", "place_success", "complete", "held_collision", "place_time", "status"):
            assert field in r
    omg = next(r for r in json.loads((out / "runs.json").read_text()) if r["method"] == "OMG")
    assert omg["status"] == "success" and omg["complete"], omg  # carried into the bin, at rest, upright
    assert omg["held_collision"] is False and omg["max_moved"] <= 0.02
    summary = json.loads((out / "summary.json").read_text())["methods"]
    assert summary["OMG"]["complete"] == 1.0 and summary["OMG"]["held_collisions"] == 0
    row = next(
        line
        for line in (out / "table.md").read_text().splitlines()
        if line.startswith("| Complete, executed (of graspable)")
    )
    assert [c.strip() for c in row.split("|")[2:-1]] == [
        f"{100 * summary[m]['complete']:.0f}%" for m in ("OMG", "RRT-C")
    ]
