"""The formation contract test: one function that checks any :class:`~.base.Formation`.

Formations layer (test support; imports nothing above it). ``check_formation(F, rng)``
checks what every description promises (jaxlie's ``tests/utils.py`` and manif's
``common_tester`` are the model: one call covers a new description):

* round trips: ``inverse(forward(r)) = r`` (yaws mod 2 pi) and ``forward(inverse(c),
  near_c=c) = c`` up to the description's equivalence (angles mod 2 pi, ``q`` vs ``-q`` of
  its :attr:`~.base.Formation.sign_free` blocks);
* rate maps: ``cluster_rate`` against central differences of ``forward`` (near the state's
  own branch), ``robot_rate(forward(r), cluster_rate(r, v), r=r) = v`` where the
  description is regular, ``robot_rate`` against differences of ``inverse`` along a motion
  of the chart (``from_chart``, whose own rate is checked the same way), and the dense
  Jacobians equal to the rate maps;
* batch equals single (a ``(2, 3)`` batch against a loop);
* sign invariance (``q`` to ``-q`` of every sign-free block of ``near_c`` and of the state
  and rate given to ``robot_rate``) and yaw-wrap invariance (yaws moved by whole turns);
* at and near each declared special set (:meth:`~.base.Formation.special_sets`): finite
  outputs, the declared error from the Jacobian, and a finite inverse Jacobian that loses
  rank where declared (singularity measure 0) and keeps it nearby.

Failures raise ``AssertionError`` naming the check, the description and the worst value.
"""

from __future__ import annotations

import numpy as np

from ..errors import DegenerateInputError, InvalidInputError
from .base import Formation

__all__ = ["check_formation", "cluster_distance", "robot_distance"]

#: Relative tolerance of the exact identities (round trips, dense = rate maps, batch = single).
EXACT = 1e-9
#: Tolerance of the central differences (step 1e-6: truncation ~1e-12, rounding ~1e-10).
DIFF = 2e-6
#: Singularity measure below which a state counts as singular, and above which as regular
#: for the difference checks.
SINGULAR, REGULAR = 1e-9, 1e-2


def _wrap(a):
    return (a + np.pi) % (2.0 * np.pi) - np.pi


def robot_distance(F: Formation, r1, r2) -> np.ndarray:
    """Largest difference of two robot states, yaws mod 2 pi, a ``pose`` robot's quaternion up to
    sign, relative to ``max(1, |r|)``; shape ``(...)``."""
    r1, r2 = np.asarray(r1, dtype=float), np.asarray(r2, dtype=float)
    d = r1 - r2
    yaw = list(F.layout.yaw_indices)
    if yaw:
        d[..., yaw] = _wrap(d[..., yaw])
    rows = F.layout.orientation_index
    if len(rows):
        a, b = r1[..., rows], r2[..., rows]
        d[..., rows] = np.where(np.sum(a * b, axis=-1, keepdims=True) < 0.0, a + b, a - b)
    return np.max(np.abs(d), axis=-1) / np.maximum(1.0, np.max(np.abs(r2), axis=-1))


def cluster_distance(F: Formation, c1, c2) -> np.ndarray:
    """Largest difference of two cluster states up to the description's equivalence: angles mod
    2 pi (:meth:`~.base.Formation.errors`), each sign-free block compared with the nearer of
    ``+-``; relative to ``max(1, |c|)``. Shape ``(...)``."""
    c1, c2 = np.asarray(c1, dtype=float), np.asarray(c2, dtype=float)
    d = np.abs(F.errors(c1, c2))
    for s in F.sign_free:
        a, b = c1[..., s], c2[..., s]
        d[..., s] = np.where(np.max(np.abs(a - b), -1, keepdims=True) <= np.max(np.abs(a + b), -1, keepdims=True),
                             np.abs(a - b), np.abs(a + b))
    return np.max(d, axis=-1) / np.maximum(1.0, np.max(np.abs(c2), axis=-1))


def _assert_small(what, F, value, tol):
    value = np.asarray(value, dtype=float)
    worst = float(np.max(value)) if value.size else 0.0
    assert np.all(np.isfinite(value)) and worst <= tol, (
        f"{F.name} ({type(F).__name__}): {what}: worst {worst:.3g} > {tol:g}")


def _flip(c, s):
    out = np.array(c, dtype=float)
    out[..., s] = -out[..., s]
    return out


def _check_round_trips(F, r, c):
    _assert_small("inverse(forward(r)) = r", F, robot_distance(F, F.inverse(c), r), EXACT)
    _assert_small("forward(inverse(c), near_c=c) = c", F,
                  cluster_distance(F, F.forward(F.inverse(c), near_c=c), c), EXACT)
    _assert_small("inverse(c, near_r=r) = r (yaws unwrapped, not only mod 2 pi)", F,
                  np.max(np.abs(F.inverse(c, near_r=r) - r), -1) / np.maximum(1, np.max(np.abs(r), -1)), EXACT)


def _tangent(F, r, v):
    """``v`` with each ``pose`` robot's quaternion rate made tangent to its unit quaternion (a
    radial rate changes no orientation, so no description need reproduce it)."""
    rows = F.layout.orientation_index
    if len(rows):
        q, vq = r[..., rows], v[..., rows]
        v = np.array(v)
        v[..., rows] = vq - np.sum(vq * q, axis=-1, keepdims=True) * q / np.sum(q * q, axis=-1, keepdims=True)
    return v


def _check_rates(F, rng, r, c):
    v = _tangent(F, r, rng.normal(size=r.shape))
    h = 1e-6
    cd = F.cluster_rate(r, v, near_c=c)
    fd = (F.forward(r + h * v, near_c=c) - F.forward(r - h * v, near_c=c)) / (2 * h)
    scale = np.maximum(1.0, np.max(np.abs(cd), -1))
    _assert_small("cluster_rate = central differences of forward", F, np.max(np.abs(cd - fd), -1) / scale, DIFF)
    back = F.robot_rate(c, cd, r=r)
    _assert_small("robot_rate(forward(r), cluster_rate(r, v), r=r) = v", F,
                  np.max(np.abs(back - v), -1) / np.maximum(1, np.max(np.abs(v), -1)), EXACT * 10)
    # dense Jacobians are the rate maps
    J, Ji = F.jacobian(r, near_c=c), F.inverse_jacobian_at(c, r=r)
    w = rng.normal(size=c.shape)
    _assert_small("jacobian @ v = cluster_rate", F,
                  np.max(np.abs(np.einsum("...ij,...j->...i", J, v) - cd), -1) / scale, EXACT)
    rw = F.robot_rate(c, w, r=r)
    _assert_small("inverse_jacobian_at @ w = robot_rate", F,
                  np.max(np.abs(np.einsum("...ij,...j->...i", Ji, w) - rw), -1)
                  / np.maximum(1, np.max(np.abs(rw), -1)), EXACT)
    _assert_small("inverse_jacobian(r) = inverse_jacobian_at(forward(r), r=r)", F,
                  np.max(np.abs(F.inverse_jacobian(r, near_c=c) - Ji), (-2, -1)), EXACT)
    # robot_rate along a motion of the chart: e(t) = e + t e_dot
    e = F.to_chart(c, r=r)
    e_dot = rng.normal(size=e.shape)
    c0, c0_dot = F.from_chart(e, e_dot)
    fd_c = (F.from_chart(e + h * e_dot) - F.from_chart(e - h * e_dot)) / (2 * h)
    _assert_small("from_chart's rate = central differences of from_chart", F,
                  np.max(np.abs(c0_dot - fd_c), -1) / np.maximum(1, np.max(np.abs(c0_dot), -1)), DIFF)
    r0 = F.inverse(c0, near_r=r)
    rr = F.robot_rate(c0, c0_dot, r=r0)
    fd_r = (F.inverse(F.from_chart(e + h * e_dot), near_r=r0) - F.inverse(F.from_chart(e - h * e_dot), near_r=r0)) / (2 * h)
    _assert_small("robot_rate = central differences of inverse along from_chart", F,
                  np.max(np.abs(rr - fd_r), -1) / np.maximum(1, np.max(np.abs(rr), -1)), DIFF)


def _check_batch(F, r, c):
    rb, cb = r.reshape((2, 3) + r.shape[1:]), c.reshape((2, 3) + c.shape[1:])
    v = np.linspace(-1.0, 1.0, rb.size).reshape(rb.shape)
    w = np.linspace(-1.0, 1.0, cb.size).reshape(cb.shape)
    batched = {
        "forward": F.forward(rb, near_c=cb), "inverse": F.inverse(cb, near_r=rb),
        "cluster_rate": F.cluster_rate(rb, v, near_c=cb), "robot_rate": F.robot_rate(cb, w, r=rb),
        "jacobian": F.jacobian(rb, near_c=cb), "inverse_jacobian_at": F.inverse_jacobian_at(cb, r=rb),
        "to_chart": F.to_chart(cb, r=rb), "singularity_measure": F.singularity_measure(rb, near_c=cb),
    }
    for i in range(2):
        for j in range(3):
            single = {
                "forward": F.forward(rb[i, j], near_c=cb[i, j]), "inverse": F.inverse(cb[i, j], near_r=rb[i, j]),
                "cluster_rate": F.cluster_rate(rb[i, j], v[i, j], near_c=cb[i, j]),
                "robot_rate": F.robot_rate(cb[i, j], w[i, j], r=rb[i, j]),
                "jacobian": F.jacobian(rb[i, j], near_c=cb[i, j]),
                "inverse_jacobian_at": F.inverse_jacobian_at(cb[i, j], r=rb[i, j]),
                "to_chart": F.to_chart(cb[i, j], r=rb[i, j]),
                "singularity_measure": F.singularity_measure(rb[i, j], near_c=cb[i, j]),
            }
            for k, s in single.items():
                b = batched[k][i, j]
                assert np.shape(b) == np.shape(s), f"{F.name}: {k}: batch shape {np.shape(b)} vs single {np.shape(s)}"
                _assert_small(f"batch = single ({k})", F,
                              np.max(np.abs(b - s)) / max(1.0, float(np.max(np.abs(s)))), EXACT)


def _check_signs_and_wraps(F, rng, r, c, regular):
    v = _tangent(F, r, rng.normal(size=r.shape))
    for s in F.sign_free:
        flipped = _flip(c, s)
        _assert_small(f"forward(r, near_c=c with {s} negated) = c", F,
                      cluster_distance(F, F.forward(r, near_c=flipped), c), EXACT)
        _assert_small(f"inverse(c with {s} negated) = r", F, robot_distance(F, F.inverse(flipped), r), EXACT)
        if np.any(regular):
            rr, cc, vv = r[regular], c[regular], v[regular]
            cd = F.cluster_rate(rr, vv, near_c=cc)
            rate = F.robot_rate(_flip(cc, s), _flip(cd, s), r=rr)
            rows = F.layout.orientation_index
            if len(rows):  # a pose robot's quaternion rate belongs to the sign its quaternion has
                sign = np.sign(np.sum(F.inverse(_flip(cc, s))[..., rows] * rr[..., rows], axis=-1, keepdims=True))
                rate[..., rows] = sign * rate[..., rows]
            _assert_small(f"robot_rate with {s} negated in c and c_dot", F,
                          np.max(np.abs(rate - vv), -1) / np.maximum(1, np.max(np.abs(vv), -1)), EXACT * 10)
    yaw = list(F.layout.yaw_indices)
    if not yaw:
        return
    wound = np.array(r)
    wound[..., yaw] += 2.0 * np.pi * rng.integers(-5, 6, wound[..., yaw].shape)
    _assert_small("inverse(forward(r wound by whole turns)) = r mod 2 pi", F,
                  robot_distance(F, F.inverse(F.forward(wound)), r), EXACT)
    _assert_small("forward(r wound by whole turns, near_c=c) = c", F,
                  cluster_distance(F, F.forward(wound, near_c=c), c), EXACT)
    if np.any(regular):
        cd, cdw = F.cluster_rate(r[regular], v[regular], near_c=c[regular]), \
            F.cluster_rate(wound[regular], v[regular], near_c=c[regular])
        _assert_small("cluster_rate invariant under whole turns of the yaws", F,
                      np.max(np.abs(cd - cdw), -1) / np.maximum(1, np.max(np.abs(cd), -1)), EXACT)
    m, mw = F.singularity_measure(r, near_c=c), F.singularity_measure(wound, near_c=c)
    _assert_small("singularity_measure invariant under whole turns of the yaws", F, np.abs(m - mw), EXACT)


def _check_special_sets(F, rng, n):
    for sset in F.special_sets():
        for eps in (0.0, 1e-9, 1e-6, 1e-3):
            r = sset.states(rng, n, eps)
            what = f"special set {sset.name!r} at eps = {eps:g}"
            assert np.all(F.reachable(r)), f"{F.name}: {what}: the generator left the reachable set"
            c = F.forward(r)
            assert np.all(np.isfinite(c)), f"{F.name}: {what}: forward not finite"
            tol = max(EXACT, sset.round_trip_tol)
            _assert_small(f"{what}: inverse(forward(r)) = r", F, robot_distance(F, F.inverse(c), r), tol)
            # where a variable's rate is undefined on the set, it is fixed only to rounding / eps nearby
            c_tol = tol if sset.jacobian != "raises" or eps == 0.0 else max(tol, 1e-14 / eps)
            _assert_small(f"{what}: forward(inverse(c), near_c=c) = c", F,
                          cluster_distance(F, F.forward(F.inverse(c), near_c=c), c), c_tol)
            Ji = F.inverse_jacobian(r)
            assert np.all(np.isfinite(Ji)), f"{F.name}: {what}: inverse Jacobian not finite"
            m = F.singularity_measure(r)
            if eps == 0.0 and sset.jacobian == "raises":
                try:
                    F.jacobian(r)
                except DegenerateInputError:
                    pass
                else:
                    raise AssertionError(f"{F.name}: {what}: jacobian should raise DegenerateInputError")
            else:
                J = F.jacobian(r)
                assert np.all(np.isfinite(J)), f"{F.name}: {what}: Jacobian not finite"
            if eps == 0.0 and sset.inverse_jacobian == "rank-deficient":
                _assert_small(f"{what}: singularity measure (rank-deficient inverse Jacobian)", F, m, SINGULAR)
            else:
                assert np.all(m > 0.0), f"{F.name}: {what}: inverse Jacobian lost rank (measure {float(np.min(m)):.3g})"


def check_formation(F: Formation, rng, n: int = 24) -> None:
    """Check the formation contract for ``F`` on ``n`` random states and its special sets.

    Parameters
    ----------
    F : Formation
    rng : numpy.random.Generator
    n : int
        Number of random robot states (a multiple of 6: a ``(2, 3)`` batch of them is
        checked against a loop).

    Raises
    ------
    AssertionError
        Naming the check, the description and the worst value.
    """
    if n % 6 or n <= 0:
        raise InvalidInputError(f"check_formation: n = {n} must be a positive multiple of 6 (a (2, 3) batch of "
                                "the samples is checked against a loop); pass n=24")
    r = F.sample_robot_state(rng, (n,))
    assert r.shape == (n, F.n_r), f"{F.name}: sample_robot_state gave shape {r.shape}, not {(n, F.n_r)}"
    assert np.all(F.reachable(r)), f"{F.name}: sample_robot_state left the reachable set"
    F.layout.check_apart(r, 0.1)
    c = F.forward(r)
    assert c.shape == (n, F.n_c) and np.all(np.isfinite(c)), f"{F.name}: forward gave {c.shape} or non-finite values"
    _check_round_trips(F, r, c)
    regular = F.singularity_measure(r, near_c=c) > REGULAR
    assert np.count_nonzero(regular) >= n // 2, f"{F.name}: only {np.count_nonzero(regular)} of {n} samples regular"
    _check_rates(F, rng, r[regular], c[regular])
    _check_batch(F, r[:6], c[:6])
    _check_signs_and_wraps(F, rng, r, c, regular)
    _check_special_sets(F, rng, max(2, n // 6))
