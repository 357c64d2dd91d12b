"""Rotations demo: why animators interpolate quaternions, not Euler angles.

Writes ``rotations.png`` with three panels:

1. the path of a body axis on the unit sphere when interpolating two orientations by linear
   blending of XYZ Euler angles against quaternion slerp (the great circle);
2. the angular speed along both paths: slerp's is constant, the Euler blend's is not;
3. gimbal lock: the smallest singular value of the map from Euler-angle rates to angular
   velocity, which falls to zero as the middle angle reaches 90° (one degree of freedom lost).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from kinema.rotation import Rotation, gimbal_lock, slerp


def _angular_speed(path: Rotation, dt: float) -> np.ndarray:
    """Angular speed (rad/s) between consecutive rotations of a stack sampled every ``dt``."""
    return (path[1:] * path[:-1].inv()).magnitude() / dt


def _rate_jacobian_min_singular_value(seq: str, angles: np.ndarray, h: float = 1e-7) -> float:
    """Smallest singular value of d(omega)/d(angles) by central differences of rotation vectors."""
    r = Rotation.from_euler(seq, angles)
    cols = []
    for j in range(3):
        step = np.zeros(3)
        step[j] = h
        plus = Rotation.from_euler(seq, angles + step) * r.inv()
        minus = Rotation.from_euler(seq, angles - step) * r.inv()
        cols.append((plus.as_rotvec() - minus.as_rotvec()) / (2 * h))
    return float(np.linalg.svd(np.column_stack(cols), compute_uv=False)[-1])


def run(out_dir: Path, quick: bool) -> dict[str, object]:
    """Draw the three panels into ``out_dir/rotations.png`` and return the key numbers."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = 60 if quick else 400
    t = np.linspace(0.0, 1.0, n)
    a0 = np.deg2rad([10.0, 20.0, 30.0])
    a1 = np.deg2rad([150.0, 60.0, -120.0])
    r0, r1 = Rotation.from_euler("XYZ", a0), Rotation.from_euler("XYZ", a1)

    euler_path = Rotation.from_euler("XYZ", a0 + t[:, None] * (a1 - a0))
    slerp_path = slerp(r0, r1, t)
    axis = np.array([0.0, 0.0, 1.0])
    euler_tip, slerp_tip = euler_path.apply(axis), slerp_path.apply(axis)
    dt = t[1] - t[0]
    w_euler, w_slerp = _angular_speed(euler_path, dt), _angular_speed(slerp_path, dt)

    pitches = np.deg2rad(np.linspace(0.0, 90.0, 31 if quick else 91))
    sigma = np.array(
        [_rate_jacobian_min_singular_value("XYZ", np.array([0.3, p, -0.4])) for p in pitches]
    )
    locked = gimbal_lock("XYZ", [0.3, np.pi / 2, -0.4])

    fig = plt.figure(figsize=(15, 4.6))
    ax = fig.add_subplot(1, 3, 1, projection="3d")
    u, v = np.mgrid[0 : 2 * np.pi : 40j, 0 : np.pi : 20j]
    ax.plot_wireframe(np.cos(u) * np.sin(v), np.sin(u) * np.sin(v), np.cos(v), color="0.85", lw=0.4)
    ax.plot(*euler_tip.T, label="Euler-angle blend", color="tab:red")
    ax.plot(*slerp_tip.T, label="slerp (great circle)", color="tab:blue")
    ax.set_title("path of the body z axis")
    ax.legend(loc="lower left", fontsize=8)
    ax.set_box_aspect((1, 1, 1))

    ax = fig.add_subplot(1, 3, 2)
    ax.plot(t[1:], w_euler, color="tab:red", label="Euler-angle blend")
    ax.plot(t[1:], w_slerp, color="tab:blue", label="slerp")
    ax.set_xlabel("t")
    ax.set_ylabel("angular speed (rad per unit t)")
    ax.set_title("angular speed along the path")
    ax.legend(fontsize=8)

    ax = fig.add_subplot(1, 3, 3)
    ax.plot(np.rad2deg(pitches), sigma, marker=".", color="tab:purple")
    ax.set_xlabel("middle angle of XYZ (degrees)")
    ax.set_ylabel("smallest singular value of ∂ω/∂angles")
    ax.set_title("gimbal lock: a degree of freedom vanishes at 90°")
    fig.tight_layout()
    path = out_dir / "rotations.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)

    return {
        "picture": str(path),
        "slerp angular speed (min, max)": f"{w_slerp.min():.12f}, {w_slerp.max():.12f}",
        "Euler blend angular speed (min, max)": f"{w_euler.min():.4f}, {w_euler.max():.4f}",
        "Euler blend path length / slerp path length": f"{(w_euler.sum() / w_slerp.sum()):.4f}",
        "smallest rate singular value at 0°, 45°, 90°": ", ".join(
            f"{sigma[i]:.2e}" for i in (0, len(sigma) // 2, -1)
        ),
        "XYZ angles (0.3, 90°, -0.4) at gimbal lock": bool(locked),
    }
