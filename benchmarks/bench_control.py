"""Time of one control step of seed 000's four formation controllers, next to dqrobotics.

For each controller of :mod:`quatform.control` (cluster-space, robot-space, quaternion,
dual-quaternion) the script measures one full ``ctrl.step(t, r, Reference(c, c_dot))``
(input checks, forward kinematics with the reference as hint, errors, command, inverse
Jacobian, saturation):

* **single**: microseconds for one formation (``(8,)`` robot state, ``(n_c,)`` reference);
* **batch**: nanoseconds per formation for one call on ``N`` formations (default 10 000;
  inputs with a leading axis of ``N``).

The reference is the Euclidean cluster state ``e = (0.1, 0.2, 1, 0.3, 0.4, 1, 0.1, 0.2)``
``(x, y, z, beta, gamma, d, phi1, phi2)`` with rate ``0.1`` in every variable, converted
by ``formation.from_euclidean``; the measured robots are ``EuclideanPair().inverse(e +
0.01)``. The batch perturbs ``e`` by ``0.1 N(0, 1)`` (``numpy.random.default_rng(0)``,
``d`` kept >= 0.2) so the ``N`` formations differ.

The peer is the same quaternion (eq. 20, on eqs. 9-19) and dual-quaternion (eqs. 26-28)
step written with dqrobotics primitives (``DQ`` objects, ``*``, ``conj``, ``P``, ``D``,
``normalize``, ``dot``, ``cross``, ``vec4``/``vec8``) for one formation, in two forms:

* **FD-J**: robot rates through the 8 x 16 inverse Jacobian built column by column by
  central differences of the inverse kinematics, itself written with ``DQ`` products;
* **JVP**: robot rates from the analytic directional derivative of the inverse
  kinematics along the command, also with ``DQ`` products (what quatform does).

dqrobotics has no batch API, so the peers have no batch column. Each peer command is
compared with quatform's (max abs difference over the base formation and the first 100
batch formations). The cluster-space and robot-space controllers use no quaternions and
have no peer. Every time is the best of several repeats of a ``time.perf_counter``-timed
loop, as in :mod:`timeit`.

Run it from the repository root::

    python benchmarks/bench_control.py                 # N = 10 000, 7 repeats (~30 s)
    python benchmarks/bench_control.py --repeat 3
    python benchmarks/bench_control.py --batch 100000
    python benchmarks/bench_control.py --before /path/to/old/src   # the speed against another tree

``--before SRC`` times the issue-13 speed check (one ``QuaternionController().step`` of one
formation, and of a batch of 1000, as the simulator calls it) for this quatform and for
the quatform package under ``SRC`` (another checkout's ``src``, run in a subprocess),
alternating the two three times and keeping each side's best, in CPU time of the timing
process (``time.process_time``: less disturbed by other processes on a shared machine),
and prints both.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import time
from functools import partial

import numpy as np
from quatform.control import (
    ClusterSpaceController,
    DualQuaternionController,
    QuaternionController,
    Reference,
    RobotSpaceController,
)
from quatform.formations import EuclideanPair

from _common import best_time, fmt, machine_description, optional_import

dqr = optional_import("dqrobotics")

#: Base Euclidean cluster state (x, y, z, beta, gamma, d, phi1, phi2) and its rate.
E_BASE = np.array([0.1, 0.2, 1.0, 0.3, 0.4, 1.0, 0.1, 0.2])
E_DOT = 0.1 * np.ones(8)
#: Offset of the measured robots' Euclidean state from the reference.
E_OFFSET = 0.01
#: Step of the central differences of the FD-J peers.
FD_STEP = 1e-6
#: Performance target for one quaternion or dual-quaternion step (quatform, single).
TARGET_US = 50.0
#: Formations of the batch on which the peers' commands are compared with quatform's.
N_COMPARE = 100

#: Table rows: name and controller class.
CONTROLLERS = {
    "cluster-space": ClusterSpaceController,
    "robot-space": RobotSpaceController,
    "quaternion": QuaternionController,
    "dual-quaternion": DualQuaternionController,
}


# --- Inputs --------------------------------------------------------------------------------


def make_inputs(ctrl, n: int, seed: int = 0):
    """Single and batched ``(r, c, c_dot)`` for ``ctrl``'s formation.

    Returns
    -------
    tuple
        ``(r, c, c_dot)`` of one formation, shapes ``(8,), (n_c,), (n_c,)``, and
        ``(r_b, c_b, cd_b)`` of ``n`` formations, shapes ``(n, 8), (n, n_c), (n, n_c)``.
    """
    F = ctrl.formation
    E = EuclideanPair()
    c, c_dot = F.from_euclidean(E_BASE, E_DOT)
    r = E.inverse(E_BASE + E_OFFSET)
    rng = np.random.default_rng(seed)
    e_b = E_BASE + 0.1 * rng.normal(size=(n, 8))
    e_b[:, 5] = np.maximum(e_b[:, 5], 0.2)  # d_c > 0
    c_b, cd_b = F.from_euclidean(e_b, np.broadcast_to(E_DOT, e_b.shape))
    r_b = E.inverse(e_b + E_OFFSET)
    return (r, c, c_dot), (r_b, c_b, cd_b), (E.inverse(E_BASE), E.inverse(e_b))


# --- dqrobotics peers ------------------------------------------------------------------------
#
# Written with DQ objects only; numbers enter and leave through DQ(8 floats) and vec4/vec8.
# A quaternion is a DQ with zero dual part.


def _saturate(u, team):
    """The team's saturation on a list of 8 floats: one factor for all robots, the smallest
    any robot needs for its speed norm and yaw rate; a non-finite entry stops the team."""
    if not all(map(math.isfinite, u)):
        return [0.0] * len(u)
    s = 1.0
    for i, rb in enumerate(team.robots):
        vx, vy, vz, wz = u[4 * i:4 * i + 4]
        speed = math.sqrt(vx * vx + vy * vy + vz * vz)
        if speed > rb.max_speed:
            s = min(s, rb.max_speed / speed)
        if abs(wz) > rb.max_yaw_rate:
            s = min(s, rb.max_yaw_rate / abs(wz))
    return [s * x for x in u]


def _wrap(a):
    return (a + math.pi) % (2.0 * math.pi) - math.pi


def _yaw(q):
    """Yaw of a quaternion DQ about z: ``2 atan2(q_z, q_w)``."""
    v = dqr.vec4(q)
    return 2.0 * math.atan2(v[3], v[0])


def _yaw_rate(q, qd):
    """Rate of ``2 atan2(q_z, q_w)`` along ``qd``."""
    v, vd = dqr.vec4(q), dqr.vec4(qd)
    return 2.0 * (v[0] * vd[3] - v[3] * vd[0]) / (v[0] * v[0] + v[3] * v[3])


def _qyaw(theta):
    return dqr.DQ(math.cos(0.5 * theta), 0.0, 0.0, math.sin(0.5 * theta), 0.0, 0.0, 0.0, 0.0)


def _vec(x, y, z):
    return dqr.DQ(0.0, x, y, z, 0.0, 0.0, 0.0, 0.0)


def _basis():
    """Unit DQs ``1, i, j, k, E, E i, E j, E k``."""
    eye = np.eye(8)
    return [dqr.DQ(*eye[k]) for k in range(8)]


def _fd_jacobian(ik, slots, basis, h=FD_STEP):
    """8 x 16 matrix of ``ik`` at ``slots`` by central differences, one column per coordinate.

    ``slots`` is a list of arguments of ``ik`` (DQs or floats); ``basis`` lists, for each
    of the 16 coordinates, ``(slot index, DQ or float unit step)``. Yaw rows (3, 7) are
    differenced modulo 2 pi.
    """
    J = np.empty((8, len(basis)))
    for col, (i, b) in enumerate(basis):
        plus, minus = list(slots), list(slots)
        plus[i] = slots[i] + h * b
        minus[i] = slots[i] - h * b
        fp, fm = ik(*plus), ik(*minus)
        d = [a - m for a, m in zip(fp, fm)]
        d[3], d[7] = _wrap(d[3]), _wrap(d[7])
        J[:, col] = d
    return J / (2.0 * h)


class DQRoboticsQuaternionStep:
    """Seed 000 eq. (20) on eqs. (9)-(19) with dqrobotics quaternions (DQs, zero dual part).

    Forward kinematics with the reference as hint: ``q_c`` = minimal rotation taking the
    hint's x axis to the measured segment, times the hint; ``q_ci = q_c* q_z(theta_i)``
    with the hint's signs. (The antiparallel fallback of quatform is not written: the
    benchmark's formations never reach it.)
    """

    def __init__(self, ctrl, jacobian: str):
        self.kx = ctrl.k_x.tolist()
        self.kd = float(ctrl.k_d)
        self.kw = ctrl.k_w.tolist()
        self.ff = 1.0 if ctrl.feedforward else 0.0
        self.team = ctrl.team
        self.jacobian = jacobian
        one, i, j, k = _basis()[:4]
        self.i = i
        # coordinates of c: x_c (3), q_c (4), d_c, q_c1 (4), q_c2 (4); slots of _ik
        self.fd_basis = [(0, i), (0, j), (0, k), (1, one), (1, i), (1, j), (1, k), (2, 1.0),
                         (3, one), (3, i), (3, j), (3, k), (4, one), (4, i), (4, j), (4, k)]

    @staticmethod
    def _unpack(c):
        """``(x_c, q_c, d_c, q_c1, q_c2)`` as (pure DQ, DQ, float, DQ, DQ) of a 16-list."""
        DQ = dqr.DQ
        return (_vec(*c[0:3]), DQ(*c[3:7], 0.0, 0.0, 0.0, 0.0), c[7],
                DQ(*c[8:12], 0.0, 0.0, 0.0, 0.0), DQ(*c[12:16], 0.0, 0.0, 0.0, 0.0))

    def _ik(self, xc, qc, d, q1c, q2c):
        """Eqs. (16)-(19): robots ``x_c +- d q_c i q_c*``, yaws of ``q_c q_ci``."""
        half = d * dqr.Im(qc * self.i * dqr.conj(qc))
        p1, p2 = dqr.vec4(xc + half), dqr.vec4(xc - half)
        return [p1[1], p1[2], p1[3], _yaw(qc * q1c), p2[1], p2[2], p2[3], _yaw(qc * q2c)]

    def _ik_jvp(self, c, cd):
        """Analytic rate of eqs. (16)-(19) at ``c`` along ``cd`` (unpacked)."""
        _, qc, d, q1c, q2c = c
        xcd, qcd, dd, q1cd, q2cd = cd
        qcc = dqr.conj(qc)
        v = dd * (qc * self.i * qcc) + 2.0 * d * dqr.Im(qcd * self.i * qcc)
        p1, p2 = dqr.vec4(xcd + v), dqr.vec4(xcd - v)
        w1 = _yaw_rate(qc * q1c, qcd * q1c + qc * q1cd)
        w2 = _yaw_rate(qc * q2c, qcd * q2c + qc * q2cd)
        return [p1[1], p1[2], p1[3], w1, p2[1], p2[2], p2[3], w2]

    def __call__(self, r, c_des, c_dot_des):
        conj, vec4 = dqr.conj, dqr.vec4
        r, cd, cdd = r.tolist(), c_des.tolist(), c_dot_des.tolist()
        xc_des, qc_des, d_des, q1_des, q2_des = self._unpack(cd)
        xcd_des, qcd_des, dd_des, q1d_des, q2d_des = self._unpack(cdd)
        # forward kinematics, eqs. (9)-(15) with the hint
        p1, p2 = _vec(*r[0:3]), _vec(*r[4:7])
        delta = p1 - p2
        length = vec4(dqr.norm(delta))[0]
        u = delta * (1.0 / length)
        a = qc_des * self.i * conj(qc_des)  # hint's x axis
        qc = dqr.normalize(1.0 + dqr.dot(a, u) + dqr.cross(a, u)) * qc_des
        qcc = conj(qc)
        xc, d = 0.5 * (p1 + p2), 0.5 * length
        q1 = qcc * _qyaw(r[3])
        q2 = qcc * _qyaw(r[7])
        if np.dot(vec4(q1), vec4(q1_des)) < 0.0:
            q1 = -q1
        if np.dot(vec4(q2), vec4(q2_des)) < 0.0:
            q2 = -q2
        # errors and command, eq. (20) with the position and shape loops
        ex = vec4(xc - xc_des)
        xv = vec4(xcd_des)
        x_cmd = _vec(*[-self.kx[m] * ex[m + 1] + self.ff * xv[m + 1] for m in range(3)])
        d_cmd = -self.kd * (d - d_des) + self.ff * dd_des
        q_cmd = []
        for q, qd, qdd in ((qc, qc_des, qcd_des), (q1, q1_des, q1d_des), (q2, q2_des, q2d_des)):
            qe = conj(qd) * q
            v = vec4(qe)
            s = -1.0 if v[0] < 0.0 else 1.0
            w = dqr.DQ(0.0, -s * self.kw[0] * v[1], -s * self.kw[1] * v[2], -s * self.kw[2] * v[3],
                       0.0, 0.0, 0.0, 0.0)
            qdot = 0.5 * q * w
            if self.ff:
                qdot = qdot + qdd * conj(qd) * q
            q_cmd.append(qdot)
        # robot rates
        state = (xc, qc, d, q1, q2)
        cmd = (x_cmd, q_cmd[0], d_cmd, q_cmd[1], q_cmd[2])
        if self.jacobian == "fd":
            J = _fd_jacobian(self._ik, state, self.fd_basis)
            cvec = np.concatenate([vec4(x_cmd)[1:], vec4(q_cmd[0]), [d_cmd],
                                   vec4(q_cmd[1]), vec4(q_cmd[2])])
            r_dot = (J @ cvec).tolist()
        else:
            r_dot = self._ik_jvp(state, cmd)
        return np.array(_saturate(r_dot, self.team))


class DQRoboticsDualQuaternionStep:
    """Seed 000 eq. (28) on eqs. (26)-(27) with dqrobotics dual quaternions.

    Robots ``q_i = r_i + E 1/2 p_i r_i`` (``r_i`` a yaw), shape ``qs = q2* q1``, cluster
    ``qc = q2 h`` with ``h`` the decoupled square root of ``qs``: rotation
    ``normalize(1 + r_s)`` (``r_s`` with scalar part >= 0), half the translation. Signs of
    ``qc``, ``qs`` follow the reference's. The inverse kinematics is ``q2 = qc h*``,
    ``q1 = q2 qs``, ``p = 2 D(q) P(q)*``, ``yaw = 2 atan2(r_z, r_w)``.
    """

    def __init__(self, ctrl, jacobian: str):
        self.kw = ctrl.k_dw.tolist()
        self.ff = 1.0 if ctrl.feedforward else 0.0
        self.team = ctrl.team
        self.jacobian = jacobian
        b = _basis()
        self.fd_basis = [(0, x) for x in b] + [(1, x) for x in b]

    @staticmethod
    def _pose(theta, x, y, z):
        r = _qyaw(theta)
        return r + dqr.E_ * 0.5 * _vec(x, y, z) * r

    @staticmethod
    def _root(qs):
        """Decoupled square root of ``qs`` (half rotation the short way, half translation)."""
        rs = dqr.P(qs)
        half_t = dqr.D(qs) * dqr.conj(rs)  # t_s / 2 (no unit check: qs may be perturbed)
        if dqr.vec4(rs)[0] < 0.0:
            rs = -rs
        n = dqr.normalize(1.0 + rs)
        return n + dqr.E_ * 0.5 * half_t * n

    def _ik(self, qc, qs):
        q2 = qc * dqr.conj(self._root(qs))
        q1 = q2 * qs
        out = []
        for q in (q1, q2):
            rq = dqr.P(q)
            t = dqr.vec4(2.0 * dqr.D(q) * dqr.conj(rq))
            out += [t[1], t[2], t[3], _yaw(rq)]
        return out

    def _ik_jvp(self, qc, qs, qcd, qsd):
        """Analytic rate of the inverse kinematics at ``(qc, qs)`` along ``(qcd, qsd)``."""
        P, D, conj, E = dqr.P, dqr.D, dqr.conj, dqr.E_
        rs, ds, rsd, dsd = P(qs), D(qs), P(qsd), D(qsd)
        sig = -1.0 if dqr.vec4(rs)[0] < 0.0 else 1.0
        v = 1.0 + sig * rs
        nv = dqr.vec4(dqr.norm(v))[0]
        n = v * (1.0 / nv)
        proj = float(np.dot(dqr.vec4(n), dqr.vec4(rsd)))
        nd = (sig / nv) * (rsd - proj * n)  # d normalize(v) along sig * rsd
        ts2 = ds * conj(rs)
        ts2d = dsd * conj(rs) + ds * conj(rsd)
        h = n + E * 0.5 * ts2 * n
        hd = nd + E * 0.5 * (ts2d * n + ts2 * nd)
        q2 = qc * conj(h)
        q2d = qcd * conj(h) + qc * conj(hd)
        q1 = q2 * qs
        q1d = q2d * qs + q2 * qsd
        out = []
        for q, qd in ((q1, q1d), (q2, q2d)):
            td = dqr.vec4(2.0 * (D(qd) * conj(P(q)) + D(q) * conj(P(qd))))
            out += [td[1], td[2], td[3], _yaw_rate(P(q), P(qd))]
        return out

    def __call__(self, r, c_des, c_dot_des):
        DQ, conj, vec4, vec8 = dqr.DQ, dqr.conj, dqr.vec4, dqr.vec8
        r, cd, cdd = r.tolist(), c_des.tolist(), c_dot_des.tolist()
        # forward kinematics, eqs. (26)-(27)
        q1 = self._pose(r[3], *r[0:3])
        q2 = self._pose(r[7], *r[4:7])
        qs = conj(q2) * q1
        qc = q2 * self._root(qs)
        out = []
        for q, lo in ((qc, 0), (qs, 8)):
            qd, qdd = DQ(*cd[lo:lo + 8]), DQ(*cdd[lo:lo + 8])
            if np.dot(vec4(dqr.P(q)), vec4(dqr.P(qd))) < 0.0:  # the reference's sign
                q = -q
            # error and command, eq. (28)
            qe = conj(qd) * q
            v = vec8(qe)
            s = -1.0 if v[0] < 0.0 else 1.0
            k = self.kw
            w = DQ(0.0, -s * k[0] * v[1], -s * k[1] * v[2], -s * k[2] * v[3],
                   0.0, -s * k[0] * v[5], -s * k[1] * v[6], -s * k[2] * v[7])
            qdot = 0.5 * q * w
            if self.ff:
                qdot = qdot + qdd * conj(qd) * q
            out.append((q, qdot))
        (qc, qcd), (qs, qsd) = out
        # robot rates
        if self.jacobian == "fd":
            J = _fd_jacobian(self._ik, (qc, qs), self.fd_basis)
            r_dot = (J @ np.concatenate([vec8(qcd), vec8(qsd)])).tolist()
        else:
            r_dot = self._ik_jvp(qc, qs, qcd, qsd)
        return np.array(_saturate(r_dot, self.team))


PEERS = {
    "quaternion": DQRoboticsQuaternionStep,
    "dual-quaternion": DQRoboticsDualQuaternionStep,
}


# --- Timing and output ---------------------------------------------------------------------


def peer_difference(peer, ctrl, single, batch) -> float:
    """Max abs difference of the peer's commands from quatform's, over the base formation
    and the first :data:`N_COMPARE` formations of the batch."""
    cases = [single] + [tuple(x[m] for x in batch) for m in range(min(N_COMPARE, len(batch[0])))]
    return max(
        float(np.max(np.abs(peer(r, c, cd) - ctrl.step(0.0, r, Reference(c, cd)))))
        for r, c, cd in cases
    )


def batch_consistency(ctrl, batch) -> float:
    """Max abs difference between batched and one-at-a-time quatform steps (first rows)."""
    r_b, c_b, cd_b = (x[:N_COMPARE] for x in batch)
    u_b = ctrl.step(0.0, r_b, Reference(c_b, cd_b))
    u_1 = np.array([ctrl.step(0.0, r, Reference(c, cd)) for r, c, cd in zip(r_b, c_b, cd_b)])
    return float(np.max(np.abs(u_b - u_1)))


def time_controller(name: str, ctrl, args) -> tuple[list[str], float, float]:
    """Table entries of one controller, its single-step time (us) and its batch check."""
    single, batch, (r_des, r_des_b) = make_inputs(ctrl, args.batch)
    r, c, cd = single
    r_b, c_b, cd_b = batch
    # as the simulator calls it: the desired robots come with the reference (Reference.robots)
    t1 = best_time(lambda: ctrl.step(0.0, r, Reference(c, cd, r_des)), args.repeat, args.min_run)
    tb = best_time(lambda: ctrl.step(0.0, r_b, Reference(c_b, cd_b, r_des_b)), args.repeat, args.min_run)
    entries = [name, fmt(1e6 * t1), fmt(1e9 * tb / args.batch)]
    for jac in ("fd", "jvp"):
        if name not in PEERS:
            entries += ["-", "-"]
        elif dqr is None:
            entries += ["n/i", "n/i"]
        else:
            peer = PEERS[name](ctrl, jac)
            tp = best_time(partial(peer, r, c, cd), args.repeat, args.min_run)
            entries += [fmt(1e6 * tp), f"{peer_difference(peer, ctrl, single, batch):.1e}"]
    return entries, 1e6 * t1, batch_consistency(ctrl, batch)


def quaternion_speed(n: int = 1000, repeat: int = 15, calls: int = 3000) -> dict:
    """CPU time of ``QuaternionController().step``: ``single_us`` (one formation) and
    ``batch_ns`` (per formation, one call on ``n``), best of ``repeat`` loops."""
    ctrl = QuaternionController()
    (r, c, cd), (r_b, c_b, cd_b), (r_des, r_des_b) = make_inputs(ctrl, n)
    out = {}
    for key, fn, k, per in (("single_us", lambda: ctrl.step(0.0, r, Reference(c, cd, r_des)), calls, 1e6),
                            ("batch_ns", lambda: ctrl.step(0.0, r_b, Reference(c_b, cd_b, r_des_b)),
                             max(1, calls // 100), 1e9 / n)):
        best = math.inf
        for _ in range(repeat):
            t0 = time.process_time()
            for _ in range(k):
                fn()
            best = min(best, (time.process_time() - t0) / k)
        out[key] = best * per
    return out


def compare_before(src: str) -> None:
    """Print :func:`quaternion_speed` of the quatform under ``src`` and of this one."""
    here = os.path.dirname(os.path.abspath(__file__))
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([os.path.abspath(src), here]))
    before, after = [], []
    for _ in range(3):
        done = subprocess.run([sys.executable, os.path.abspath(__file__), "--speed-json"], env=env,
                              capture_output=True, text=True, check=True)
        before.append(json.loads(done.stdout.strip().splitlines()[-1]))
        after.append(quaternion_speed())
    b = {k: min(x[k] for x in before) for k in before[0]}
    a = {k: min(x[k] for x in after) for k in after[0]}
    print(f"QuaternionController().step, CPU time, best of 3 alternating runs (before = {src}):")
    print(f"  single (us)              before {b['single_us']:7.1f}   after {a['single_us']:7.1f}   "
          f"target <= {TARGET_US:.0f}: {'met' if a['single_us'] <= TARGET_US else 'NOT met'}")
    print(f"  batch of 1000 (ns/form.) before {b['batch_ns']:7.0f}   after {a['batch_ns']:7.0f}")


def main(argv: list[str] | None = None) -> None:
    """Parse the options, time every controller and peer and print the table and notes."""
    if argv is None and sys.argv[1:] == ["--speed-json"]:  # the --before subprocess
        print(json.dumps(quaternion_speed()))
        return
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--batch", type=int, default=10_000, help="formations in the batch (default 10000)")
    parser.add_argument("--repeat", type=int, default=7, help="repeats, the best is kept (default 7)")
    parser.add_argument(
        "--min-run", type=float, default=0.2, help="least seconds per repeat (default 0.2)"
    )
    parser.add_argument("--before", metavar="SRC", help="time the quaternion step here and under SRC, print both")
    args = parser.parse_args(argv)
    if args.before:
        compare_before(args.before)
        return
    if args.batch < 1 or args.repeat < 1 or args.min_run <= 0:
        parser.error("--batch and --repeat must be >= 1 and --min-run > 0")

    for line in machine_description({"quatform": True, "dqrobotics": dqr is not None}, width=10):
        print(line)
    print(f"timing    : best of {args.repeat} repeats of >= {args.min_run} s each (time.perf_counter)\n")

    cols = (
        ("controller", 16, "<"),
        ("quatform single (us)", 22, ">"),
        (f"quatform batch (ns/formation, N={args.batch})", 44, ">"),
        ("dqrobotics FD-J single (us)", 29, ">"),
        ("|u diff|", 10, ">"),
        ("dqrobotics JVP single (us)", 28, ">"),
        ("|u diff|", 10, ">"),
    )
    print("".join(f"{h:{a}{w}}" for h, w, a in cols))
    print("-" * sum(w for _, w, _ in cols))

    singles, consistency = {}, {}
    for name, cls in CONTROLLERS.items():
        entries, singles[name], consistency[name] = time_controller(name, cls(), args)
        print("".join(f"{e:{a}{w}}" for e, (_, w, a) in zip(entries, cols)), flush=True)

    verdicts = ", ".join(
        f"{n} {fmt(singles[n])} us {'met' if singles[n] <= TARGET_US else 'NOT met'}"
        for n in ("quaternion", "dual-quaternion")
    )
    print(f"\ntarget: one quaternion or dual-quaternion step <= {TARGET_US:.0f} us (quatform, single): {verdicts}")
    print(
        "batch check: batched vs one-at-a-time quatform steps, max |u diff| over the first "
        f"{N_COMPARE} formations: "
        + ", ".join(f"{k} {v:.1e}" for k, v in consistency.items())
    )

    print("\nquatform: ctrl.step(0.0, r, Reference(c, c_dot, r_des)), Reference built inside the timed call;")
    print("  single = (8,) robot state, batch = one call on (N, 8) / (N, n_c) inputs; gains of")
    print("  Table 1, feed-forward on, commands saturated by the default Team.")
    print("-        : no dqrobotics peer (the cluster-space and robot-space controllers use no")
    print("           quaternions); dqrobotics has no batch API, so its peers are single-formation only")
    print("n/i      : dqrobotics not installed")
    print("|u diff| : max abs difference (m/s, rad/s) of the peer's commands from quatform's, over")
    print(f"           the base formation and the first {N_COMPARE} batch formations")
    print("dqrobotics peers (one formation, numpy arrays in and out, conversion to/from DQ timed):")
    print("  quaternion      eqs. (9)-(15) forward kinematics with the reference as hint (minimal")
    print("                  rotation normalize(1 + dot(a, u) + cross(a, u)) of the hint's x axis a")
    print("                  onto the segment u, times the hint; q_ci = conj(q_c) * q_z(theta_i)),")
    print("                  errors conj(q_des) * q, eq. (20) command 0.5 q w + q_dot_des conj(q_des) q;")
    print("                  no antiparallel fallback (not reached here)")
    print("  dual-quaternion q_i = r_i + E_ 0.5 p_i r_i, qs = conj(q2) q1, qc = q2 h with h the decoupled")
    print("                  root (normalize(1 + r_s), r_s scalar >= 0; half translation), signs of the")
    print("                  reference, errors conj(q_des) q, eq. (28) command")
    print("                  0.5 q w + q_dot_des conj(q_des) q")
    print("  FD-J            robot rates = J @ command with the 8 x 16 inverse Jacobian built column by")
    print(f"                  column by central differences (step {FD_STEP:g}) of the inverse kinematics")
    print("                  written with DQ products (quaternion: x_c +- d Im(q_c i conj(q_c)),")
    print("                  yaw(q_c q_ci); dual-quaternion: q2 = qc conj(h(qs)), q1 = q2 qs,")
    print("                  p = 2 D(q) conj(P(q)), yaw = 2 atan2(r_z, r_w)): 32 inverse kinematics")
    print("                  evaluations per step")
    print("  JVP             robot rates = analytic derivative of the same inverse kinematics along")
    print("                  the command (product rule on the DQ expressions), one evaluation, as")
    print("                  quatform does")


if __name__ == "__main__":
    main()
