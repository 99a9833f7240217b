"""Speed of quatform's algebra layer next to pytransform3d, dqrobotics and numpy-quaternion.

For each operation (quaternion product, log, exp, power 0.5; dual-quaternion product,
log, exp, power 0.5, both the screw and the decoupled forms) the script measures

* the **single-call** time: microseconds for one call on one (dual) quaternion, the way
  each library is used on a single value (``(4,)``/``(8,)`` arrays for quatform and
  pytransform3d, ``DQ`` objects for dqrobotics, ``quaternion`` scalars for
  numpy-quaternion);
* the **batch** time: nanoseconds per element for one call on ``N`` elements (default
  100 000) through the library's vectorised API. dqrobotics has no batch API: its batch
  cell is a plain Python loop over ``DQ`` objects, timed on a smaller ``N`` (default 2000)
  and marked ``L``.

A library that lacks an operation gets ``-``; the footnotes name the function timed in
every peer cell and say why a cell is empty. Inputs are random unit (dual) quaternions
from ``numpy.random.default_rng(0)``, converted to each library's types before timing.
Every time is the best of several repeats of a ``time.perf_counter``-timed loop, as in
:mod:`timeit`.

Run it from the repository root::

    python benchmarks/bench_algebra.py            # N = 100 000, 7 repeats (~2.5 min)
    python benchmarks/bench_algebra.py --quick    # 3 shorter repeats
    python benchmarks/bench_algebra.py --n 1000000
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass
from types import SimpleNamespace
from typing import Callable

import numpy as np
import quatform.algebra as qa

from _common import best_time, fmt, machine_description, optional_import

pr = optional_import("pytransform3d.rotations")
pbr = optional_import("pytransform3d.batch_rotations")
pt = optional_import("pytransform3d.transformations")
ptr = optional_import("pytransform3d.trajectories")
dqr = optional_import("dqrobotics")
npq = optional_import("quaternion")

#: Table columns: distribution name and whether it is importable.
LIBRARIES = {
    "quatform": True,
    "pytransform3d": pr is not None,
    "dqrobotics": dqr is not None,
    "numpy-quaternion": npq is not None,
}

#: Column headings.
HEADINGS = {
    "quatform": "quatform",
    "pytransform3d": "pt3d",
    "dqrobotics": "dqrobotics",
    "numpy-quaternion": "np-quat",
}

#: Table rows, in order.
OPERATIONS = (
    "q product",
    "q log",
    "q exp",
    "q pow 0.5",
    "dq product",
    "dq log (screw)",
    "dq exp (screw)",
    "dq pow 0.5 (screw)",
    "dq log (decoupled)",
    "dq exp (decoupled)",
    "dq pow 0.5 (decoupled)",
)


@dataclass
class Cell:
    """What is timed for one operation of one library.

    Attributes
    ----------
    note : str
        The function(s) timed, or why there is nothing to time; printed as a footnote.
    single : callable or None
        One call on one element.
    batch : callable or None
        One call (or loop) over ``batch_n`` elements.
    batch_n : int
        Number of elements ``batch`` processes.
    loop : bool
        ``batch`` is a Python loop rather than a vectorised call.
    """

    note: str
    single: Callable[[], object] | None = None
    batch: Callable[[], object] | None = None
    batch_n: int = 0
    loop: bool = False


def make_inputs(n: int, seed: int = 0) -> SimpleNamespace:
    """Random unit quaternions and dual quaternions and their logarithms.

    Parameters
    ----------
    n : int
        Number of elements.
    seed : int
        Seed for :func:`numpy.random.default_rng`.

    Returns
    -------
    SimpleNamespace
        ``q1, q2`` (n, 4) unit quaternions, ``qlog`` (n, 4) their pure logarithms,
        ``d1, d2`` (n, 8) unit dual quaternions (translations ~ N(0, 1)), ``dlog`` and
        ``dlog_dec`` (n, 8) the screw and decoupled logarithms of ``d1``.
    """
    rng = np.random.default_rng(seed)

    def unit(shape):
        q = rng.normal(size=shape)
        return q / np.linalg.norm(q, axis=-1, keepdims=True)

    q1, q2 = unit((n, 4)), unit((n, 4))
    d1 = qa.dq_from_pose(unit((n, 4)), rng.normal(size=(n, 3)))
    d2 = qa.dq_from_pose(unit((n, 4)), rng.normal(size=(n, 3)))
    return SimpleNamespace(
        q1=q1, q2=q2, qlog=qa.qlog(q1), d1=d1, d2=d2,
        dlog=qa.dqlog(d1), dlog_dec=qa.dqlog_decoupled(d1),
    )


def quatform_cells(x: SimpleNamespace, n_loop: int) -> dict[str, Cell]:
    """Cells for quatform: (4,)/(8,) arrays for one call, (N, 4)/(N, 8) arrays for a batch."""
    del n_loop  # quatform is vectorised
    n = len(x.q1)
    a, b, lg, d, e, h, hd = x.q1[0], x.q2[0], x.qlog[0], x.d1[0], x.d2[0], x.dlog[0], x.dlog_dec[0]
    return {
        "q product": Cell("qmul", lambda: qa.qmul(a, b), lambda: qa.qmul(x.q1, x.q2), n),
        "q log": Cell("qlog", lambda: qa.qlog(a), lambda: qa.qlog(x.q1), n),
        "q exp": Cell("qexp", lambda: qa.qexp(lg), lambda: qa.qexp(x.qlog), n),
        "q pow 0.5": Cell("qpow", lambda: qa.qpow(a, 0.5), lambda: qa.qpow(x.q1, 0.5), n),
        "dq product": Cell("dqmul", lambda: qa.dqmul(d, e), lambda: qa.dqmul(x.d1, x.d2), n),
        "dq log (screw)": Cell("dqlog", lambda: qa.dqlog(d), lambda: qa.dqlog(x.d1), n),
        "dq exp (screw)": Cell("dqexp", lambda: qa.dqexp(h), lambda: qa.dqexp(x.dlog), n),
        "dq pow 0.5 (screw)": Cell(
            "dqpow", lambda: qa.dqpow(d, 0.5), lambda: qa.dqpow(x.d1, 0.5), n
        ),
        "dq log (decoupled)": Cell(
            "dqlog_decoupled", lambda: qa.dqlog_decoupled(d), lambda: qa.dqlog_decoupled(x.d1), n
        ),
        "dq exp (decoupled)": Cell(
            "dqexp_decoupled",
            lambda: qa.dqexp_decoupled(hd),
            lambda: qa.dqexp_decoupled(x.dlog_dec),
            n,
        ),
        "dq pow 0.5 (decoupled)": Cell(
            "dqpow_decoupled",
            lambda: qa.dqpow_decoupled(d, 0.5),
            lambda: qa.dqpow_decoupled(x.d1, 0.5),
            n,
        ),
    }


def pytransform3d_cells(x: SimpleNamespace, n_loop: int) -> dict[str, Cell]:
    """Cells for pytransform3d: its single-element functions and its batch_* / trajectories ones."""
    del n_loop  # pytransform3d is vectorised where it has a batch function
    n = len(x.q1)
    a, b, d, e = x.q1[0], x.q2[0], x.d1[0], x.d2[0]
    identity = np.array([1.0, 0.0, 0.0, 0.0])
    halves = np.full(n, 0.5)
    no_log = (
        "- : no quaternion log/exp; compact_axis_angle_from_quaternion and "
        "quaternion_from_compact_axis_angle fold the angle into [0, pi] (w >= 0), so they "
        "differ from the algebraic log/exp for half of the inputs, and have no batch form"
    )
    return {
        "q product": Cell(
            "rotations.concatenate_quaternions / batch_rotations.batch_concatenate_quaternions",
            lambda: pr.concatenate_quaternions(a, b),
            lambda: pbr.batch_concatenate_quaternions(x.q1, x.q2),
            n,
        ),
        "q log": Cell(no_log),
        "q exp": Cell(no_log),
        "q pow 0.5": Cell(
            "rotations.quaternion_slerp(identity, q, 0.5, shortest_path=False) (= q^0.5); "
            "batch - : batch_rotations.quaternion_slerp_batch batches over t for one "
            "quaternion pair, not over N quaternions",
            lambda: pr.quaternion_slerp(identity, a, 0.5, shortest_path=False),
        ),
        "dq product": Cell(
            "transformations.concatenate_dual_quaternions(unit=False) / "
            "trajectories.batch_concatenate_dual_quaternions (unit=True, the default, "
            "would also renormalise the inputs)",
            lambda: pt.concatenate_dual_quaternions(d, e, unit=False),
            lambda: ptr.batch_concatenate_dual_quaternions(x.d1, x.d2),
            n,
        ),
        "dq log (screw)": Cell(
            "- : no dual-quaternion log (screw_parameters_from_dual_quaternion returns "
            "(point, axis, pitch, angle), not a dual quaternion)"
        ),
        "dq exp (screw)": Cell("- : no dual-quaternion exp"),
        "dq pow 0.5 (screw)": Cell(
            "transformations.dual_quaternion_power / trajectories.dual_quaternions_power "
            "(screw power; folds the sign of the input, like quatform dqpow(shortest=True))",
            lambda: pt.dual_quaternion_power(d, 0.5),
            lambda: ptr.dual_quaternions_power(x.d1, halves),
            n,
        ),
    }


def dqrobotics_cells(x: SimpleNamespace, n_loop: int) -> dict[str, Cell]:
    """Cells for dqrobotics: methods of ``DQ`` objects; its batch cells are Python loops."""
    DQ = dqr.DQ
    q1 = [DQ(v) for v in x.q1[:n_loop]]
    q2 = [DQ(v) for v in x.q2[:n_loop]]
    ql = [DQ(v) for v in x.qlog[:n_loop]]
    d1 = [DQ(v) for v in x.d1[:n_loop]]
    d2 = [DQ(v) for v in x.d2[:n_loop]]
    dl = [DQ(v) for v in x.dlog_dec[:n_loop]]
    a, b, lg, d, e, h = q1[0], q2[0], ql[0], d1[0], d2[0], dl[0]
    as_q = " (a quaternion is a DQ with zero dual part)"
    no_screw = "- : log/exp/pow are the decoupled forms (see the decoupled rows)"
    return {
        "q product": Cell(
            "DQ * DQ" + as_q,
            lambda: a * b,
            lambda: [u * v for u, v in zip(q1, q2)],
            n_loop,
            loop=True,
        ),
        "q log": Cell("DQ.log()" + as_q, a.log, lambda: [u.log() for u in q1], n_loop, loop=True),
        "q exp": Cell("DQ.exp()" + as_q, lg.exp, lambda: [u.exp() for u in ql], n_loop, loop=True),
        "q pow 0.5": Cell(
            "DQ.pow(0.5)" + as_q,
            lambda: a.pow(0.5),
            lambda: [u.pow(0.5) for u in q1],
            n_loop,
            loop=True,
        ),
        "dq product": Cell(
            "DQ * DQ", lambda: d * e, lambda: [u * v for u, v in zip(d1, d2)], n_loop, loop=True
        ),
        "dq log (screw)": Cell(no_screw),
        "dq exp (screw)": Cell(no_screw),
        "dq pow 0.5 (screw)": Cell(no_screw),
        "dq log (decoupled)": Cell(
            "DQ.log() (decoupled: log r + eps t/2)", d.log, lambda: [u.log() for u in d1], n_loop,
            loop=True,
        ),
        "dq exp (decoupled)": Cell(
            "DQ.exp() (decoupled)", h.exp, lambda: [u.exp() for u in dl], n_loop, loop=True
        ),
        "dq pow 0.5 (decoupled)": Cell(
            "DQ.pow(0.5) (decoupled: r^0.5, t/2)",
            lambda: d.pow(0.5),
            lambda: [u.pow(0.5) for u in d1],
            n_loop,
            loop=True,
        ),
    }


def numpy_quaternion_cells(x: SimpleNamespace, n_loop: int) -> dict[str, Cell]:
    """Cells for numpy-quaternion: ``quaternion`` scalars and arrays of dtype quaternion."""
    del n_loop  # numpy-quaternion is vectorised
    n = len(x.q1)
    q1, q2, ql = (npq.as_quat_array(v) for v in (x.q1, x.q2, x.qlog))
    a, b, lg = q1[0], q2[0], ql[0]
    no_dq = "- : no dual quaternions"
    return {
        "q product": Cell("q1 * q2 (scalars and arrays)", lambda: a * b, lambda: q1 * q2, n),
        "q log": Cell("quaternion.log() / np.log(array)", a.log, lambda: np.log(q1), n),
        "q exp": Cell("quaternion.exp() / np.exp(array)", lg.exp, lambda: np.exp(ql), n),
        "q pow 0.5": Cell("q ** 0.5 (principal root, = q^0.5)", lambda: a**0.5, lambda: q1**0.5, n),
        "dq product": Cell(no_dq),
    }


CELL_BUILDERS = {
    "quatform": quatform_cells,
    "pytransform3d": pytransform3d_cells,
    "dqrobotics": dqrobotics_cells,
    "numpy-quaternion": numpy_quaternion_cells,
}


def measure(cell: Cell | None, installed: bool, repeat: int, min_run: float) -> tuple[str, str]:
    """Formatted (single-call µs, batch ns/element) entries of one table cell."""
    if not installed:
        return "n/i", "n/i"
    if cell is None:
        return "-", "-"
    single = "-" if cell.single is None else fmt(1e6 * best_time(cell.single, repeat, min_run))
    if cell.batch is None:
        return single, "-"
    batch = fmt(1e9 * best_time(cell.batch, repeat, min_run) / cell.batch_n)
    return single, batch + (" L" if cell.loop else "")


def main(argv: list[str] | None = None) -> None:
    """Parse the options, time every cell and print the table with its footnotes."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--n", type=int, default=100_000, help="batch size (default 100000)")
    parser.add_argument(
        "--n-loop", type=int, default=2000,
        help="elements in the dqrobotics Python loop (default 2000)",
    )
    parser.add_argument("--quick", action="store_true", help="3 short repeats instead of 7")
    args = parser.parse_args(argv)
    repeat, min_run = (3, 0.05) if args.quick else (7, 0.2)
    n_loop = min(args.n_loop, args.n)

    for line in machine_description(LIBRARIES):
        print(line)
    print(f"timing  : best of {repeat} repeats of >= {min_run} s each (time.perf_counter)\n")

    inputs = make_inputs(args.n)
    cells = {
        lib: CELL_BUILDERS[lib](inputs, n_loop) if installed else {}
        for lib, installed in LIBRARIES.items()
    }
    width, op_width = 11, 24
    group = width * len(LIBRARIES)
    print(f"{'':<{op_width}}| {'single call (us per call)':<{group}}"
          f"| batch (ns per element, N={args.n})")
    heads = "".join(f"{HEADINGS[lib]:>{width}}" for lib in LIBRARIES)
    print(f"{'operation':<{op_width}}| {heads}| {heads}")
    print("-" * (op_width + 2 * group + 4))
    for op in OPERATIONS:
        entries = [measure(cells[lib].get(op), inst, repeat, min_run) for lib, inst in LIBRARIES.items()]
        singles = "".join(f"{s:>{width}}" for s, _ in entries)
        batches = "".join(f"{b:>{width}}" for _, b in entries)
        print(f"{op:<{op_width}}| {singles}| {batches}", flush=True)

    print("\n-    : the library has no such operation (see the notes below)")
    print(f"L    : Python loop over N={n_loop} DQ objects (dqrobotics has no batch API), per element")
    print("n/i  : library not installed")
    for lib in LIBRARIES:
        if lib == "quatform" or not cells[lib]:
            continue
        print(f"\n{lib}:")
        for op in OPERATIONS:
            if op in cells[lib]:
                print(f"  {op:<{op_width - 2}} {cells[lib][op].note}")


if __name__ == "__main__":
    main()
