"""The ``quatform demo`` job: the algebra at work on the seeds' questions (top layer).

Until the formation layers land, the demo shows three things a reader of the seeds cares
about: (1) where the cluster frame of seed 000 eq. (26) sits with each dual-quaternion
square root, (2) that quaternion rates stay well conditioned through pitch 90 degrees
where Euler-angle rates blow up, (3) how the integrators of seed 001 §2.2.7 drift.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from .algebra import (
    dq_from_pose,
    dqconj,
    dqmul,
    dqsqrt_decoupled,
    dqsqrt_screw,
    integrate,
    pose_from_dq,
    q_angle_between,
    q_from_axis_angle,
    qdot_matrix,
    qmul,
    qnorm,
)


def cluster_frame_example() -> dict:
    """Cluster frame ``q2 (q2* q1)^(1/2)`` of two robots with each square root."""
    q1 = q_from_axis_angle([0.0, 0.0, 1.0], np.radians(30.0))
    q2 = qmul(q_from_axis_angle([0.0, 0.0, 1.0], np.radians(150.0)),
              q_from_axis_angle([0.0, 1.0, 0.0], np.radians(90.0)))
    p1, p2 = np.array([1.0, 0.5, 2.0]), np.array([-1.0, -0.5, 1.0])
    d1, d2 = dq_from_pose(q1, p1), dq_from_pose(q2, p2)
    s = dqmul(dqconj(d2), d1)  # seed 000 eq. (27)
    mid = 0.5 * (p1 + p2)
    out = {"robot1": p1.tolist(), "robot2": p2.tolist(), "midpoint": mid.tolist()}
    for name, root in (("decoupled", dqsqrt_decoupled), ("screw", dqsqrt_screw)):
        qc, pc = pose_from_dq(dqmul(d2, root(s)))  # seed 000 eq. (26)
        out[name] = {
            "position": pc.tolist(),
            "distance_to_midpoint_m": float(np.linalg.norm(pc - mid)),
            "angle_to_robot1_deg": float(np.degrees(q_angle_between(qc, q1))),
            "angle_to_robot2_deg": float(np.degrees(q_angle_between(qc, q2))),
        }
    return out


def euler_rate_gain(roll, pitch) -> float:
    """Largest gain of the ZYX Euler-angle rate map ``d(yaw, pitch, roll)/dt = E omega_body``.

    ``E = [[0, sr/cp, cr/cp], [0, cr, -sr], [1, sr tp, cr tp]]``; the gain (2-norm) is the
    same for world-frame angular velocity. Infinite at ``cos(pitch) = 0``.
    """
    cr, sr, cp = np.cos(roll), np.sin(roll), np.cos(pitch)
    if abs(cp) < 1e-15:
        return float("inf")
    tp = np.tan(pitch)
    return float(np.linalg.norm(np.array([[0.0, sr / cp, cr / cp], [0.0, cr, -sr], [1.0, sr * tp, cr * tp]]), 2))


def quaternion_rate_gains(roll, pitch) -> np.ndarray:
    """Singular values of ``G(q)`` with ``q_dot = G(q) omega`` at the same attitude."""
    q = qmul(q_from_axis_angle([0, 1, 0], pitch), q_from_axis_angle([1, 0, 0], roll))
    return np.linalg.svd(qdot_matrix(q), compute_uv=False)


def conditioning_example(pitches_deg=(0.0, 60.0, 89.0, 89.99, 90.0)) -> list[dict]:
    """Largest gain from angular velocity to parameter rates, Euler angles vs quaternions."""
    rows = []
    for deg in pitches_deg:
        pitch = np.radians(deg)
        sv = quaternion_rate_gains(0.3, pitch)
        rows.append({"pitch_deg": deg, "euler_rate_gain": euler_rate_gain(0.3, pitch),
                     "quaternion_rate_gain_max": float(sv.max()), "quaternion_rate_gain_min": float(sv.min())})
    return rows


def drift_example(steps: int = 20000, dt: float = 0.01) -> dict:
    """Norm and angle error of each integrator after ``steps`` constant-rate steps."""
    omega = np.array([0.3, -0.5, 0.8])
    exact = q_from_axis_angle(omega, np.linalg.norm(omega) * steps * dt)
    out = {}
    for method in ("exp", "euler-normalized", "euler-log", "euler"):
        q = np.array([1.0, 0.0, 0.0, 0.0])
        for _ in range(steps):
            q = integrate(q, omega, dt, method=method)
        n = float(qnorm(q))
        out[method] = {"norm_minus_1": n - 1.0,
                       "angle_error_rad": float(q_angle_between(q / n, exact))}
    return out


def run(out: str | Path | None = None) -> dict:
    """Run the demo, print a report, and if ``out`` is given write ``summary.json`` and a plot."""
    if out is not None:
        out = Path(out)
        out.mkdir(parents=True, exist_ok=True)
    result = {"cluster_frame": cluster_frame_example(),
              "rate_conditioning": conditioning_example(),
              "integrator_drift": drift_example()}
    cf = result["cluster_frame"]
    print("quatform demo - the algebra layer at work\n")
    print("1. Cluster frame of seed 000 eq. (26), q2 (q2* q1)^(1/2), robots at",
          cf["robot1"], "and", cf["robot2"])
    for name in ("decoupled", "screw"):
        r = cf[name]
        print(f"   {name:9s} root: position {np.round(r['position'], 3).tolist()}, "
              f"{r['distance_to_midpoint_m']:.3f} m from the midpoint, "
              f"{r['angle_to_robot1_deg']:.1f} deg / {r['angle_to_robot2_deg']:.1f} deg to the robots")
    print("\n2. Gain from angular velocity to orientation-parameter rates (roll 0.3 rad)")
    print("   pitch [deg]   Euler ZYX     quaternion (min..max)")
    for row in result["rate_conditioning"]:
        print(f"   {row['pitch_deg']:10.2f}   {row['euler_rate_gain']:10.4g}    "
              f"{row['quaternion_rate_gain_min']:.3f}..{row['quaternion_rate_gain_max']:.3f}")
    print("\n3. Integrating q_dot = 1/2 omega q, 20 000 steps of 10 ms (seed 001 eqs. 2.36-2.38)")
    for method, r in result["integrator_drift"].items():
        print(f"   {method:17s} | ||q|| - 1 = {r['norm_minus_1']:+.2e} | angle error {r['angle_error_rad']:.2e} rad")
    if out is not None:
        (out / "summary.json").write_text(json.dumps(result, indent=2))
        _plot(result, out / "demo.png")
        print(f"\nwrote {out / 'summary.json'} and {out / 'demo.png'}")
    return result


def _plot(result: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    pitches = np.linspace(0.0, 90.0, 400)
    euler = [euler_rate_gain(0.3, np.radians(d)) for d in pitches]
    quat = [quaternion_rate_gains(0.3, np.radians(d)).max() for d in pitches]
    fig, ax = plt.subplots(figsize=(6, 4))
    ax.semilogy(pitches, np.where(np.isinf(euler), np.nan, euler), label="Euler ZYX angle rates")
    ax.semilogy(pitches, quat, label="quaternion rates")
    ax.axvline(90.0, color="k", lw=0.5, ls="--")
    ax.set_xlabel("pitch [deg]")
    ax.set_ylabel("gain from angular velocity to parameter rates")
    ax.set_title("Orientation-rate conditioning: the pitch 90 deg singularity")
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
