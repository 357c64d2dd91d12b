"""kinema.anim against scipy.interpolate, plus keys, extremes and bad input."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.interpolate import CubicHermiteSpline, CubicSpline

from kinema.anim import Track, subdivide

T = np.array([0.0, 0.4, 1.1, 1.5, 2.9, 3.0, 4.2])
V = np.array([[0.0, 1.0], [1.0, -1.0], [0.5, 2.0], [-0.3, 0.0], [2.0, 1.0], [2.1, 1.5], [0.0, 0.0]])
S = np.linspace(-0.0, 4.2, 997)


def test_natural_and_clamped_cubic_agree_with_scipy():
    nat = Track(T, V, "natural_cubic")
    ref = CubicSpline(T, V, bc_type="natural")
    for n in range(3):
        got = nat(S) if n == 0 else nat.derivative(n)(S)
        np.testing.assert_allclose(got, ref(S, n), atol=1e-12 * (1 + np.abs(ref(S, n)).max()))
    ends = np.array([[0.5, -1.0], [2.0, 0.3]])
    cl = Track(T, V, "clamped_cubic", end_tangents=ends)
    ref = CubicSpline(T, V, bc_type=((1, ends[0]), (1, ends[1])))
    np.testing.assert_allclose(cl(S), ref(S), atol=1e-12)
    np.testing.assert_allclose(
        Track(T, V, "clamped_cubic")(S), CubicSpline(T, V, bc_type="clamped")(S), atol=1e-12
    )


def test_hermite_agrees_with_scipy():
    m = np.sin(np.arange(14.0)).reshape(7, 2)
    tr = Track(T, V, "hermite", tangents=m)
    ref = CubicHermiteSpline(T, V, m)
    np.testing.assert_allclose(tr(S), ref(S), atol=1e-12)
    np.testing.assert_allclose(tr.derivative()(S), ref(S, 1), atol=1e-11)


@pytest.mark.parametrize(
    "kw",
    [
        {"interpolation": "step"},
        {"interpolation": "linear"},
        {"interpolation": "polynomial"},
        {"interpolation": "catmull_rom"},
        {"interpolation": "cardinal", "tension": 0.5},
        {"interpolation": "kochanek_bartels", "tension": 0.2, "continuity": 0.3, "bias": -0.4},
        {"interpolation": "bezier", "handles": np.ones((6, 2, 2))},
    ],
)
def test_interpolating_schemes_hit_their_keys(kw):
    tr = Track(T, V, **kw)
    np.testing.assert_allclose(tr(T), V, atol=1e-12)


def test_scalar_channels_shapes_and_extrapolation():
    tr = Track([0.0, 1.0, 2.0], [0.0, 1.0, 0.0], "catmull_rom", "cycle")
    assert isinstance(tr(0.5), float)
    assert tr(np.zeros((2, 3))).shape == (2, 3)
    assert tr(2.5) == pytest.approx(tr(0.5))
    lin = Track([0.0, 1.0], [0.0, 2.0], "linear", "linear")
    assert lin(3.0) == pytest.approx(6.0)
    assert Track([1.0], [7.0])(5.0) == 7.0


def test_million_keys_and_close_keys():
    t = np.linspace(0, 1, 1_000_001)
    tr = Track(t, np.sin(t), "natural_cubic")
    s = np.random.default_rng(0).uniform(0, 1, 1000)
    np.testing.assert_allclose(tr(s), np.sin(s), atol=1e-12)
    close = Track([0.0, 1e-9, 1.0], [0.0, 1e-9, 1.0], "natural_cubic")
    assert np.isfinite(close(np.linspace(0, 1, 11))).all()


def test_bad_input_names_the_problem():
    with pytest.raises(
        ValueError, match=r"times\[1\] = 2.0 and times\[2\] = 1.0|times\[1\] = 2 and times\[2\] = 1"
    ):
        Track([0.0, 2.0, 1.0], [0.0, 1.0, 2.0])
    with pytest.raises(ValueError, match="strictly increasing"):
        Track([0.0, 1.0, 1.0], [0.0, 1.0, 2.0])
    with pytest.raises(ValueError, match=r"values\[1\]"):
        Track([0.0, 1.0], [0.0, np.nan])
    with pytest.raises(ValueError, match="interpolation"):
        Track([0.0, 1.0], [0.0, 1.0], "akima")
    with pytest.raises(ValueError, match="tangents"):
        Track([0.0, 1.0], [0.0, 1.0], "hermite")
    with pytest.raises(ValueError, match=r"t\[1\]"):
        Track([0.0, 1.0], [0.0, 1.0])([0.5, np.nan])
    with pytest.warns(RuntimeWarning, match="Runge"):
        Track(np.arange(12.0), np.zeros(12), "polynomial")


def test_subdivision_shapes_and_interpolation():
    square = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    assert subdivide(square, "chaikin", 2, closed=True).shape == (16, 2)
    four = subdivide(square, "four_point", 2, closed=True)
    np.testing.assert_array_equal(four[::4], square)
    with pytest.raises(ValueError, match="scheme"):
        subdivide(square, "loop")


@settings(max_examples=50, deadline=None)
@given(
    st.lists(st.floats(-10, 10), min_size=3, max_size=12),
    st.sampled_from(["natural_cubic", "catmull_rom", "linear"]),
)
def test_property_interpolation_hits_keys(values, scheme):
    t = np.cumsum(np.linspace(0.5, 1.5, len(values)))
    tr = Track(t, values, scheme)
    np.testing.assert_allclose(tr(t), values, atol=1e-9 * (1 + np.abs(values).max()))


def test_rotation_track_slerp_matches_scipy_and_squad_is_smooth():
    from scipy.spatial.transform import Rotation as R
    from scipy.spatial.transform import Slerp

    from kinema import Rotation
    from kinema.anim import RotationTrack

    times = np.array([0.0, 0.7, 1.5, 2.0, 3.1])
    keys = Rotation.random(5, rng=5)
    s = np.linspace(0, 3.1, 401)
    ours = RotationTrack(times, keys, "slerp")(s)
    ref = Slerp(times, R.from_quat(keys.as_quat(), scalar_first=True))(s)
    np.testing.assert_allclose(ours.as_matrix(), ref.as_matrix(), atol=1e-12)
    tr = RotationTrack(times, keys, "slerp")
    w = tr.angular_velocity(0.3)
    expected = (keys[1] * keys[0].inv()).as_rotvec() / 0.7
    np.testing.assert_allclose(w, expected, atol=1e-12)

    uniform = np.arange(5.0)
    sq = RotationTrack(uniform, keys, "squad")
    assert np.all((sq(uniform) * keys.inv()).magnitude() < 1e-12)  # passes through its keys
    q = sq(np.linspace(0, 4, 101)).as_quat()
    np.testing.assert_allclose(np.linalg.norm(q, axis=1), 1.0, atol=1e-15)
    # C1: the angular velocity is continuous across interior keys (slerp's jumps).
    for k in (1.0, 2.0, 3.0):
        jump_squad = np.linalg.norm(sq.angular_velocity(k + 1e-4) - sq.angular_velocity(k - 1e-4))
        sl = RotationTrack(uniform, keys, "slerp")
        jump_slerp = np.linalg.norm(sl.angular_velocity(k + 1e-4) - sl.angular_velocity(k - 1e-4))
        assert jump_squad < 1e-2 < jump_slerp
    with pytest.raises(ValueError, match="interpolation"):
        RotationTrack(times, keys, "cubic")


def test_rotation_spline_matches_scipy_rotation_spline():
    from scipy.spatial.transform import Rotation as R
    from scipy.spatial.transform import RotationSpline

    from kinema import Rotation
    from kinema.anim import RotationTrack

    times = np.array([0.0, 0.7, 1.5, 2.0, 3.1, 3.4, 4.5])
    keys = Rotation.from_rotvec(np.random.default_rng(3).normal(scale=0.8, size=(7, 3)))
    ours = RotationTrack(times, keys, "spline")
    ref = RotationSpline(times, R.from_quat(keys.as_quat(), scalar_first=True))
    s = np.linspace(0, 4.5, 997)
    # scipy stops its fixed-point iteration at a relative change of 1e-9 (its angular
    # acceleration jumps by up to 3e-6 rad/s² at these keys); kinema iterates to 1e-13.
    np.testing.assert_allclose(ours(s).as_matrix(), ref(s).as_matrix(), atol=1e-7)
    # scipy's rates are in the body frame; kinema's in the world frame.
    body_w = ours(s).apply(ours.angular_velocity(s), inverse=True)
    np.testing.assert_allclose(body_w, ref(s, 1), atol=1e-6)
    body_a = ours(s).apply(ours.angular_acceleration(s), inverse=True)
    np.testing.assert_allclose(body_a, ref(s, 2), atol=1e-5)
    # C2 at the interior keys, where slerp and squad are not.
    for k in times[1:-1]:
        jump = ours.angular_acceleration(k + 1e-9) - ours.angular_acceleration(k - 1e-9)
        assert np.linalg.norm(jump) < 2e-7
    assert np.allclose(np.linalg.norm(ours(s).as_quat(), axis=1), 1.0, atol=1e-15)


def test_rotation_track_long_arc_and_bad_flags():
    from kinema import Rotation
    from kinema.anim import RotationTrack

    keys = Rotation.from_rotvec([[0, 0, 0], [0, 0.5, 0], [0, 1.0, 0]])
    tr = RotationTrack([0, 1, 2], keys, "slerp", shortest=[True, False])
    np.testing.assert_allclose(tr.angular_velocity(0.5), [0, 0.5, 0], atol=1e-12)
    np.testing.assert_allclose(tr.angular_velocity(1.5), [0, 0.5 - 2 * np.pi, 0], atol=1e-9)
    with pytest.raises(ValueError, match="shortest"):
        RotationTrack([0, 1, 2], keys, shortest=[True, False, True])
    with pytest.raises(ValueError, match="shortest"):
        RotationTrack([0, 1, 2], keys, shortest="yes")


def test_per_key_interpolation_modes():
    t = np.array([0.0, 1.0, 2.0, 3.5, 4.0])
    v = np.array([0.0, 1.0, -1.0, 2.0, 0.5])
    modes = ["step", "catmull_rom", "linear", "natural_cubic", "linear"]  # the last is unused
    mixed = Track(t, v, modes)
    np.testing.assert_allclose(mixed(t), v, atol=1e-15)
    for k, mode in enumerate(modes[:-1]):
        s = np.linspace(t[k], t[k + 1], 7)[1:-1]
        np.testing.assert_array_equal(mixed(s), Track(t, v, mode)(s))
    assert mixed(0.999) == 0.0  # the step segment holds its key
    with pytest.raises(ValueError, match="interpolation"):
        Track(t, v, ["linear", "linear"])
    with pytest.raises(ValueError, match="interpolation"):
        Track(t, v, ["linear", "polynomial", "linear", "linear"])
    with pytest.raises(ValueError, match="interpolation"):
        Track(t, v, ["linear", "cubic", "linear", "linear"])
    with pytest.raises(ValueError, match="cannot be mixed"):
        Track(t, v, ["hermite", "bezier", "linear", "linear"], tangents=np.zeros(5))


def test_arc_length_reparameterisation_moves_at_constant_speed():
    from kinema.anim import reparameterize_by_arc_length

    t = np.array([0.0, 0.3, 1.4, 2.0, 3.5])
    pts = np.array([[0, 0], [1, 2], [3, 2.5], [4, 0], [6, 1]], dtype=float)
    curve = reparameterize_by_arc_length(Track(t, pts, "catmull_rom"))
    s = np.linspace(0, curve.length, 2001)
    p = curve(s)
    step = np.linalg.norm(np.diff(p, axis=0), axis=1)
    # Equal arc-length steps: chords of equal arcs agree up to the curvature term κ²h²/24.
    np.testing.assert_allclose(step, curve.length / 2000, rtol=2e-4)
    # Independent oracle: scipy's adaptive quadrature of the speed up to time_at(s) gives s.
    from scipy.integrate import quad

    speed = Track(t, pts, "catmull_rom").derivative()
    for target in [0.1, 1.7, 4.2, curve.length * 0.9]:
        tt = float(curve.time_at(target))
        knots = [k for k in t if k < tt]
        total = sum(
            quad(lambda x: np.linalg.norm(speed(x)), a, b, epsabs=1e-13, epsrel=1e-13)[0]
            for a, b in zip(knots, [*knots[1:], tt], strict=True)
        )
        assert total == pytest.approx(target, abs=1e-9)
    np.testing.assert_allclose(p[0], pts[0], atol=1e-12)
    np.testing.assert_allclose(p[-1], pts[-1], atol=1e-9)
    # A straight line's length is exact.
    line = reparameterize_by_arc_length(
        Track([0.0, 1.0, 5.0], [[0, 0, 0], [1, 1, 1], [2, 2, 2]], "linear")
    )
    assert line.length == pytest.approx(2 * np.sqrt(3), rel=1e-12)
    np.testing.assert_allclose(line(np.sqrt(3)), [1, 1, 1], atol=1e-10)
    with pytest.raises(ValueError, match="track"):
        reparameterize_by_arc_length(Track([0.0], [1.0]))


def test_easing_and_clips():
    from kinema import Rotation
    from kinema.anim import Clip, RotationTrack, ease

    u = np.linspace(0, 1, 11)
    for kind in ["linear", "ease_in", "ease_out", "ease_in_out", "smoothstep"]:
        y = ease(u, kind)
        assert y[0] == 0.0 and y[-1] == pytest.approx(1.0) and np.all(np.diff(y) >= 0)
    # Ease-in starts at rest, ease-out ends at rest, ease-in-out does both.
    d = 1e-6
    assert ease(d, "ease_in") / d < 1e-5 and (1 - ease(1 - d, "ease_out")) / d < 1e-5
    assert ease(d, "ease_in_out") / d < 1e-5 and (1 - ease(1 - d, "ease_in_out")) / d < 1e-5
    with pytest.raises(ValueError, match="kind"):
        ease(0.5, "bounce")

    clip = Clip(
        {
            "opacity": Track([0.0, 2.0], [0.0, 1.0], "linear"),
            "turn": RotationTrack([0.5, 1.5], Rotation.random(2, rng=0)),
        }
    )
    assert clip.duration == 2.0
    t, values = clip.sample(24)
    assert len(t) == 49 and values["opacity"].shape == (49,) and len(values["turn"]) == 49
    np.testing.assert_allclose(values["opacity"], t / 2.0, atol=1e-15)
    with pytest.raises(ValueError, match="channels"):
        Clip({})


def parabola_arc(x):
    """Arc length of y = x² from 0 to x: (x √(1 + 4x²) + asinh(2x) / 2) / 2."""
    return (x * np.sqrt(1 + 4 * x**2) + np.arcsinh(2 * x) / 2) / 2


@pytest.mark.parametrize("kind", ["linear", "ease_in", "ease_out", "ease_in_out", "smoothstep"])
def test_eased_motion_along_a_path_covers_the_analytic_arc_length(kind):
    from kinema.anim import ease, reparameterize_by_arc_length

    # The parabola y = x², x in [0, 2], exactly: a cubic Hermite segment with end tangents
    # (2, 0) and (2, 8) reproduces (2t, 4t²).
    path = reparameterize_by_arc_length(
        Track([0.0, 1.0], [[0, 0], [2, 4]], "hermite", tangents=[[2, 0], [2, 8]])
    )
    assert path.length == pytest.approx(parabola_arc(2.0), rel=1e-10)
    u = np.linspace(0, 1, 41)
    p = path(ease(u, kind) * path.length)  # the eased motion along the path
    np.testing.assert_allclose(p[:, 1], p[:, 0] ** 2, atol=1e-9)  # on the parabola
    # The distance travelled at time u is the eased fraction of the analytic length.
    eased = {
        "linear": u,
        "ease_in": u**2,
        "ease_out": 1 - (1 - u) ** 2,
        "ease_in_out": (1 - np.cos(np.pi * u)) / 2,
        "smoothstep": 3 * u**2 - 2 * u**3,
    }[kind]
    np.testing.assert_allclose(parabola_arc(p[:, 0]), eased * parabola_arc(2.0), atol=1e-8)


def test_an_arc_length_tolerance_that_cannot_be_met_is_an_error_not_a_cap():
    from kinema.anim import reparameterize_by_arc_length

    # The cusp (t², t³) (a cubic: the Lagrange polynomial through 4 keys is exact) has a speed
    # with a kink at t = 0, inside a key interval and never on a subdivision point: the table
    # converges at second order, reaching 1e-6 and never 1e-12.
    t = np.array([-1.0, -0.35, 0.6, 1.2])
    cusp = Track(t, np.stack([t**2, t**3], axis=1), "polynomial")
    half = lambda x: ((4 + 9 * x**2) ** 1.5 - 8) / 27  # noqa: E731
    curve = reparameterize_by_arc_length(cusp, tol=1e-6)
    assert curve.length == pytest.approx(half(1.0) + half(1.2), rel=1e-6)
    with pytest.raises(ValueError, match=r"^tol: cannot be met"):
        reparameterize_by_arc_length(cusp, tol=1e-12)
    for bad in (0.0, -1.0, float("nan"), "x"):
        with pytest.raises(ValueError, match="tol"):
            reparameterize_by_arc_length(cusp, tol=bad)


def test_arc_length_helix_against_scipy_quad_and_bad_s():
    import pickle

    from scipy.integrate import quad

    from kinema.anim import reparameterize_by_arc_length

    u = np.linspace(0, 3 * np.pi, 25)
    r, p = 0.7, 0.4
    pts = np.stack([r * np.cos(u), r * np.sin(u), p * u / (2 * np.pi)], axis=1)
    tan = np.stack([-r * np.sin(u), r * np.cos(u), np.full_like(u, p / (2 * np.pi))], axis=1)
    track = Track(u, pts, "hermite", tangents=tan)
    curve = reparameterize_by_arc_length(track, tol=1e-12)
    speed = track.derivative()
    oracle = sum(
        quad(lambda x: np.linalg.norm(speed(x)), a, b, epsabs=1e-14, epsrel=1e-14)[0]
        for a, b in itertools.pairwise(u)
    )
    assert curve.length == pytest.approx(oracle, rel=1e-11)
    # The exact helix length differs only by the Hermite approximation (h = 3π/24).
    assert curve.length == pytest.approx(3 * np.pi * np.hypot(r, p / (2 * np.pi)), rel=1e-4)
    assert np.ndim(curve.time_at(1.0)) == 0
    assert curve.time_at([[0.5, 1.0]]).shape == (1, 2)
    with pytest.raises(ValueError, match=r"^s\[1\]: contains NaN"):
        curve.time_at([0.5, np.nan])
    again = pickle.loads(pickle.dumps(curve))
    np.testing.assert_array_equal(
        again(np.linspace(0, curve.length, 9)), curve(np.linspace(0, curve.length, 9))
    )


def test_easing_symmetry_and_nan_and_clip_errors():
    import pickle

    from kinema import Rotation
    from kinema.anim import Clip, RotationTrack, ease

    u = np.linspace(0, 1, 101)
    for kind in ["linear", "ease_in_out", "smoothstep"]:
        np.testing.assert_allclose(ease(u, kind) + ease(1 - u, kind), 1.0, atol=1e-15)
    np.testing.assert_allclose(ease(u, "ease_out"), 1 - ease(1 - u, "ease_in"), atol=1e-15)
    assert ease(-2.0, "smoothstep") == 0.0 and ease(5.0, "ease_in") == 1.0
    with pytest.raises(ValueError, match=r"^u\[0\]: contains NaN"):
        ease([np.nan])
    with pytest.raises(ValueError, match="kind") as info:
        ease(0.5, "bounce")
    assert "bounce" not in str(info.value)

    clip = Clip(
        {
            "x": Track([0.5, 2.0], [[0.0, 0.0], [3.0, 1.0]], "linear"),
            "turn": RotationTrack([1.0, 3.0], Rotation.random(2, rng=1)),
        }
    )
    assert (clip.start, clip.end, clip.duration) == (0.5, 3.0, 2.5)
    t, v = clip.sample(24)
    np.testing.assert_array_equal(t, 0.5 + np.arange(61) / 24.0)
    assert v["x"].shape == (61, 2) and isinstance(v["turn"], Rotation) and len(v["turn"]) == 61
    for fps in (0, -24, float("nan"), float("inf"), "fast"):
        with pytest.raises(ValueError, match=r"^fps") as info:
            clip.sample(fps)
        assert "fast" not in str(info.value)
    t2, v2 = pickle.loads(pickle.dumps(clip)).sample(24)
    np.testing.assert_array_equal(t2, t)
    np.testing.assert_array_equal(v2["x"], v["x"])
    with pytest.raises(ValueError, match="channels"):
        Clip({"v": Track([0.0, 1.0], [0.0, 1.0]).derivative()})
