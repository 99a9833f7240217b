"""``quatform sweep SPEC --out DIR`` and ``quatform sweeps`` (registered by :mod:`quatform.cli`).

Sweeps layer. :func:`sweep_arguments` and :func:`sweeps_arguments` fill in the two
subcommands' parsers (the CLI names them); :func:`sweep_command` and :func:`sweeps_command`
run them.
"""

from __future__ import annotations

import sys

__all__ = ["sweep_arguments", "sweeps_arguments", "sweep_command", "sweeps_command"]

#: Most cells the summary printed on stdout shows (all are in summary.csv).
_MAX_PRINTED = 60


def sweep_arguments(p) -> None:
    """The description and options of ``quatform sweep`` on its parser ``p``."""
    import argparse

    from ..sim.backends import SIM_BACKENDS
    from .spec import PARAMETERS

    p.formatter_class = argparse.RawDescriptionHelpFormatter
    p.description = (
        "Run a sweep spec (docs/sweeps.md): every trial of every cell, batched, resumable. Writes\n"
        "results.csv/json or Parquet shards trials/*.parquet (a row per trial), summary.csv/json (a\n"
        "row per cell) and figures/ into --out; a rerun into the same --out skips the chunks already\n"
        "stored. Progress on stderr.")
    p.epilog = "parameters a spec's [vary] may hold:\n" + "\n".join(
        f"  {name} ({q.unit}){'' if q.kinds is None else ' [' + ', '.join(q.kinds) + ' only]'}: {q.help}"
        for name, q in PARAMETERS.items())
    p.add_argument("spec", metavar="SPEC", help="built-in sweep name (see 'quatform sweeps') or file.toml")
    p.add_argument("--out", metavar="DIR", required=True, help="output folder (resumed when it holds this sweep)")
    p.add_argument("--trials", type=int, metavar="K", help="trials per cell instead of the spec's (a quick look)")
    p.add_argument("--backend", "--compute", dest="backend", default="numpy",
                   help=f"compute backend: {' or '.join(SIM_BACKENDS)} (jax: pip install -e \".[jax]\"); "
                   "--compute is the same flag, as 'quatform run' names it")
    p.add_argument("--workers", type=int, default=1, metavar="N",
                   help="local processes, or Dask workers with --scheduler local (default 1: in this process)")
    p.add_argument("--scheduler", metavar="ADDR",
                   help="Dask: local (a LocalCluster), tcp://HOST:PORT (join one) or slurm (dask-jobqueue, the "
                        "spec's [slurm] table and --slurm); pip install -e \".[dask]\"")
    p.add_argument("--slurm", action="append", default=[], metavar="KEY=VALUE",
                   help="a dask-jobqueue SLURMCluster option (queue, account, cores, memory, walltime, jobs ...)")
    p.add_argument("--print-job-script", action="store_true",
                   help="with --scheduler slurm: print the job script dask-jobqueue would submit, run nothing")
    p.add_argument("--results", metavar="FORMAT",
                   help="csv (results.csv/json), parquet (trials/*.parquet, one shard per chunk; pyarrow: pip install "
                        "-e \".[dask]\") or both; default the spec's results, else the one --out's sweep was started "
                        "with, else csv up to 100,000 trials (cells x trials) and parquet above")
    p.add_argument("--no-plots", action="store_true", help="write the tables only")
    p.add_argument("--quiet", action="store_true", help="no progress lines")


def sweeps_arguments(p) -> None:
    """The description of ``quatform sweeps`` on its parser ``p``."""
    p.description = "List the built-in sweep specs with their titles and sources."


def _slurm_options(spec, pairs) -> dict:
    from ..checks import check_keys
    from ..errors import InvalidInputError
    from .spec import SLURM_KEYS, check_slurm

    opts = dict(spec.slurm)
    for pair in pairs:
        key, sep, value = pair.partition("=")
        if not sep:
            raise InvalidInputError(f"--slurm {pair!r}: give KEY=VALUE (e.g. --slurm queue=normal)")
        check_keys({key: value}, SLURM_KEYS, "--slurm", "the options", "see docs/sweeps.md")
        opts[key] = int(value) if value.isdigit() else value
    check_slurm(opts, "--slurm / [slurm]")
    return opts


def sweep_command(args) -> None:
    from dataclasses import replace

    from ..errors import InvalidInputError
    from .executors import check_scheduler, slurm_job_script
    from .results import results_mode
    from .runner import run_sweep
    from ..sim.output import check_inputs_outside
    from .spec import load_sweep

    if not args.out.strip():
        raise InvalidInputError(f"--out {args.out!r} is empty; give a folder (e.g. --out runs/sweep)")
    check_inputs_outside(args.out, args.spec)  # a spec file inside --out: refused before any work
    if args.trials is not None and args.trials < 1:
        raise InvalidInputError(f"--trials {args.trials} must be >= 1")
    check_scheduler(args.scheduler)  # Dask missing: one line before the spec's experiments are built
    spec = load_sweep(args.spec, trials=args.trials)
    if args.slurm or args.scheduler == "slurm":
        spec = replace(spec, slurm=_slurm_options(spec, args.slurm))
    if args.print_job_script:
        if args.scheduler != "slurm":
            raise InvalidInputError("--print-job-script goes with --scheduler slurm")
        print(slurm_job_script(spec.slurm))
        return
    summary = run_sweep(spec, args.out, backend=args.backend, workers=args.workers, scheduler=args.scheduler,
                        plots=not args.no_plots, quiet=args.quiet, results=args.results)
    key = spec.compare_key
    names = [a.name for a in spec.axes]
    print(f"{key:16s} " + " ".join(f"{n:>18s}" for n in names) + f" {'trials':>7s} {'failed':>7s} {'success':>8s}")
    for s in summary[:_MAX_PRINTED]:
        vals = " ".join(f"{s[n]:18.4g}" for n in names)
        print(f"{s[key]:16s} {vals} {s['trials']:7d} {s['failed']:7d} {s['success_rate']:8.2f}")
    if len(summary) > _MAX_PRINTED:
        print(f"... {len(summary) - _MAX_PRINTED} more cells in summary.csv")
    mode = results_mode(spec, args.results, args.out)
    tables = {"csv": "results.csv/json", "parquet": "trials/*.parquet", "both": "results.csv/json, trials/*.parquet"}
    print(f"\nfiles in {args.out}/: {tables[mode]}, summary.csv/json" + ("" if args.no_plots else ", figures/"),
          file=sys.stdout)


def sweeps_command(args) -> None:
    from ..tomlio import read_toml
    from .spec import builtin_sweeps

    files = builtin_sweeps()
    for name in sorted(files):
        data, _ = read_toml(name, files, "sweep")
        print(f"{name:32s} {data.get('title', '')} ({data.get('source', '')})")
