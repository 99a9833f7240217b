"""The evolution-strategies example (examples/es_residual.py) at a small budget: it runs, writes
its learning curve, its returns are finite and the same seed gives the same curve."""

from __future__ import annotations

import csv
import importlib.util
import math
from pathlib import Path

import pytest

pytest.importorskip("jax")
pytest.importorskip("matplotlib")

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "es_residual.py"
SMALL = ["--generations", "2", "--population", "2", "--episodes", "2", "--eval-episodes", "2",
         "--episode-s", "0.3", "--seed", "3"]


def _example():
    spec = importlib.util.spec_from_file_location("es_residual", EXAMPLE)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_es_example_writes_a_finite_reproducible_curve(tmp_path):
    es = _example()
    rows = es.main(SMALL + ["--out", str(tmp_path / "a")])
    again = es.main(SMALL + ["--out", str(tmp_path / "b")])
    assert [r["generation"] for r in rows] == [0, 1, 2]
    keys = ("mean_return", "best_return", "policy_heldout", "base_heldout")
    assert all(math.isfinite(r[k]) for r in rows for k in keys)
    assert [[r[k] for k in keys] for r in rows] == [[r[k] for k in keys] for r in again]
    # generation 0's policy is the base controller (its last layer starts at zero)
    assert rows[0]["policy_heldout"] == rows[0]["base_heldout"]
    with open(tmp_path / "a" / "curve.csv", newline="") as fh:
        written = list(csv.DictReader(fh))
    assert [float(r["policy_heldout"]) for r in written] == [r["policy_heldout"] for r in rows]
    assert (tmp_path / "a" / "curve.png").stat().st_size > 0


def test_es_example_refuses_an_odd_population(capsys):
    with pytest.raises(SystemExit):
        _example().parse(["--population", "3"])
    assert "even" in capsys.readouterr().err
