"""The user guide's Python blocks run, in order, in one namespace (docs/guide.md): what it shows works."""

import os
import re

import pytest

GUIDE = os.path.join(os.path.dirname(__file__), "..", "..", "docs", "guide.md")


def _python_blocks(text: str) -> list:
    return re.findall(r"^```python\n(.*?)^```", text, flags=re.S | re.M)


def test_the_guides_python_blocks_run(tmp_path, monkeypatch):
    with open(GUIDE, encoding="utf-8") as f:
        blocks = _python_blocks(f.read())
    assert len(blocks) >= 5
    monkeypatch.chdir(tmp_path)  # whatever a block writes stays out of the checkout
    namespace = {"__name__": "guide"}
    for k, block in enumerate(blocks):
        try:
            exec(compile(block, f"docs/guide.md block {k + 1}", "exec"), namespace)
        except Exception as exc:
            pytest.fail(f"docs/guide.md block {k + 1} failed: {exc!r}\n{block}")
