"""The picture beside every sweep table: per-object success and time per stage."""

import numpy as np
from PIL import Image

from pickplan.eval.plots import STAGES, plot_table


def _records(execute: bool):
    rng = np.random.default_rng(0)
    out = []
    for m in ("OMG", "CHOMP"):
        for target in ("005_tomato_soup_can", "pen_01", "004_sugar_box"):
            for run in range(3):
                ok = bool(rng.random() < 0.8)
                out.append(
                    {
                        "method": m,
                        "target": target,
                        "valid": True,
                        "planning_success": ok,
                        "execution_success": ok and execute and bool(rng.random() < 0.9),
                        "execution_run": execute,
                        "stage_times": {s: float(rng.uniform(0.0005, 0.003)) for s in STAGES},
                    }
                )
    return out


def test_a_png_per_table_with_and_without_execution(tmp_path):
    pictures = []
    for execute in (True, False):
        path = tmp_path / f"table_{execute}.png"
        plot_table(str(path), _records(execute), ["OMG", "CHOMP"], "Table III: planners")
        image = np.asarray(Image.open(path).convert("RGB"))
        assert image.shape[0] > 200 and image.shape[1] > 500
        assert len(np.unique(image.reshape(-1, 3), axis=0)) > 20  # bars, not a blank canvas
        pictures.append(image)
    # the executed version draws the lifted bars the other leaves out
    assert pictures[0].shape != pictures[1].shape or np.abs(pictures[0].astype(int) - pictures[1]).sum() > 0
