"""MuJoCo is optional. quatform imports, and every kinematic feature works,
without it; asking for MuJoCo physics then fails with a message naming the extra.
(This file needs no MuJoCo: it hides it from a fresh interpreter.)"""

from __future__ import annotations

import re
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from quatform.errors import MissingDependencyError
from quatform.sim.mujoco_backend import INSTALL_HINT, import_mujoco

ROOT = Path(__file__).resolve().parents[1]

SCRIPT = textwrap.dedent("""
    import sys
    sys.modules["mujoco"] = None  # "not installed": importing it raises ImportError
    import quatform, quatform.cli, quatform.runs, quatform.sim, quatform.robots.physics, quatform.report
    from quatform.robots.physics import quadrotor_mjcf, QuadrotorCascade
    quadrotor_mjcf("q", (0, 0, 1)); QuadrotorCascade()  # the models need no MuJoCo
    from quatform.sim import mujoco_backend
    from quatform.errors import MissingDependencyError
    try:
        mujoco_backend.PhysicsWorld(quads=[("q", (0, 0, 1), 0.0)])
    except MissingDependencyError as exc:
        assert isinstance(exc, ImportError)
        print("MESSAGE:", exc)
    rc = quatform.cli.main(["run", "mas-kitts-helix", "--physics", "mujoco", "--controller", "quaternion",
                            "--out", sys.argv[1]])
    print("RC:", rc)
""")


def test_quatform_imports_without_mujoco_and_names_the_extra(tmp_path):
    out = subprocess.run([sys.executable, "-c", SCRIPT, str(tmp_path / "run")], capture_output=True, text=True, check=False,
                         timeout=120)
    assert out.returncode == 0, out.stderr
    assert "MESSAGE:" in out.stdout and "pip install -e \".[mujoco]\"" in out.stdout
    assert "RC: 2" in out.stdout and "pip install -e \".[mujoco]\"" in out.stderr


def test_importing_quatform_does_not_import_mujoco():
    code = ("import sys, quatform, quatform.cli, quatform.runs, quatform.sim, quatform.robots.physics, "
            "quatform.sim.mujoco_backend, quatform.report.physics_render; print('mujoco' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=False, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "False"


# -- the install hint names the checkout's form ------------------------------------

def test_missing_mujoco_names_the_checkout_install(monkeypatch):
    """``pip install quatform[mujoco]`` cannot work from a checkout."""
    monkeypatch.setitem(sys.modules, "mujoco", None)  # "not installed"
    with pytest.raises(MissingDependencyError) as info:
        import_mujoco()
    msg = str(info.value)
    assert INSTALL_HINT == 'pip install -e ".[mujoco]"' and INSTALL_HINT in msg
    assert "quatform[mujoco]" not in msg and "\n" not in msg


def test_no_install_hint_names_the_package_index_form():
    """Every hint in the physics backend's files (cli.py's help is checked by the CLI's tests)."""
    files = [ROOT / "src/quatform/sim/mujoco_backend.py", ROOT / "src/quatform/report/physics_render.py",
             ROOT / "docs/physics.md", ROOT / "benchmarks/bench_physics.py",
             *sorted((ROOT / "src/quatform/robots/physics").glob("*.py"))]
    bad = [f"{f.name}: {line.strip()}" for f in files for line in f.read_text().splitlines()
           if re.search(r"pip install [\"']?quatform\[mujoco\]", line)]
    assert not bad, bad
