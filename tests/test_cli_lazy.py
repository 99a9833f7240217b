"""``quatform --help`` imports none of the numerical layers; each command's parser is built
(and its modules imported) only when that command is given, with the same options."""

from __future__ import annotations

import argparse
import json
import subprocess
import sys

import pytest

from quatform import cli

HEAVY = ("numpy", "scipy", "matplotlib", "jax", "rosbags", "mujoco", "dask", "distributed", "rerun")

PROBE = """
import json, sys
from quatform.cli import main
try:
    main(sys.argv[1:])
except SystemExit:
    pass
print(json.dumps(sorted(m for m in sys.modules if m.split(".")[0] in {heavy!r} or m.startswith("quatform."))),
      file=sys.stderr)
"""


def _imported(*argv) -> list:
    """The heavy and quatform modules a fresh interpreter holds after ``quatform ARGV``."""
    r = subprocess.run([sys.executable, "-c", PROBE.format(heavy=set(HEAVY)), *argv], capture_output=True,
                       text=True, timeout=120, check=True)
    assert r.stdout.startswith("usage: quatform")
    return json.loads(r.stderr.strip().splitlines()[-1])


def test_top_level_help_imports_no_numerical_layer():
    mods = _imported("--help")
    assert not [m for m in mods if m.split(".")[0] in HEAVY], mods
    assert set(mods) <= {"quatform.cli", "quatform.errors"}, mods


def test_run_help_imports_the_kinds_but_not_scipy_matplotlib_or_jax():
    mods = _imported("run", "--help")
    assert "quatform.scenarios" in mods  # its options come from the kinds' Options
    assert not [m for m in mods if m.split(".")[0] in ("scipy", "matplotlib", "jax", "mujoco", "rerun")], mods


def _help(parser, name) -> str:
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return sub.choices[name].format_help()


@pytest.mark.parametrize("name", list(cli.COMMANDS))
def test_a_command_built_alone_has_the_options_of_the_full_parser(name):
    assert _help(cli._build_parser(only=(name,)), name) == _help(cli._build_parser(), name)
    assert "options:" in _help(cli._build_parser(only=(name,)), name)


def test_the_command_is_the_first_word_that_is_not_an_option():
    assert cli._given_command(["--version"]) is None
    assert cli._given_command(["run", "helix", "--out", "x"]) == "run"
    assert cli._given_command(["-h", "sweep"]) == "sweep"
