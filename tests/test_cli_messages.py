"""Every command-line flag the source names (in an error, a hint or a help text) is one the
CLI takes, with the value it names where the flag has choices."""

from __future__ import annotations

import argparse
import ast
import json
import re
from pathlib import Path

from quatform import cli

SRC = Path(__file__).resolve().parents[1] / "src" / "quatform"
#: ``--flag`` and, when one follows (``--flag value`` / ``--flag=value``), the word after it;
#: not a fragment such as ``"--no-" + name``.
FLAG = re.compile(r"(?<![\w-])(--[a-z][a-z0-9]*(?:-[a-z0-9]+)*)(?![\w-])(?:[ =]([a-z0-9][\w.]*))?")


def _docstrings(tree) -> set:
    return {id(node.body[0].value) for node in ast.walk(tree)
            if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef))
            and node.body and isinstance(node.body[0], ast.Expr) and isinstance(node.body[0].value, ast.Constant)}


def named_flags() -> dict:
    """``{(flag, word after it or ''): [file:line, ...]}`` over every string of the source but docstrings."""
    found: dict = {}
    for f in sorted(SRC.rglob("*.py")):
        tree = ast.parse(f.read_text(encoding="utf-8"))
        docs = _docstrings(tree)
        for c in ast.walk(tree):
            if isinstance(c, ast.Constant) and isinstance(c.value, str) and id(c) not in docs:
                for m in FLAG.findall(c.value):
                    found.setdefault(m, []).append(f"{f.relative_to(SRC)}:{c.lineno}")
    return found


def parser_actions() -> dict:
    """``{flag: [its actions on every parser that has it]}`` of the whole CLI."""
    actions: dict = {}

    def walk(parser):
        for a in parser._actions:
            for s in a.option_strings:
                actions.setdefault(s, []).append(a)
            if isinstance(a, argparse._SubParsersAction):
                for p in a.choices.values():
                    walk(p)

    walk(cli._build_parser())
    return actions


def test_every_flag_named_in_the_source_exists_with_its_value():
    actions = parser_actions()
    choice_words = {str(c) for acts in actions.values() for a in acts for c in (a.choices or ())
                    if not isinstance(a, argparse._SubParsersAction)}
    found = named_flags()
    assert ("--compute", "numpy") in found and ("--scheduler", "local") in found  # the scan sees them
    wrong = []
    for (flag, word), where in sorted(found.items()):
        if flag not in actions:
            wrong.append(f"{flag} (no command takes it): {where}")
        elif word in choice_words:  # a value the CLI knows: every parser with choices for the flag takes it
            refused = [a for a in actions[flag] if a.choices is not None and word not in a.choices]
            if refused:
                wrong.append(f"{flag} {word} (refused: choices {list(refused[0].choices)}): {where}")
    assert not wrong, "\n".join(wrong)


def _usage_error(capsys, argv) -> str:
    """The one stderr line of a usage error (exit 2, no traceback)."""
    try:
        cli.main(argv)
    except SystemExit as exc:
        assert exc.code == 2
    else:
        raise AssertionError(f"{argv} parsed")
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    return err.strip()


def test_backend_names_physics_and_compute(tmp_path, capsys):
    """run / compare / teleop have no ``--backend``: with any value (or none) it is one line
    naming the physics (``--physics``) and the compute backend (``--compute``)."""
    out = str(tmp_path / "x")
    both = "the physics is --physics kinematic|mujoco, the compute backend --compute numpy|jax"
    for command, argv in (("run", ["run", "mas-kitts-spiral", "--out", out, "--backend", "mujoco"]),
                          ("run", ["run", "mas-kitts-spiral", "--out", out, "--backend", "jax"]),
                          ("run", ["run", "mas-kitts-spiral", "--out", out, "--backend", "gpu"]),
                          ("compare", ["compare", "mas-kitts-spiral", "--out", out, "--backend=kinematic"]),
                          ("compare", ["compare", "mas-kitts-spiral", "--out", out, "--backend"])):
        err = _usage_error(capsys, argv)
        assert f"--backend is not an option of {command}: {both}" in err, err
    err = _usage_error(capsys, ["teleop", "teleop-x", "--out", out, "--backend", "jax"])  # no --physics there
    assert "--backend is not an option of teleop: the compute backend is --compute numpy|jax" in err, err
    assert not (tmp_path / "x").exists()


def test_backend_is_named_before_a_missing_out(capsys):
    """``--backend`` without ``--out`` on run / compare / teleop: the line names ``--physics``
    and ``--compute`` first (not the missing ``--out``, which would leave ``--backend`` for
    the next try)."""
    for command in ("run", "compare", "teleop"):
        err = _usage_error(capsys, [command, "mas-kitts-spiral", "--backend", "mujoco"])
        assert f"--backend is not an option of {command}: " in err and "--compute numpy|jax" in err, err


def test_physics_chooses_what_moves_the_robots(tmp_path, capsys):
    """``--physics kinematic`` runs the kinematic models and metrics.json names the physics."""
    out = tmp_path / "run"
    assert cli.main(["run", "mas-kitts-helix", "--physics", "kinematic", "--controller", "quaternion",
                     "--out", str(out), "--no-plots", "--no-mcap"]) == 0
    m = json.loads((out / "metrics.json").read_text())
    assert m["physics"] == "kinematic" and "backend" not in m
    capsys.readouterr()
    err = _usage_error(capsys, ["run", "mas-kitts-helix", "--out", str(tmp_path / "y"), "--physics", "jax"])
    assert "invalid choice: 'jax'" in err, err


def test_sweep_backend_stays_the_compute_backend():
    parser = cli._build_parser(only=("sweep",))
    for flag in ("--backend", "--compute"):
        assert parser.parse_args(["sweep", "s", "--out", "o", flag, "jax"]).backend == "jax"


def test_compare_over_takes_the_flags_spelling(tmp_path, capsys, monkeypatch):
    """``--over orientation-error`` as the run option's flag (``--orientation-error``) spells it;
    ``orientation_error`` still works; ``--help`` shows the dashes."""
    from quatform import runs
    from quatform.errors import InvalidInputError

    seen = []

    def compare(sc, out, *, over=None, **_):
        seen.append(over)
        raise InvalidInputError("stop")  # the axis the runner got is all this test needs

    monkeypatch.setattr(runs, "compare", compare)
    for spelling in ("orientation-error", "orientation_error"):
        assert cli.main(["compare", "teleop-free-motion", "--out", str(tmp_path / "c"), "--over", spelling]) == 2
    assert seen == ["orientation_error", "orientation_error"]
    capsys.readouterr()
    try:
        cli.main(["compare", "--help"])
    except SystemExit as exc:
        assert exc.code == 0
    text = " ".join(capsys.readouterr().out.split())
    assert "orientation-error" in text and "orientation_error" not in text
