"""The batch spread over JAX's devices (:mod:`quatform.sim.jax_devices`): chunk sizes,
the CPU device count, and sharded runs equal to NumPy (a subprocess with three CPU devices,
so a batch that does not divide is padded).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import pytest

pytest.importorskip("jax")

from quatform.sim import jax_devices  # noqa: E402

SRC = str(Path(__file__).resolve().parents[1] / "src")
TESTS = str(Path(__file__).resolve().parent)


def fake_jax(n: int, platform: str = "cpu"):
    return SimpleNamespace(devices=lambda: [SimpleNamespace(platform=platform)] * n)


@pytest.mark.parametrize(("n", "platform", "worlds", "per_call", "size"), [
    (1, "cpu", 10_000, None, jax_devices.CPU_WORLDS_PER_DEVICE),
    (2, "cpu", 10_000, None, 2 * jax_devices.CPU_WORLDS_PER_DEVICE),
    (2, "cpu", 3, None, 4),        # a small batch: one padded call, an equal slice per device
    (3, "cpu", 10, 10, 12),        # given: rounded up to the devices
    (4, "gpu", 10_000, None, 10_000),  # an accelerator takes the whole batch
    (1, "cpu", 5, 100, 5),         # never more than the batch
])
def test_chunk_size(n, platform, worlds, per_call, size):
    assert jax_devices.chunk_size(fake_jax(n, platform), worlds, per_call) == size


def test_usable_cores_positive():
    assert 1 <= jax_devices.usable_cores() <= (os.cpu_count() or 1)


SCRIPT = r"""
import dataclasses, json, sys
import numpy as np
from conftest import assert_logs_equal, short_scenario
from quatform.scenarios.team import TEAM
from quatform.sim.loop import require_jax
from quatform.sim.jax_rollout import rollout_metrics
from quatform.sim.metrics import compute_metrics
from quatform.sim.trial_measurement import TickMeasurement
jax = require_jax()
ex = TEAM.experiment(short_scenario("mas-kitts-spiral", 0.4), controller="quaternion")
T, B = ex.times.size, 4
rng = np.random.default_rng(3)
x0 = ex.x0 + rng.normal(0.0, 0.2, (B, 8))
x0[2, 4:7] = x0[2, 0:3]  # world 2: its robots on each other (failed; the others go on)
noise, dropped = rng.normal(0.0, 0.01, (T, B, 8)), rng.random((T, B)) < 0.1
noise[:, 2], dropped[:, 2] = 0.0, False  # measured on each other too
meas = TickMeasurement(noise, 1, dropped)
ex = dataclasses.replace(ex, x0=x0, measurement=meas)
a, b = ex.run(backend="numpy"), ex.run(backend="jax")
assert_logs_equal(a, b)
seen = []
assert_logs_equal(a, ex.run(backend="jax", progress=seen.append))
r = rollout_metrics(ex, x0, meas, trials_per_call=int(sys.argv[1]))
print(json.dumps({"devices": len(jax.devices()), "failed": np.asarray(b.meta["failed"]).tolist(),
                  "rollout_failed": r["failed"].tolist(), "progress": len(seen),
                  "max_err": r["max_robot_position_error_m"].tolist()}))
"""


def run_script(env_extra: dict, script: str = SCRIPT, per_call: int | str = 2) -> dict:
    env = {k: v for k, v in os.environ.items() if k != "XLA_FLAGS"}
    env.update(env_extra, PYTHONPATH=os.pathsep.join([SRC, TESTS]))
    out = subprocess.run([sys.executable, "-c", script, str(per_call)], env=env, capture_output=True, text=True,
                         timeout=300)
    assert out.returncode == 0, out.stderr[-3000:]
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_three_devices_pad_and_equal_numpy():
    """Four worlds on three CPU devices: padded to six, sharded, equal to NumPy, the failed world marked."""
    res = run_script({"XLA_FLAGS": "--xla_force_host_platform_device_count=3"})
    assert res["devices"] == 3
    assert res["failed"] == [False, False, True, False]
    assert res["rollout_failed"] == res["failed"]
    assert res["progress"] >= 2


HORN = r"""
import dataclasses, json, sys
import numpy as np
from conftest import short_scenario
from quatform.scenarios.team import TEAM
from quatform.sim.loop import require_jax
from quatform.sim.jax_rollout import ROLLOUT_METRICS, rollout_metrics
jax = require_jax()
name, barrier = sys.argv[1].split(":")
ex = TEAM.experiment(dataclasses.replace(short_scenario(name, 0.3), metrics_from_s=0.1), controller="quaternion",
                     min_separation=None if barrier == "on" else 0.0)
x0 = ex.x0 + np.random.default_rng(7).normal(0.0, 0.05, (5,) + ex.x0.shape)
ex = dataclasses.replace(ex, x0=x0)
r = rollout_metrics(ex, x0, formation_metrics=False, trials_per_call=6)
logged = ex.run(backend="numpy")
worst = 0.0
for i in range(5):
    want = ex.metrics(logged.world(i))
    for key in set(ROLLOUT_METRICS) & set(r):
        if isinstance(want[key], float):
            worst = max(worst, abs(float(r[key][i]) - want[key]) / max(1.0, abs(want[key])))
jx = ex.run(backend="jax")
print(json.dumps({"devices": len(jax.devices()), "worst": worst, "applied": ex.meta["safety"]["applied"],
                  "log": float(np.max(np.abs(np.asarray(jx["state"]) - np.asarray(logged["state"]))))}))
"""


@pytest.mark.parametrize("case", ["team-tetrahedron-helix:off", "team-ring-flip:on"])
def test_teams_on_three_devices_end_and_equal_numpy(case):
    """Three CPU devices: a team of four without the barrier (Horn's 4 x 4 eigensolve: the
    batch sharded) and a team of ten under the barrier (its loop and 32 x 32 solves: one
    device) both end within the subprocess's time limit, their rollout metrics and logged
    states equal to NumPy's."""
    res = run_script({"XLA_FLAGS": "--xla_force_host_platform_device_count=3"}, HORN, per_call=case)
    assert res["devices"] == 3
    assert res["applied"] == case.endswith(":on")
    assert res["worst"] <= 1e-9 and res["log"] <= 1e-9


def test_shardable_reads_the_program():
    """``shardable``: one CPU device or an accelerator always; several CPU devices only for a
    program without a loop and without a LAPACK call on matrices larger than 4 x 4."""
    import jax
    import jax.numpy as jnp

    hazards = jax_devices.program_hazards
    assert hazards(jax.make_jaxpr(lambda a: a * 2.0)(jnp.ones((3, 4, 4)))) == (False, 0)
    assert hazards(jax.make_jaxpr(lambda a: jnp.linalg.eigh(a)[0])(jnp.ones((3, 4, 4)))) == (False, 4)
    assert hazards(jax.make_jaxpr(lambda a: jnp.linalg.solve(a, a))(jnp.eye(6)[None]))[1] == 6

    def looping(a):
        return jax.lax.scan(lambda c, _: (jax.lax.while_loop(lambda v: v[0, 0] < 3.0, lambda v: v + 1.0, c), None),
                            a, None, length=2)[0]

    assert hazards(jax.make_jaxpr(looping)(jnp.zeros((2, 2)))) == (True, 0)
    cpu = [SimpleNamespace(platform="cpu")] * 2
    fake = SimpleNamespace(devices=lambda: cpu, make_jaxpr=jax.make_jaxpr, tree_util=jax.tree_util)
    assert jax_devices.shardable(fake, jax.jit(lambda c, x: jnp.linalg.eigh(c)[0]), jnp.ones((2, 4, 4)), {})
    assert not jax_devices.shardable(fake, jax.jit(lambda c, x: jnp.linalg.eigh(c)[0]), jnp.ones((2, 5, 5)), {})
    assert not jax_devices.shardable(fake, jax.jit(lambda c, x: looping(c)), jnp.zeros((2, 2)), {})
    gpu = SimpleNamespace(devices=lambda: [SimpleNamespace(platform="gpu")] * 2)
    assert jax_devices.shardable(gpu, None, None, None)


COUNT = r"""
import json, sys
import jax
from quatform.sim.jax_devices import share_cores
if sys.argv[1].startswith("share"):
    share_cores(int(sys.argv[1][5:]))  # a sweep's worker among others
elif sys.argv[1] != "0":
    jax.config.update("jax_num_cpu_devices", int(sys.argv[1]))  # the user's choice
from quatform.sim.loop import require_jax
print(json.dumps({"devices": len(require_jax().devices())}))
"""


@pytest.mark.parametrize("chosen", [0, 1, 3])
def test_cpu_devices_are_the_cores_unless_chosen(chosen):
    """Without the user's choice quatform asks JAX for one CPU device per usable core."""
    want = chosen or jax_devices.usable_cores()
    assert run_script({}, COUNT, chosen)["devices"] == want


def test_workers_share_the_cores():
    """A sweep's worker among ``w`` asks for ``cores // w`` devices (at least one)."""
    cores = jax_devices.usable_cores()
    assert run_script({}, COUNT, "share2")["devices"] == max(1, cores // 2)
    assert run_script({}, COUNT, f"share{cores + 1}")["devices"] == 1


CACHED = r"""
import dataclasses, json, sys, time
import numpy as np
from quatform.scenarios import load_scenario
from quatform.scenarios.team import TEAM
ex = TEAM.experiment(load_scenario("mas-kitts-spiral"), controller="quaternion")
ex = dataclasses.replace(ex, times=ex.times[:40], x0=ex.x0 + np.linspace(0.0, 0.02, 3)[:, None],
                         finish=lambda log: log)
from quatform.sim.loop import require_jax
jax = require_jax()
jax.config.update("jax_log_compiles", True)  # JAX logs its persistent cache's hits and misses
import logging
said = []
handler = logging.Handler()
handler.emit = lambda record: said.append(record.getMessage())
logging.getLogger("jax").addHandler(handler)
log = ex.run(backend="jax")
print(json.dumps({"dir": jax.config.jax_compilation_cache_dir, "state": log["state"].tolist(),
                  "hits": sum("compilation cache hit" in m.lower() for m in said)}))
"""


def test_compiled_programs_kept_on_disk(tmp_path):
    """With ``QUATFORM_JAX_CACHE`` a run keeps its compiled tick there (a folder of this user's
    alone); a second process loads it and gets the same floats as a process that compiles
    (``off``: no folder)."""
    where = tmp_path / "cache"
    first = run_script({jax_devices.CACHE_ENV: str(where)}, CACHED)
    assert first["dir"] == str(where)
    entries = sorted(p.name for p in where.iterdir())
    assert entries and (where.stat().st_mode & 0o077) == 0
    again = run_script({jax_devices.CACHE_ENV: str(where)}, CACHED)
    assert sorted(p.name for p in where.iterdir()) == entries  # loaded, nothing compiled anew
    assert first["hits"] == 0 and again["hits"] >= 1
    fresh = run_script({jax_devices.CACHE_ENV: "off"}, CACHED)
    assert fresh["dir"] is None
    assert first["state"] == again["state"] == fresh["state"]


@pytest.mark.parametrize(("value", "want"), [("off", None), ("OFF", None), ("", None), ("0", None),
                                             ("/x/y", Path("/x/y"))])
def test_cache_dir_from_the_environment(monkeypatch, value, want):
    monkeypatch.setenv(jax_devices.CACHE_ENV, value)
    assert jax_devices.cache_dir() == want


def test_cache_dir_default(monkeypatch, tmp_path):
    monkeypatch.delenv(jax_devices.CACHE_ENV, raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    assert jax_devices.cache_dir() == tmp_path / "quatform" / "jax"
    monkeypatch.delenv("XDG_CACHE_HOME")
    assert jax_devices.cache_dir() == Path.home() / ".cache" / "quatform" / "jax"


def options_of(monkeypatch, jax, flags: str = "") -> dict:
    """:func:`jax_devices.compiler_options` asked afresh, with ``XLA_FLAGS`` set to ``flags``."""
    monkeypatch.setenv("XLA_FLAGS", flags)
    monkeypatch.setattr(jax_devices, "_ACCEPTED", [None])
    return jax_devices.compiler_options(jax)


def test_compiler_options_on_the_cpu(monkeypatch):
    """On the CPU an XLA that knows the options gets them; one that refuses them (an older
    jaxlib) gets none; ``XLA_FLAGS`` naming one, or ``$QUATFORM_XLA_OPTIONS=off``, leaves XLA's
    choice; another backend gets none. A compiled program with them computes as without them."""
    import jax
    import jax.numpy as jnp

    if jax.default_backend() != "cpu":
        pytest.skip("the options are the CPU's")
    try:
        jax.jit(lambda: 0.0, compiler_options=jax_devices.CPU_COMPILER_OPTIONS).lower().compile()
        known = True
    except Exception:
        known = False
    assert options_of(monkeypatch, jax) == (jax_devices.CPU_COMPILER_OPTIONS if known else {})
    assert options_of(monkeypatch, jax, "--xla_cpu_experimental_ynn_fusion_type=LIBRARY_FUSION_TYPE_REDUCE") == {}
    monkeypatch.setenv(jax_devices.OPTIONS_ENV, "off")
    assert options_of(monkeypatch, jax) == {}
    monkeypatch.delenv(jax_devices.OPTIONS_ENV)

    def refusing(*args, **kwargs):
        raise RuntimeError("INVALID_ARGUMENT: No such compile option")

    monkeypatch.setattr(jax_devices, "configure", lambda jax: None)  # a fake JAX has no settings
    monkeypatch.setattr(jax_devices, "_ACCEPTED", [None])
    assert jax_devices.compiler_options(SimpleNamespace(default_backend=lambda: "cpu", jit=refusing)) == {}
    monkeypatch.setattr(jax_devices, "_ACCEPTED", [None])
    assert jax_devices.compiler_options(SimpleNamespace(default_backend=lambda: "gpu", jit=refusing)) == {}
    x = jnp.asarray([[0.1, 0.2, 0.3], [1.0, -2.0, 4.0]], dtype=jnp.float32)
    f = lambda a: jnp.sum(a[:, :, None] * a[:, None, :], axis=1)  # noqa: E731
    assert jnp.allclose(jax.jit(f, compiler_options=options_of(monkeypatch, jax))(x), jax.jit(f)(x), rtol=1e-6)


def test_jit_passes_options_only_where_there_are_some(monkeypatch):
    """``jax_devices.jit`` gives ``jax.jit`` the options where there are some, none otherwise (a
    JAX whose ``jit`` has no ``compiler_options`` keyword compiles too)."""
    seen = []

    def jit(fn, **kwargs):
        seen.append(kwargs)
        return fn

    fake = SimpleNamespace(jit=jit)
    monkeypatch.setattr(jax_devices, "_ACCEPTED", [{}])
    assert jax_devices.jit(fake, abs)(-2) == 2 and seen[-1] == {}
    monkeypatch.setattr(jax_devices, "_ACCEPTED", [dict(jax_devices.CPU_COMPILER_OPTIONS)])
    jax_devices.jit(fake, abs)
    assert seen[-1] == {"compiler_options": jax_devices.CPU_COMPILER_OPTIONS}
