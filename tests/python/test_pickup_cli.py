"""`metamodel build` / `compare` end to end on the real simulation with tiny budgets."""
import json
import math

from pickplan.pickup.cli import main
from pickplan.pickup.metamodel import MetaModel


def test_build_and_compare(tmp_path):
    out = str(tmp_path)
    args = ["--quick", "--parts", "box", "--out", out, "--seed", "1", "--budget", "40",
            "--quiet"]
    assert main(["metamodel", "build", *args]) == 0
    mm = MetaModel.load(tmp_path / "metamodel_box.json")
    assert [lv.name for lv in mm.levels] == ["low", "medium", "high"]
    assert all(bm.n_simulations <= 40 for bm in mm.boundaries.values())
    # Slow gripper, fast closing, low uncertainty: near-certain success.
    assert mm.rho(0.1, 0.15, 0.002, math.radians(5)) > 0.8
    assert main(["metamodel", "compare", *args, "--samples", "3"]) == 0
    data = json.loads((tmp_path / "box_comparison.json").read_text())
    assert len(data["rows"]) == 3 * 4
    assert all(0.0 <= r["rho_extensive"] <= 1.0 for r in data["rows"])
    assert (tmp_path / "box_comparison.png").stat().st_size > 1000
    assert (tmp_path / "box_comparison.md").read_text().count("\n| ") == 13
