"""Keyframing: evaluating 10^6 samples of a 1000-key cubic track, kinema against
scipy.interpolate.CubicSpline (natural), in one process; plus construction time.

Run: python bench/bench_anim.py
"""

from __future__ import annotations

import time

import numpy as np
from scipy.interpolate import CubicSpline

from kinema.anim import Track


def best(fn, k: int = 5) -> float:
    fn()
    out = float("inf")
    for _ in range(k):
        start = time.perf_counter()
        fn()
        out = min(out, time.perf_counter() - start)
    return 1e3 * out


def main() -> None:
    rng = np.random.default_rng(0)
    t = np.cumsum(rng.uniform(0.5, 1.5, 1000))
    v = rng.normal(size=(1000, 3))
    s = rng.uniform(t[0], t[-1], 1_000_000)
    ours, ref = Track(t, v, "natural_cubic"), CubicSpline(t, v, bc_type="natural")
    np.testing.assert_allclose(ours(s[:1000]), ref(s[:1000]), atol=1e-10)
    rows = [
        (
            "build (1000 keys, 3 channels)",
            best(lambda: Track(t, v, "natural_cubic")),
            best(lambda: CubicSpline(t, v, bc_type="natural")),
        ),
        ("evaluate 10^6 samples", best(lambda: ours(s)), best(lambda: ref(s))),
        (
            "first derivative, 10^6 samples",
            best(lambda: ours.derivative()(s)),
            best(lambda: ref(s, 1)),
        ),
    ]
    print("| operation | kinema (ms) | scipy (ms) | scipy / kinema |")
    print("|---|---:|---:|---:|")
    for name, a, b in rows:
        print(f"| {name} | {a:.2f} | {b:.2f} | {b / a:.1f}x |")


if __name__ == "__main__":
    main()
