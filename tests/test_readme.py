"""The README's Python examples run as written (a user copies them first)."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from quatform.control import SafeController

README = Path(__file__).resolve().parents[1] / "README.md"
BLOCKS = re.findall(r"```python\n(.*?)```", README.read_text(), re.S)


def test_the_readme_has_its_examples():
    assert len(BLOCKS) >= 3


@pytest.mark.parametrize("i", range(len(BLOCKS)))
def test_readme_example_runs_and_commands_are_finite(i):
    if "gymnasium" in BLOCKS[i]:
        pytest.importorskip("gymnasium")
    scope: dict = {}
    exec(compile(BLOCKS[i], f"README.md python block {i + 1}", "exec"), scope)
    for name in ("u", "tau_m", "tau_s"):
        if name in scope:
            assert np.all(np.isfinite(scope[name]))
    if isinstance(scope.get("ctrl"), SafeController):  # the team example: the barrier has nothing to do
        ctrl = scope["ctrl"]
        s = ctrl.update(0.0, scope["measured"], scope["Reference"](scope["c_des"], scope["c_dot"]), ctrl.init())
        assert s.signals["safety_active"][0] == 0.0 and s.signals["min_separation"][0] > 0.3
