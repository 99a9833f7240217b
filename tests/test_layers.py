"""Layers one way, no private reach-ins, checked on the source text.

Every ``from ... import ...`` of quatform (at module level or inside a function) must go to
the same package or a lower layer, and nothing may import an underscored module or name of
another module (``from .plots import _save``, ``from ..formations._geometry import ...``)."""

from __future__ import annotations

import ast
from pathlib import Path

SRC = Path(__file__).resolve().parents[1] / "src" / "quatform"

#: Layer of each top-level package or module of quatform (higher imports lower, never the reverse).
LAYERS = {
    "errors": 0, "checks": 0, "tomlio": 0, "papers": 0, "registry": 0,
    "algebra": 1, "messages": 1,
    "formations": 2, "planning": 2, "network": 2, "teleop": 2,
    "robots": 3,
    "control": 4, "references": 4,
    "sim": 5,
    "scenarios": 6,
    "report": 7, "bags": 7,
    "runs": 8, "plan_runs": 8, "envs": 8, "sweeps": 8, "ros2": 8, "cli": 8, "__main__": 8, "outputs": 8, "live": 8,
}
#: Modules of a package that sit in another layer than the package (the longest dotted prefix
#: of a module in LAYERS or here decides): the teleoperation package holds the arms'
#: kinematics (beside formations) and the teleoperation controller and its task-space
#: errors, which use the control layer's contract and stiffness law.
MODULE_LAYERS = {"teleop.controller": 4, "teleop.task": 4, "teleop.control": 4, "teleop.__init__": 4}


MODULE_LAYERS_PACKAGES = {key.split(".")[0] for key in MODULE_LAYERS}


def layer(parts) -> int:
    """The layer of the module ``parts`` (``("teleop", "arm")``)."""
    for n in range(len(parts), 0, -1):
        key = ".".join(parts[:n])
        if key in MODULE_LAYERS:
            return MODULE_LAYERS[key]
    return LAYERS[parts[0]]


def _imports(root=SRC):
    """``(file, its module parts, target module parts, imported names)`` of every quatform import."""
    for f in sorted(root.rglob("*.py")):
        parts = f.relative_to(root).with_suffix("").parts
        package = list(parts[:-1])
        for node in ast.walk(ast.parse(f.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ImportFrom):
                if node.level:
                    base = package[:len(package) - (node.level - 1)]
                    target = base + (node.module.split(".") if node.module else [])
                elif node.module and node.module.split(".")[0] == "quatform":
                    target = node.module.split(".")[1:]
                else:
                    continue
                yield f, parts, target, [a.name for a in node.names]
            elif isinstance(node, ast.Import):
                for a in node.names:
                    if a.name.split(".")[0] == "quatform":
                        yield f, parts, a.name.split(".")[1:], []


def _private(name: str) -> bool:
    return name.startswith("_") and not name.startswith("__")


def test_every_top_level_package_has_a_layer():
    tops = {p.stem if p.is_file() else p.name for p in SRC.iterdir()
            if (p.suffix == ".py" and p.stem != "__init__") or (p.is_dir() and (p / "__init__.py").exists())}
    assert tops <= set(LAYERS), sorted(tops - set(LAYERS))


def _upward(root=SRC) -> list:
    upward = []
    for f, parts, target, names in _imports(root):
        if parts[0] == "__init__" or not target:
            continue
        # ``from ..teleop import x`` is the package's __init__
        there = tuple(target) if len(target) > 1 or not (root / target[0]).is_dir() else (target[0], "__init__")
        across = parts[0] != there[0] or parts[0] in MODULE_LAYERS_PACKAGES  # a mixed package: within it too
        if across and layer(there) > layer(parts):
            upward.append(f"{'/'.join(parts)} imports {'.'.join(target)} (layer {layer(there)} > {layer(parts)})")
    return upward


def _reach_ins(root=SRC) -> list:
    found = []
    for f, parts, target, names in _imports(root):
        if any(_private(p) for p in target):
            found.append(f"{'/'.join(parts)} imports module {'.'.join(target)}")
        if list(target) != list(parts):
            found += [f"{'/'.join(parts)} imports {'.'.join(target)}.{n}" for n in names if _private(n)]
    return found


def test_imports_go_down_the_layers_only():
    assert _upward() == []


def test_no_private_module_or_name_of_another_module_is_imported():
    assert _reach_ins() == []


def test_the_checks_find_an_upward_and_a_private_import(tmp_path):
    """The checks above are not vacuous: on a sample tree they find each kind of import."""
    (tmp_path / "sim").mkdir()
    (tmp_path / "sim" / "plot_it.py").write_text("from ..report.plots import _save\nfrom . import log\n"
                                                  "from quatform.algebra._kernels import qmul\n")
    (tmp_path / "report").mkdir()
    (tmp_path / "report" / "plots.py").write_text("from ..sim import Log\n\n\ndef f():\n    from .figures import _x\n")
    (tmp_path / "teleop").mkdir()
    (tmp_path / "teleop" / "arm.py").write_text("from .controller import TeleopController\n")
    assert sorted(_upward(tmp_path)) == ["sim/plot_it imports report.plots (layer 7 > 5)",
                                         "teleop/arm imports teleop.controller (layer 4 > 2)"]
    assert sorted(_reach_ins(tmp_path)) == ["report/plots imports report.figures._x",
                                            "sim/plot_it imports module algebra._kernels",
                                            "sim/plot_it imports report.plots._save"]
