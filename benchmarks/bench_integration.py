"""Drift and accuracy of the quaternion integrators of :func:`quatform.algebra.integrate`.

Every method in :data:`quatform.algebra.INTEGRATORS` ("exp", "euler-normalized",
"euler-log", "euler") is run from the identity for ``--steps`` steps (default 10^6) of
``dt`` (default 0.01 s, so T = 10^4 s) with a world-frame angular velocity, in two cases:

constant
    ``omega = (0.3, -0.5, 0.8)`` rad/s (``--omega``). The reference is exact: the rotation
    by ``|omega| t`` about ``omega``, ``q_from_axis_angle(omega, |omega| t)``.
time-varying
    ``omega(t) = (sin 0.1 t, cos 0.07 t, 0.5)`` rad/s, passed to each step at the step's
    midpoint ``t_k + dt/2`` (held constant over the step, which is what ``integrate``
    assumes). There is no closed form, so the reference is the fourth-order
    commutator-free Magnus integrator (Blanes & Moan 2006; Alvermann & Fehske 2011,
    "CF4"): with the Gauss points ``t + (1/2 -+ sqrt(3)/6) h``, angular velocities ``w1,
    w2`` there and ``a1,2 = (3 -+ 2 sqrt(3))/12``, one step is
    ``q <- exp(h/2 (a1 w1 + a2 w2)) exp(h/2 (a2 w1 + a1 w2)) q``, run with
    ``h = dt / --substeps`` (default 10). It is vectorised: the step factors of a block of
    steps are computed at once and multiplied together pairwise (a tree), so it costs a
    few seconds for 10^7 steps and adds only ~log2(steps) roundings. Its own error is
    estimated by the angle between the runs with ``h`` and ``h/2`` and printed.

Reported per method: the final ``| ||q|| - 1 |``, its maximum over the run, the final
angle error (:func:`quatform.algebra.q_angle_between` of the normalised ``q`` and the
reference, in rad), and the wall time per step of ``integrate`` called on one quaternion
and of the fast loop below.

Calling ``integrate`` once per step costs tens of microseconds (input validation and
array overhead), i.e. minutes for 10^6 steps and four methods. The long runs therefore
use a plain-Python-float loop with the same formulas as ``integrate``, including its
renormalisation of the input by ``||q||`` for every method but "euler" (the unit check
of ``as_unit_quaternion``):

* exp: ``q <- exp(dt/2 omega) q``;
* euler: ``q <- q + dt (1/2 omega q)``;
* euler-normalized: the Euler step, then ``q / ||q||``;
* euler-log: the Euler step, then ``exp`` of its ``log`` with the real part set to 0.

Before the long runs the script checks, for the first ``--check-steps`` (default 1000)
steps of both cases, that this loop agrees with ``integrate`` to 1e-12 and prints the
check.

Run it from the repository root::

    python benchmarks/bench_integration.py                 # 10^6 steps, ~20 s
    python benchmarks/bench_integration.py --steps 100000 --dt 0.001 --omega 1 0 0
"""

from __future__ import annotations

import argparse
import math
import time
from dataclasses import dataclass
from typing import Callable

import numpy as np

import quatform.algebra as qa
from quatform.algebra.kernels import qmul_components

Quat = tuple[float, float, float, float]
Vec = tuple[float, float, float]

#: Largest accepted difference between the fast loop and ``integrate``.
CHECK_TOLERANCE = 1e-12


# --- The recurrences of quatform.algebra.integrate on Python floats ----------------------


def _qmul(a: Quat, b: Quat) -> Quat:
    """quatform's own product kernel, which also runs on Python floats."""
    return qmul_components(*a, *b)


def _norm(q: Quat) -> float:
    return math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])


def _normalise(q: Quat) -> Quat:
    n = _norm(q)
    return (q[0] / n, q[1] / n, q[2] / n, q[3] / n)


def _exp_pure(x: float, y: float, z: float) -> Quat:
    """``qexp((0, v))`` = ``(cos|v|, sinc|v| v)``."""
    a = math.sqrt(x * x + y * y + z * z)
    s = math.sin(a) / a if a > 0.0 else 1.0
    return (math.cos(a), s * x, s * y, s * z)


def _euler(q: Quat, w: Vec, dt: float) -> Quat:
    p = _qmul((0.0, w[0], w[1], w[2]), q)
    return (q[0] + dt * (0.5 * p[0]), q[1] + dt * (0.5 * p[1]),
            q[2] + dt * (0.5 * p[2]), q[3] + dt * (0.5 * p[3]))


def _step_exp(q: Quat, w: Vec, dt: float) -> Quat:
    h = 0.5 * dt
    return _qmul(_exp_pure(h * w[0], h * w[1], h * w[2]), _normalise(q))


def _step_euler_normalized(q: Quat, w: Vec, dt: float) -> Quat:
    return _normalise(_euler(_normalise(q), w, dt))


def _step_euler_log(q: Quat, w: Vec, dt: float) -> Quat:
    n0, n1, n2, n3 = _euler(_normalise(q), w, dt)
    s = math.sqrt(n1 * n1 + n2 * n2 + n3 * n3)
    if s > 0.0:  # qlog's vector part: (atan2(|v|, w) / |v|) v
        f = math.atan2(s, n0) / s
    else:
        f = 1.0 / n0 if n0 > 0.0 else 1.0
    return _exp_pure(f * n1, f * n2, f * n3)


#: Fast single-quaternion step for each method of ``integrate`` (world frame).
FAST_STEPS: dict[str, Callable[[Quat, Vec, float], Quat]] = {
    "exp": _step_exp,
    "euler-normalized": _step_euler_normalized,
    "euler-log": _step_euler_log,
    "euler": _euler,
}


# --- The two cases and their references --------------------------------------------------


@dataclass
class Case:
    """An angular-velocity profile and the reference orientation at the end of the run.

    Attributes
    ----------
    name : str
    omega_at : callable
        ``omega_at(t)``: angular velocity (rad/s) at time ``t`` as a tuple of floats.
    reference : callable
        ``reference(dt, steps)``: unit quaternion at ``t = dt * steps``.
    """

    name: str
    omega_at: Callable[[float], Vec]
    reference: Callable[[float, int], np.ndarray]


def constant_case(omega: Vec) -> Case:
    """Constant ``omega``; the reference is the exact rotation by ``|omega| t``."""
    w = tuple(float(c) for c in omega)
    speed = math.sqrt(sum(c * c for c in w))
    return Case(
        f"constant omega = ({w[0]:g}, {w[1]:g}, {w[2]:g}) rad/s",
        lambda t: w,
        lambda dt, steps: qa.q_from_axis_angle(w, speed * dt * steps),
    )


def _omega_varying(t: float) -> Vec:
    return (math.sin(0.1 * t), math.cos(0.07 * t), 0.5)


def _omega_varying_array(t: np.ndarray) -> np.ndarray:
    return np.stack([np.sin(0.1 * t), np.cos(0.07 * t), np.full_like(t, 0.5)], axis=-1)


def ordered_product(p: np.ndarray) -> np.ndarray:
    """``p[m-1] ... p[1] p[0]`` of ``(m, 4)`` quaternions by pairwise products (a tree)."""
    while len(p) > 1:
        head = qa.qmul(p[1::2][: len(p) // 2], p[0::2][: len(p) // 2])
        p = np.concatenate([head, p[-1:]]) if len(p) % 2 else head
    return p[0]


def magnus4(omega_array: Callable[[np.ndarray], np.ndarray], h: float, steps: int,
            block: int = 1 << 20) -> np.ndarray:
    """Orientation after ``steps`` CF4 Magnus steps of ``h`` from the identity (world frame).

    Parameters
    ----------
    omega_array : callable
        Vectorised angular velocity: ``(m,)`` times to ``(m, 3)`` rad/s.
    h : float
        Step, s.
    steps : int
    block : int
        Steps whose factors are formed and multiplied together at once.
    """
    c = math.sqrt(3.0) / 6.0
    a1, a2 = (3.0 - 2.0 * math.sqrt(3.0)) / 12.0, (3.0 + 2.0 * math.sqrt(3.0)) / 12.0
    q = qa.IDENTITY
    for start in range(0, steps, block):
        t = np.arange(start, min(start + block, steps)) * h
        w1, w2 = omega_array(t + (0.5 - c) * h), omega_array(t + (0.5 + c) * h)
        late = np.zeros(t.shape + (4,))
        early = np.zeros(t.shape + (4,))
        late[:, 1:] = 0.5 * h * (a1 * w1 + a2 * w2)
        early[:, 1:] = 0.5 * h * (a2 * w1 + a1 * w2)
        q = qa.qmul(ordered_product(qa.qmul(qa.qexp(late), qa.qexp(early))), q)
    return qa.qnormalize(q)


def varying_case(substeps: int) -> Case:
    """``omega(t) = (sin 0.1t, cos 0.07t, 0.5)``; the reference is CF4 with ``dt/substeps``.

    The reference's error estimate (angle to the run with half its step) is printed.
    """

    def reference(dt: float, steps: int) -> np.ndarray:
        fine = magnus4(_omega_varying_array, dt / substeps, steps * substeps)
        finer = magnus4(_omega_varying_array, dt / (2 * substeps), steps * 2 * substeps)
        err = float(qa.q_angle_between(fine, finer))
        print(f"  reference: CF4 Magnus with h = dt/{substeps}; angle to h = dt/{2 * substeps}:"
              f" {err:.2e} rad")
        return fine

    return Case("omega(t) = (sin 0.1t, cos 0.07t, 0.5) rad/s", _omega_varying, reference)


# --- Runs -----------------------------------------------------------------------------------


def check_against_integrate(method: str, case: Case, dt: float, steps: int) -> tuple[float, float]:
    """Run the fast loop and ``integrate`` side by side.

    Returns
    -------
    max_diff : float
        Largest component difference over the ``steps`` steps.
    seconds_per_step : float
        Wall time of one ``integrate`` call on one quaternion.
    """
    step = FAST_STEPS[method]
    fast: Quat = (1.0, 0.0, 0.0, 0.0)
    slow = qa.IDENTITY
    max_diff = 0.0
    elapsed = 0.0
    for k in range(steps):
        w = case.omega_at((k + 0.5) * dt)
        fast = step(fast, w, dt)
        start = time.perf_counter()
        slow = qa.integrate(slow, w, dt, method=method)
        elapsed += time.perf_counter() - start
        max_diff = max(max_diff, float(np.max(np.abs(np.array(fast) - slow))))
    return max_diff, elapsed / steps


def run_fast(method: str, case: Case, dt: float, steps: int) -> tuple[Quat, float, float]:
    """Integrate ``steps`` steps with the fast loop.

    Returns
    -------
    q : tuple of float
        Final (unnormalised) quaternion.
    max_dev : float
        Maximum of ``| ||q|| - 1 |`` after each step.
    seconds_per_step : float
        Wall time per step, norm bookkeeping included.
    """
    step = FAST_STEPS[method]
    omega_at = case.omega_at
    q: Quat = (1.0, 0.0, 0.0, 0.0)
    max_dev = 0.0
    start = time.perf_counter()
    for k in range(steps):
        q = step(q, omega_at((k + 0.5) * dt), dt)
        dev = abs(_norm(q) - 1.0)
        if dev > max_dev:
            max_dev = dev
    return q, max_dev, (time.perf_counter() - start) / steps


def main(argv: list[str] | None = None) -> None:
    """Parse the options, check the fast loop, run both cases and print the tables."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--steps", type=int, default=1_000_000, help="steps (default 10^6)")
    parser.add_argument("--dt", type=float, default=0.01, help="step in s (default 0.01)")
    parser.add_argument(
        "--omega", type=float, nargs=3, default=(0.3, -0.5, 0.8), metavar=("WX", "WY", "WZ"),
        help="constant angular velocity in rad/s (default 0.3 -0.5 0.8)",
    )
    parser.add_argument(
        "--check-steps", type=int, default=1000,
        help="steps compared with quatform.algebra.integrate (default 1000)",
    )
    parser.add_argument(
        "--substeps", type=int, default=10,
        help="reference steps per step in the time-varying case (default 10)",
    )
    args = parser.parse_args(argv)
    cases = (constant_case(tuple(args.omega)), varying_case(args.substeps))
    methods = qa.INTEGRATORS

    print(f"{args.steps} steps of dt = {args.dt:g} s (T = {args.steps * args.dt:g} s), "
          "world frame, from the identity\n")
    print(f"check: fast loop vs quatform.algebra.integrate over the first {args.check_steps} steps")
    integrate_time = {}
    for case in cases:
        for method in methods:
            diff, per_step = check_against_integrate(method, case, args.dt, args.check_steps)
            integrate_time[case.name, method] = per_step
            verdict = "ok" if diff <= CHECK_TOLERANCE else "FAILED"
            print(f"  {case.name:<44} {method:<17} max |diff| = {diff:.1e}  {verdict}")
            if diff > CHECK_TOLERANCE:
                raise SystemExit(f"fast loop disagrees with integrate (tolerance {CHECK_TOLERANCE:g})")

    for case in cases:
        print(f"\n{case.name}")
        ref = case.reference(args.dt, args.steps)
        header = (f"  {'method':<17}{'final |‖q‖-1|':>15}{'max |‖q‖-1|':>14}"
                  f"{'angle err (rad)':>17}{'integrate µs/step':>19}{'fast loop µs/step':>19}")
        rows = []
        for method in methods:
            q, max_dev, per_step = run_fast(method, case, args.dt, args.steps)
            angle = float(qa.q_angle_between(qa.qnormalize(q), ref))
            rows.append(
                f"  {method:<17}{abs(_norm(q) - 1.0):>15.2e}{max_dev:>14.2e}{angle:>17.2e}"
                f"{1e6 * integrate_time[case.name, method]:>19.1f}{1e6 * per_step:>19.2f}"
            )
        print(header)
        print("\n".join(rows))


if __name__ == "__main__":
    main()
