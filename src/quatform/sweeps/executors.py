"""Where a sweep's chunks run: in process, local processes, Dask (local, a cluster, SLURM).

Sweeps layer. :func:`executor` yields a :class:`concurrent.futures.Executor` (or None: run
in this process, one chunk after another). Dask and dask-jobqueue are optional
(``pip install -e ".[dask]"``), imported only here and only when asked for. A trial's result
does not depend on where it ran (its random numbers come from its own seed, the chunks are
fixed by the spec), so every executor gives the same table.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import signal
from concurrent.futures import ProcessPoolExecutor

from ..checks import nearest
from ..errors import InvalidInputError, MissingDependencyError, ResourceLimitError, UnreachableError
from ..sim.jax_devices import share_cores, usable_cores

__all__ = ["executor", "check_scheduler", "SCHEDULERS", "slurm_cluster", "slurm_job_script", "CONNECT_TIMEOUT_S",
           "LOCAL_WORKERS_PER_CORE", "parallel_workers"]

#: Named schedulers (besides ``tcp://HOST:PORT``).
SCHEDULERS = ("local", "slurm")
#: How long joining a cluster may take before its address is called unreachable, s.
CONNECT_TIMEOUT_S = 5.0
#: Most local worker processes (a pool or a Dask LocalCluster) per usable core: beyond the
#: cores they only add memory (each imports quatform, NumPy and perhaps JAX), and a huge
#: --workers would start that many processes.
LOCAL_WORKERS_PER_CORE = 4


def parallel_workers(workers: int, scheduler: str | None) -> int:
    """How many chunks can run at once: local workers are bounded by this machine's usable
    cores; a cluster's (``tcp://``, ``slurm``) are taken as given."""
    return min(workers, usable_cores()) if scheduler in (None, "local") else workers


def _import(module: str, scheduler: str = "slurm"):
    try:
        return __import__(module, fromlist=["_"])
    except ImportError:
        what = "dask-jobqueue" if module == "dask_jobqueue" else "Dask (its distributed package)"
        raise MissingDependencyError(f"--scheduler {scheduler} needs {what}, which is not installed here: "
                                     'pip install -e ".[dask]" (or leave --scheduler out to run on this machine)'
                                     ) from None


def _modules(scheduler: str) -> tuple:
    """The optional modules the ``--scheduler`` needs (one line for an unknown one)."""
    if scheduler not in SCHEDULERS and not scheduler.startswith("tcp://"):
        raise InvalidInputError(f"--scheduler {scheduler!r} unknown{nearest(scheduler, SCHEDULERS)}; give local, "
                                "slurm or tcp://HOST:PORT")
    return ("distributed", "dask_jobqueue") if scheduler == "slurm" else ("distributed",)


def check_scheduler(scheduler: str | None) -> None:
    """Refuse (one line naming ``pip install -e ".[dask]"``) a ``--scheduler`` that is unknown or
    whose Dask packages are not importable, before any experiment is built."""
    if scheduler is not None:
        for module in _modules(scheduler):
            _import(module, scheduler)


def slurm_cluster(options: dict):
    """A dask-jobqueue ``SLURMCluster`` with the ``[slurm]`` options (``jobs`` is how many to
    submit, not a cluster keyword; ``cores`` defaults to 1, ``memory`` to 4 GB, ``processes`` to
    ``cores``)."""
    jq = _import("dask_jobqueue")
    opts = {k: v for k, v in options.items() if k != "jobs"}
    opts.setdefault("cores", 1)
    opts.setdefault("memory", "4GB")
    opts.setdefault("processes", opts["cores"])
    try:
        return jq.SLURMCluster(**opts)
    except (TypeError, ValueError) as exc:
        raise InvalidInputError(f"[slurm] options {sorted(opts)}: {' '.join(str(exc).split())}") from None


def slurm_job_script(options: dict) -> str:
    """The batch script dask-jobqueue submits for each SLURM job of ``options`` (what
    ``quatform sweep ... --scheduler slurm --print-job-script`` shows)."""
    cluster = slurm_cluster(options)
    try:
        return cluster.job_script()
    finally:
        cluster.close()


def _worker_setup(processes: int) -> None:
    """In each local worker: JAX's CPU devices shared (:func:`share_cores`), and Ctrl-C left to
    the sweep's own process, which stops the workers (a terminal's Ctrl-C reaches the whole
    process group: the workers printed their tracebacks)."""
    share_cores(processes)
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _process_context():
    """Worker processes started clean: ``forkserver`` where the platform has it, else
    ``spawn``; never a bare ``fork`` of this process, which may hold JAX's (or BLAS's) threads
    and deadlock in the child (Python's own warning for JAX)."""
    methods = multiprocessing.get_all_start_methods()
    return multiprocessing.get_context("forkserver" if "forkserver" in methods else "spawn")


@contextlib.contextmanager
def executor(workers: int = 1, scheduler: str | None = None, slurm: dict | None = None,
             timeout_s: float = CONNECT_TIMEOUT_S):
    """The executor of ``--workers`` / ``--scheduler`` (None: in this process).

    Parameters
    ----------
    workers : int
        Local processes (no scheduler), Dask workers of a ``local`` cluster, SLURM jobs.
    scheduler : str, optional
        ``local`` (a ``LocalCluster`` of ``workers`` one-thread processes), ``tcp://HOST:PORT``
        (join a running scheduler, at most ``timeout_s`` to reach it) or ``slurm``
        (dask-jobqueue, the ``slurm`` options).
    """
    if not isinstance(workers, int) or workers < 1:
        raise InvalidInputError(f"--workers {workers!r} must be a whole number >= 1")
    cores = usable_cores()
    if scheduler in (None, "local") and workers > LOCAL_WORKERS_PER_CORE * cores:
        raise ResourceLimitError(f"--workers {workers}: this machine has {cores} usable core(s), and more than "
                                 f"{LOCAL_WORKERS_PER_CORE * cores} local worker processes only add memory; give "
                                 f"--workers {cores}, or run on a cluster (--scheduler tcp://HOST:PORT or slurm)")
    if scheduler is None:
        if workers == 1:
            yield None
            return
        before = set(multiprocessing.active_children())
        pool = ProcessPoolExecutor(max_workers=workers, mp_context=_process_context(), initializer=_worker_setup,
                                   initargs=(workers,))
        try:
            yield pool
        except BaseException:
            # Ctrl-C or an error: the queued chunks dropped and the workers stopped now (waiting for
            # the running chunks could hang the exit; a chunk cut off is not stored, a rerun runs it)
            # (not cancel_futures: Python 3.11's pool then fails setting BrokenProcessPool on them)
            pool.shutdown(wait=False)
            for proc in set(multiprocessing.active_children()) - before:
                proc.terminate()
            raise
        pool.shutdown(wait=True)
        return
    _modules(scheduler)
    distributed = _import("distributed", scheduler)
    with contextlib.ExitStack() as stack:
        if scheduler == "local":
            cluster = stack.enter_context(distributed.LocalCluster(n_workers=workers, threads_per_worker=1,
                                                                   processes=True, dashboard_address=None))
            client = stack.enter_context(distributed.Client(cluster))
            client.run(_worker_setup, workers)  # this machine's cores shared by its workers; Ctrl-C is ours
        elif scheduler == "slurm":
            cluster = stack.enter_context(slurm_cluster(dict(slurm or {})))
            cluster.scale(jobs=int((slurm or {}).get("jobs", workers)))
            client = stack.enter_context(distributed.Client(cluster))
        else:
            try:
                client = distributed.Client(scheduler, timeout=f"{timeout_s}s")
            except ValueError as exc:
                raise InvalidInputError(f"--scheduler {scheduler}: not a scheduler address ({exc}); give "
                                        "tcp://HOST:PORT") from None
            except (OSError, TimeoutError) as exc:
                raise UnreachableError(f"--scheduler {scheduler}: no Dask scheduler answered within {timeout_s:g} s "
                                       f"({type(exc).__name__}); start one (dask scheduler) or check the address"
                                       ) from None
            except Exception as exc:  # something else answered: its bytes are no Dask handshake
                raise UnreachableError(f"--scheduler {scheduler}: what answered there is not a Dask scheduler (its "
                                       f"reply failed the handshake: {type(exc).__name__}); check the address and "
                                       "port (dask scheduler listens on 8786)") from None
            stack.enter_context(client)
        yield client.get_executor()
