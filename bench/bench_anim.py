"""Keyframing: evaluating 10^6 samples of a 1000-key cubic track, kinema against
scipy.interpolate.CubicSpline (natural), and of 1000-key rotation tracks against scipy's
Slerp and RotationSpline, in one process; plus construction time.

Run: python bench/bench_anim.py [--quick]
(--quick: 10^5 samples, best of 2.)
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from kinema import Rotation
from kinema.anim import RotationTrack, Track

try:
    from scipy.interpolate import CubicSpline
    from scipy.spatial.transform import Rotation as R
    from scipy.spatial.transform import RotationSpline, Slerp
except ImportError:
    CubicSpline = None


def best(fn, k: int) -> float:
    fn()
    out = float("inf")
    for _ in range(k):
        start = time.perf_counter()
        fn()
        out = min(out, time.perf_counter() - start)
    return 1e3 * out


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--quick", action="store_true", help="10^5 samples, best of 2")
    args = parser.parse_args()
    if CubicSpline is None:
        print("scipy: not installed, nothing to compare with")
        return
    e, k = (5, 2) if args.quick else (6, 5)
    rng = np.random.default_rng(0)
    t = np.cumsum(rng.uniform(0.5, 1.5, 1000))
    v = rng.normal(size=(1000, 3))
    s = rng.uniform(t[0], t[-1], 10**e)
    ours, ref = Track(t, v, "natural_cubic"), CubicSpline(t, v, bc_type="natural")
    np.testing.assert_allclose(ours(s[:1000]), ref(s[:1000]), atol=1e-10)
    rows = [
        (
            "build (1000 keys, 3 channels)",
            lambda: Track(t, v, "natural_cubic"),
            lambda: CubicSpline(t, v, bc_type="natural"),
        ),
        (f"evaluate 10^{e} samples", lambda: ours(s), lambda: ref(s)),
        (f"first derivative, 10^{e} samples", lambda: ours.derivative()(s), lambda: ref(s, 1)),
    ]
    keys = Rotation.from_rotvec(rng.normal(scale=0.6, size=(1000, 3)))
    sp_keys = R.from_quat(keys.as_quat(), scalar_first=True)
    slerp, sp_slerp = RotationTrack(t, keys, "slerp"), Slerp(t, sp_keys)
    spline, sp_spline = RotationTrack(t, keys, "spline"), RotationSpline(t, sp_keys)
    np.testing.assert_allclose(
        slerp(s[:1000]).as_matrix(), sp_slerp(s[:1000]).as_matrix(), atol=1e-12
    )
    # scipy stops after 10 fixed-point iterations (relative change 1e-9 or not): on 1000 keys
    # its orientations differ from the converged spline by up to ~2e-5.
    diff = np.abs(spline(s[:1000]).as_matrix() - sp_spline(s[:1000]).as_matrix()).max()
    assert diff < 1e-4, diff
    print(f"rotation spline: largest difference from scipy {diff:.1e}")
    rows += [
        (
            "slerp track: build (1000 keys)",
            lambda: RotationTrack(t, keys, "slerp"),
            lambda: Slerp(t, sp_keys),
        ),
        (f"slerp track: evaluate 10^{e} samples", lambda: slerp(s), lambda: sp_slerp(s)),
        (
            "rotation spline: build (1000 keys)",
            lambda: RotationTrack(t, keys, "spline"),
            lambda: RotationSpline(t, sp_keys),
        ),
        (f"rotation spline: evaluate 10^{e} samples", lambda: spline(s), lambda: sp_spline(s)),
        (
            f"rotation spline: angular velocity, 10^{e} samples",
            lambda: spline.angular_velocity(s),
            lambda: sp_spline(s, 1),
        ),
    ]
    print("| operation | kinema (ms) | scipy (ms) | scipy / kinema |")
    print("|---|---:|---:|---:|")
    for name, mine, theirs in rows:
        a, b = best(mine, k), best(theirs, k)
        print(f"| {name} | {a:.2f} | {b:.2f} | {b / a:.1f}x |")


if __name__ == "__main__":
    main()
