"""The README's Python example runs as written (a user copies it first) and its plan lifts the target."""

import pathlib
import re

README = pathlib.Path(__file__).resolve().parents[2] / "README.md"


def _python_blocks():
    return re.findall(r"```python\n(.*?)```", README.read_text(), flags=re.S)


def test_readme_python_example_plans_and_lifts():
    blocks = _python_blocks()
    assert blocks, "README.md has no python example"
    namespace = {}
    for block in blocks:
        exec(compile(block, str(README), "exec"), namespace)  # noqa: S102 - our own README
    # The example names its results `result` and `run`: the plan succeeds and the target is lifted.
    assert namespace["result"].status.value == "success"
    assert namespace["run"].status.value == "lifted"
    assert namespace["run"].target_lift > 0.1
