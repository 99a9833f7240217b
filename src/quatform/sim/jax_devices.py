"""The batch of worlds spread over JAX's devices: every CPU core or every GPU (sim layer).

A compiled rollout is elementwise along its batch of worlds (no world reads another), so
the batch splits over devices without communication: each device runs the same compiled
tick on its slice. JAX's CPU backend offers one device unless told otherwise, and one
device runs an XLA loop on one core; :func:`configure` asks for one CPU device per usable
core before JAX starts its backends (where the user has not chosen a number: the
``jax_num_cpu_devices`` setting or ``XLA_FLAGS=--xla_force_host_platform_device_count``),
so a 2-core laptop runs two slices at once. On a GPU machine the devices are the GPUs.

:func:`place` puts a chunk's arrays on the devices: the batch axis sharded
(``jax.sharding.NamedSharding`` over a one-axis mesh), everything else replicated. The
arithmetic of each world is that of one device, so the results equal the unsharded run
(tests: to 1e-9 of NumPy, and sharded equal to unsharded). :func:`shardable` says whether a
compiled scan may be sharded on the CPU at all: a loop in the tick (the separation barrier's
solver, which iterates while any world of the batch does: an all-reduce across the devices
at every iteration) or a LAPACK call on matrices larger than 4 x 4 (the barrier's batched
solves, the singularity measure's SVD) can stall for good with the batch over several CPU
devices (docs/performance.md, "Sharded scans"), so such a scan runs on one device.

:func:`chunk_size` picks how many worlds one compiled call runs. On the CPU a chunk of a
few hundred worlds per device keeps a tick's working set (tens of arrays of the chunk's
length) in cache and bounds the memory of a large batch; on this project's 2-core machine
two devices run the helix rollouts 1.4-1.7x the rate of one, and chunks of a few hundred
worlds per device run 1.1x one call of 10^4 worlds (docs/performance.md, "JAX"). On an accelerator one call takes the whole batch.

:func:`compiler_options` gives the ``jax.jit`` options of a compiled tick: on the CPU, XLA's
YNNPACK fusions off where its XLA has them (jaxlib 0.10.2 hands each small fused operation to a
library call: the quaternion and robot-space teams' ticks run 1.3-2x slower with them,
docs/performance.md); ``QUATFORM_XLA_OPTIONS=off`` keeps XLA's defaults.

:func:`configure` also keeps JAX's compiled programs on disk (JAX's persistent compilation
cache) in a folder of this user's (:func:`cache_dir`: ``$QUATFORM_JAX_CACHE``, else
``$XDG_CACHE_HOME/quatform/jax``, else ``~/.cache/quatform/jax``; ``QUATFORM_JAX_CACHE=off``
keeps none), unless the user set JAX's own ``jax_compilation_cache_dir``: a sweep's worker
processes, a resumed sweep and a rerun then load a configuration's compiled tick instead of
compiling it again (about 1 s each for seed 000's two robots, more for large teams). A loaded
program is the one compiled before (JAX keys it by the program, the devices and its own
version), so the floats are the same. The folder is trusted code (a program read from it
runs): it is created readable by this user alone.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

__all__ = ["CACHE_ENV", "CPU_COMPILER_OPTIONS", "CPU_WORLDS_PER_DEVICE", "OPTIONS_ENV", "batch_devices", "cache_dir",
           "LAPACK_PRIMITIVES", "SHARDABLE_LAPACK_SIZE", "chunk_size", "compiler_options", "configure", "jit", "place",
           "program_hazards", "shardable", "share_cores", "usable_cores"]

#: Environment variable naming the folder of the compiled programs (``off``: keep none).
CACHE_ENV = "QUATFORM_JAX_CACHE"

#: XLA options of quatform's compiled ticks on the CPU (:func:`compiler_options`): XLA's YNNPACK
#: fusions off. jaxlib 0.10.2's XLA hands chains of small reductions and elementwise
#: operations to YNNPACK, one library call per fusion; a tick is a few hundred such operations on
#: arrays of a few hundred worlds, and the calls cost more than the work (docs/performance.md,
#: "XLA's YNNPACK fusions": the quaternion and robot-space teams' ticks 1.3-2x slower).
CPU_COMPILER_OPTIONS = {"xla_cpu_experimental_ynn_fusion_type": ""}

#: Environment variable: ``off`` compiles with XLA's own defaults (no :data:`CPU_COMPILER_OPTIONS`).
OPTIONS_ENV = "QUATFORM_XLA_OPTIONS"

#: The options :func:`compiler_options` found this process's XLA to accept (None: not yet asked).
_ACCEPTED: list = [None]

#: Worlds per CPU device in one compiled call (the cache-sized chunk; docs/performance.md).
CPU_WORLDS_PER_DEVICE = 256


def usable_cores() -> int:
    """The CPU cores this process may run on (its affinity mask where the OS has one)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # macOS, Windows
        return max(1, os.cpu_count() or 1)


#: Processes of this machine sharing its cores for JAX (:func:`share_cores`; 1: this one alone).
_SHARERS = [1]


def share_cores(processes: int) -> None:
    """Say that ``processes`` worker processes (a sweep's ``--workers``) share this machine's
    cores: :func:`configure` then asks for ``usable_cores() // processes`` CPU devices (at
    least one) in each, not one per core in every worker. A process pool's initializer."""
    _SHARERS[0] = max(1, int(processes))


def cache_dir() -> Path | None:
    """The folder of JAX's compiled programs (module docstring): ``$QUATFORM_JAX_CACHE``
    (None when it is ``off``, ``none``, ``0`` or empty), else ``quatform/jax`` in
    ``$XDG_CACHE_HOME`` or ``~/.cache``."""
    value = os.environ.get(CACHE_ENV)
    if value is not None:
        return None if value.strip().lower() in ("", "off", "none", "0") else Path(value).expanduser()
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "quatform" / "jax"


def _keep_compiled(jax) -> None:
    """Point JAX's persistent compilation cache at :func:`cache_dir` (every program kept,
    however quick its compilation), unless the user set JAX's own folder or asked for none;
    a folder that cannot be made leaves compilation as it was."""
    if getattr(jax.config, "jax_compilation_cache_dir", None):  # the user's own cache
        return
    path = cache_dir()
    if path is None:
        return
    try:
        path.mkdir(mode=0o700, parents=True, exist_ok=True)
    except OSError:  # read-only home, a file in the way: compile every time
        return
    jax.config.update("jax_compilation_cache_dir", str(path))
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)


def configure(jax) -> None:
    """Ask JAX for one CPU device per usable core (per core of this process's share,
    :func:`share_cores`), unless the user chose a number or JAX's backends already run (the
    setting is read once, when they start; then nothing changes); keep compiled programs on
    disk (:func:`cache_dir`)."""
    _keep_compiled(jax)
    chosen = getattr(jax.config, "jax_num_cpu_devices", None)  # None: a JAX without the setting
    if chosen is None or chosen != -1 or "xla_force_host_platform_device_count" in os.environ.get("XLA_FLAGS", ""):
        return
    try:
        jax.config.update("jax_num_cpu_devices", max(1, usable_cores() // _SHARERS[0]))
    except RuntimeError:  # JAX already ran something: its devices stay as they are
        pass


def compiler_options(jax) -> dict:
    """The ``compiler_options`` of ``jax.jit`` for a compiled tick: :data:`CPU_COMPILER_OPTIONS`
    where JAX's default backend is the CPU, its XLA knows the options (asked once per process
    by compiling a constant), ``XLA_FLAGS`` does not set them itself and ``$QUATFORM_XLA_OPTIONS``
    is not ``off`` (XLA's defaults: to compare, or should a later XLA make them slower); else
    none. The options choose how XLA emits the program, not its arithmetic: a world's floats
    are those of the default emitters up to the order of a fused sum's rounding (tests: to 1e-9
    of NumPy). Asking starts JAX's backends: :func:`configure` runs first."""
    if _ACCEPTED[0] is None:
        configure(jax)
        flags = os.environ.get("XLA_FLAGS", "")
        wanted = os.environ.get(OPTIONS_ENV, "").strip().lower() != "off"
        accepted = {}
        if wanted and jax.default_backend() == "cpu" and not any(k in flags for k in CPU_COMPILER_OPTIONS):
            try:
                jax.jit(lambda: 0.0, compiler_options=CPU_COMPILER_OPTIONS).lower().compile()
                accepted = dict(CPU_COMPILER_OPTIONS)
            except Exception:  # an XLA without them (JAX's own error type varies by release)
                accepted = {}
        _ACCEPTED[0] = accepted
    return dict(_ACCEPTED[0])


def jit(jax, fn):
    """``jax.jit(fn)`` with :func:`compiler_options` (none passed where there are none, so a
    JAX whose ``jit`` has no ``compiler_options`` compiles it too)."""
    options = compiler_options(jax)
    return jax.jit(fn, compiler_options=options) if options else jax.jit(fn)


#: JAX primitives that run a LAPACK (or BLAS) routine on the CPU, per matrix of a batch.
LAPACK_PRIMITIVES = frozenset({"cholesky", "eig", "eigh", "geqp3", "geqrf", "hessenberg", "householder_product",
                               "lu", "qr", "schur", "svd", "triangular_solve", "tridiagonal", "tridiagonal_solve"})

#: The largest matrix (rows or columns) a LAPACK call of a sharded CPU scan may take: Horn's
#: 4 x 4 eigensolve ran 150 scans and 34 rollouts without a stall; solves of 16 x 16 and SVDs
#: of 8 x 16 stalled (docs/performance.md, "Sharded scans").
SHARDABLE_LAPACK_SIZE = 4

def program_hazards(closed_jaxpr) -> tuple[bool, int]:
    """``(loops, size)`` of a traced program (a ``ClosedJaxpr`` or ``Jaxpr``, sub-programs
    included): whether it holds a ``while`` loop, and the largest matrix dimension a
    :data:`LAPACK_PRIMITIVES` call takes (0: none)."""
    loops, size = False, 0
    stack = [closed_jaxpr]
    while stack:
        j = stack.pop()
        j = getattr(j, "jaxpr", j)
        for eqn in j.eqns:
            name = eqn.primitive.name
            loops = loops or name == "while"
            if name in LAPACK_PRIMITIVES:
                dims = [d for v in eqn.invars for d in getattr(getattr(v, "aval", None), "shape", ())[-2:]]
                size = max([size, *dims])
            for value in eqn.params.values():
                for sub in value if isinstance(value, (tuple, list)) else (value,):
                    if hasattr(sub, "eqns") or hasattr(getattr(sub, "jaxpr", None), "eqns"):
                        stack.append(sub)
    return loops, size


def shardable(jax, run, carry, xs) -> bool:
    """Whether the jitted scan ``run(carry, xs)`` may run with its batch sharded over JAX's
    devices: always on one device or an accelerator; on several CPU devices only when its
    program (traced here: :func:`quatform.sim.loop.scan_ticks` keeps the answer per ``run`` and
    input layout) holds no ``while`` loop and no LAPACK call on matrices larger than
    :data:`SHARDABLE_LAPACK_SIZE` (:func:`program_hazards`)."""
    devices = batch_devices(jax)
    if len(devices) == 1 or devices[0].platform != "cpu":
        return True
    loops, size = program_hazards(jax.make_jaxpr(getattr(run, "__wrapped__", run))(carry, xs))
    return not loops and size <= SHARDABLE_LAPACK_SIZE


def batch_devices(jax) -> list:
    """The devices a batch is spread over: those of JAX's default backend."""
    return list(jax.devices())


def chunk_size(jax, worlds: int, per_call: int | None = None) -> int:
    """Worlds per compiled call: ``per_call`` when given, else the whole batch on an
    accelerator and :data:`CPU_WORLDS_PER_DEVICE` per CPU device; rounded up to a multiple
    of the device count (each device gets an equal slice) and at most the batch so rounded."""
    devices = batch_devices(jax)
    n = len(devices)
    if per_call is None:
        per_call = CPU_WORLDS_PER_DEVICE * n if devices[0].platform == "cpu" else worlds
    size = max(1, min(int(per_call), worlds))
    return -(-size // n) * n


def place(jax, arrays: dict, batch_axes: dict) -> dict:
    """``arrays`` on the devices: ``arrays[k]`` sharded along ``batch_axes[k]`` (its batch
    axis; its length a multiple of the device count), replicated when ``k`` has none. On one
    device the arrays are returned as they are (JAX copies them on the call)."""
    devices = batch_devices(jax)
    if len(devices) == 1:
        return arrays
    from jax.sharding import Mesh, NamedSharding, PartitionSpec

    mesh = Mesh(np.array(devices), ("batch",))
    out = {}
    for key, a in arrays.items():
        axis = batch_axes.get(key)
        spec = PartitionSpec() if axis is None else PartitionSpec(*([None] * axis + ["batch"]))
        out[key] = jax.device_put(a, NamedSharding(mesh, spec))
    return out
