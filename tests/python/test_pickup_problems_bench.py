"""bench/pickup_problems.py (issue 37's benchmark): its --near-bound reaches plan_routed, and a bad
value is refused before any problem is solved."""

import importlib.util
import math
import os
from dataclasses import replace

import pytest

from pickplan.pickup.nlp import planner, random_problems, routed

SCRIPT = os.path.join(os.path.dirname(__file__), "..", "..", "bench", "pickup_problems.py")


@pytest.fixture(scope="module")
def bench():
    spec = importlib.util.spec_from_file_location("pickup_problems_bench", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.parametrize("value", ["-1", "nan", "inf"])
def test_a_bad_near_bound_is_refused(bench, value):
    with pytest.raises(SystemExit, match="--near-bound"):
        bench.main(["--near-bound", value, "--n", "1", "--shots", "0", "--method", "routed"])


def test_the_near_bound_reaches_plan_routed(bench, monkeypatch):
    seen = []
    real = routed.plan_routed

    def plan(*args, **kwargs):
        seen.append(kwargs.get("near_bound", routed.NEAR_BOUND))
        return real(*args, **kwargs)

    monkeypatch.setattr(routed, "plan_routed", plan)
    spec = replace(random_problems.random_problems(1, 0)[0], metamodel="standin")
    for value, expected in ((None, routed.NEAR_BOUND), (0.0, 0.0)):
        seen.clear()
        args = bench.argparse.Namespace(near_bound=value)
        job = (spec, None, planner.Method.routed, 0, {}, bench._routed_options(args), 0.0)
        record = bench._solve(job)
        assert seen == [expected] and record["solved"] and math.isfinite(record["T"])
