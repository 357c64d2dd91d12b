"""kinema.rods: the large-deflection cantilever against the elastica (a shooting solution
with scipy), a straight rod at rest, views, pickling, failed steps and bad arguments."""

from __future__ import annotations

import pickle

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

import kinema
from kinema.rods import Rod

SOFT = {"radius": 0.01, "youngs_modulus": 1e6, "shear_modulus": 4e5, "density": 1000.0}


def cantilever(n: int, length: float = 1.0, **kwargs: object) -> Rod:
    """A horizontal cantilever of ``n + 1`` edges along +x, clamped at its first edge, whose
    middle (the clamp point of the discrete beam, see docs/rods.md) is the origin."""
    h = length / (n + 0.5)
    points = np.zeros((n + 2, 3))
    points[:, 0] = (np.arange(n + 2) - 0.5) * h
    rod = Rod(points, **{**SOFT, "gravity": (0.0, 0.0, 0.0), **kwargs})  # type: ignore[arg-type]
    rod.clamp(0)
    return rod


def elastica_tip(load: float) -> tuple[float, float]:
    """Tip ``(x, y)`` of an inextensible cantilever of unit length and bending stiffness
    under a dead vertical tip load ``load = F L² / EI`` (Bisshopp & Drucker 1945), by
    shooting: ``θ'' = -load cos θ``, ``θ(0) = 0``, ``θ'(1) = 0``, with ``x' = cos θ``,
    ``y' = -sin θ`` (θ the downward angle)."""

    def run(k0: float) -> np.ndarray:
        def rhs(_s: float, u: np.ndarray) -> list[float]:
            th, dth = u[0], u[1]
            return [dth, -load * np.cos(th), np.cos(th), -np.sin(th)]

        sol = solve_ivp(rhs, (0.0, 1.0), [0.0, k0, 0.0, 0.0], rtol=1e-12, atol=1e-12)
        return sol.y[:, -1]

    k0 = brentq(lambda k: run(k)[1], 1e-9, load, xtol=1e-14)
    end = run(k0)
    return float(end[2]), float(end[3])


@pytest.mark.parametrize("load", [1.0, 3.0, 10.0])
def test_large_deflection_matches_the_elastica(load: float) -> None:
    rod = cantilever(40)
    ei = rod.stiffness["bending"][0]
    rod.set_force(-1, (0.0, -load * ei, 0.0))
    rod.solve_static()
    x, y = elastica_tip(load)
    tip = rod.positions[-1]
    # Within 1 % of the length in each coordinate, and 1 % of the deflection.
    assert abs(tip[0] - x) < 0.01 and abs(tip[1] - y) < 0.01, (tip, x, y)
    assert abs(tip[1] / y - 1.0) < 0.01, (tip, x, y)


def test_straight_rod_is_at_rest_and_frames_are_orthonormal() -> None:
    rod = Rod.straight(10, 0.5, direction=(0.0, 0.0, 2.0), gravity=(0.0, 0.0, 0.0))
    assert len(rod) == 10 and rod.twists.shape == (9,)
    assert rod.energy() < 1e-25
    rod.step(1.0 / 60.0, steps=10)
    np.testing.assert_allclose(rod.positions[:, 2], np.linspace(0.0, 0.5, 10), atol=1e-12)
    f = rod.material_frames
    assert f.shape == (9, 3, 3)
    np.testing.assert_allclose(
        f @ f.transpose(0, 2, 1), np.broadcast_to(np.eye(3), f.shape), atol=1e-12
    )
    np.testing.assert_allclose(f[:, 0], np.broadcast_to([0.0, 0.0, 1.0], (9, 3)), atol=1e-12)
    np.testing.assert_allclose(np.cross(f[:, 1], f[:, 2]), f[:, 0], atol=1e-12)


def test_twisted_rod_stores_twist_energy() -> None:
    """A rod twisted uniformly by ``Φ`` over its length ``L`` (both ends free of load) holds
    ``GJ Φ² / (2 L')`` with ``L'`` the interior vertices' Voronoi length."""
    n, length, total = 11, 1.0, 1.5
    twist = np.linspace(0.0, total, n - 1)
    rod = Rod.straight(n, length, twist=twist, gravity=(0.0, 0.0, 0.0), **SOFT)  # type: ignore[arg-type]
    gj = rod.stiffness["twisting"]
    h = length / (n - 1)
    per_vertex = total / (n - 2)
    expected = (n - 2) * gj * per_vertex**2 / (2.0 * h)
    assert rod.energy() == pytest.approx(expected, rel=1e-12)


def test_views_are_read_only_and_outlive_the_rod() -> None:
    rod = cantilever(8, gravity=(0.0, -9.81, 0.0))
    x = rod.positions
    assert not x.flags.writeable
    with pytest.raises(ValueError):
        x[0, 0] = 1.0
    rod.step(0.01, 3)
    assert x[-1, 1] < 0.0  # updated in place
    del rod
    assert np.isfinite(x).all()


def test_pickle_resumes_bitwise() -> None:
    rod = cantilever(8, gravity=(0.0, -9.81, 0.0))
    rod.step(1.0 / 60.0, 5)
    copy = pickle.loads(pickle.dumps(rod))
    rod.step(1.0 / 60.0, 5)
    copy.step(1.0 / 60.0, 5)
    assert np.array_equal(rod.positions, copy.positions)
    assert np.array_equal(rod.twists, copy.twists)
    assert rod.time == copy.time


def test_a_failed_step_leaves_the_rod_as_it_was() -> None:
    rod = cantilever(8, gravity=(0.0, -9.81, 0.0), max_iterations=1)
    before = rod.positions.copy()
    with pytest.raises(kinema.SimulationError):
        rod.step(0.5)
    assert np.array_equal(rod.positions, before)
    explicit = cantilever(8, gravity=(0.0, -9.81, 0.0), integrator="symplectic")
    with pytest.raises(kinema.SimulationError, match="diverged"):
        explicit.step(0.05, 100)
    assert np.array_equal(explicit.positions[:, 1], np.zeros(10))


SECRET = "zebra-7731"


@pytest.mark.parametrize(
    ("kwargs", "error", "name"),
    [
        ({"points": [[0.0, 0.0, 0.0]]}, ValueError, "points"),
        ({"points": [[0.0, 0.0, 0.0], [np.nan, 0.0, 0.0]]}, ValueError, "points"),
        ({"points": [[0.0, 0.0, 0.0], [0.0, 0.0, 0.0]]}, ValueError, "points"),
        ({"points": SECRET}, ValueError, "points"),
        ({"radius": -1.0}, ValueError, "radius"),
        ({"radius": [1.0, 2.0, 3.0]}, ValueError, "radius"),
        ({"radius": SECRET}, ValueError, "radius"),
        ({"youngs_modulus": 0.0}, ValueError, "youngs_modulus"),
        ({"youngs_modulus": SECRET}, TypeError, "youngs_modulus"),
        ({"shear_modulus": np.inf}, ValueError, "shear_modulus"),
        ({"density": -1.0}, ValueError, "density"),
        ({"twist": [0.0]}, ValueError, "twist"),
        ({"twist": SECRET}, ValueError, "twist"),
        ({"integrator": SECRET}, ValueError, "integrator"),
        ({"tolerance": 0.0}, ValueError, "tolerance"),
        ({"max_iterations": 0}, ValueError, "max_iterations"),
        ({"gravity": (0.0, np.nan, 0.0)}, ValueError, "gravity"),
    ],
)
def test_bad_arguments_name_the_argument(kwargs: dict, error: type, name: str) -> None:
    args = {"points": [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]], **kwargs}
    with pytest.raises(error, match=f"^{name}") as info:
        Rod(**args)
    assert SECRET not in str(info.value)


def test_bad_method_arguments_name_the_argument() -> None:
    rod = Rod.straight(5, 1.0)
    for call, name in [
        (lambda: rod.step(-1.0), "dt"),
        (lambda: rod.step(np.nan), "dt"),
        (lambda: rod.step(0.01, steps=-1), "steps"),
        (lambda: rod.clamp(3), "end"),
        (lambda: rod.pin(5), "index"),
        (lambda: rod.set_force(0, (np.inf, 0.0, 0.0)), "force"),
        (lambda: rod.set_force(9, (0.0, 0.0, 0.0)), "index"),
    ]:
        with pytest.raises(ValueError, match=f"^{name}"):
            call()
    with pytest.raises(TypeError, match=r"^index"):
        rod.pin(1.5)  # type: ignore[arg-type]
    for bad in [(lambda: Rod.straight(1, 1.0), "n"), (lambda: Rod.straight(3, -1.0), "length")]:
        with pytest.raises(ValueError, match=f"^{bad[1]}"):
            bad[0]()


def both_clamped(edges: int = 20) -> Rod:
    """A straight rod along +x of ``edges`` edges clamped at both ends, the clamped edges'
    middles 1 m apart, no gravity."""
    h = 1.0 / (edges - 1)
    points = np.zeros((edges + 1, 3))
    points[:, 0] = (np.arange(edges + 1) - 0.5) * h
    rod = Rod(points, **{**SOFT, "gravity": (0.0, 0.0, 0.0)})  # type: ignore[arg-type]
    rod.clamp(0)
    rod.clamp(-1)
    return rod


def test_turning_a_clamp_twists_the_rod_by_the_turn() -> None:
    """Turning the far clamp by φ about the axis (in turns under half a turn, each to static
    equilibrium) stores the twist energy ``GJ φ² / (2L)`` of a uniformly twisted rod, φ up
    to 5 rad (beyond ±π: twist is counted continuously), and the rod stays straight (below
    Greenhill's 8.99 B/GJ = 11.2 rad here)."""
    rod = both_clamped()
    gj = rod.stiffness["twisting"]
    for k in range(1, 11):
        phi = 0.5 * k
        rod.move_clamp(-1, kinema.Rotation.from_rotvec([phi, 0.0, 0.0]))
        rod.solve_static()
        assert rod.energy() == pytest.approx(gj * phi**2 / 2.0, rel=1e-9)
    assert np.abs(rod.positions[:, 1:]).max() < 1e-12
    frames = rod.material_frames
    assert frames[-1, 1] == pytest.approx([0.0, -np.sin(5.0), np.cos(5.0)], abs=1e-12)


def test_moving_a_clamp_carries_the_end_with_the_motions_velocity() -> None:
    rod = both_clamped()
    rest = rod.positions.copy()
    rod.move_clamp(0, None, (0.0, 0.1, 0.0))
    rod.step(0.01, 4)
    assert rod.positions[:2] == pytest.approx(rest[:2] + np.array([0.0, 0.1, 0.0]), abs=1e-15)
    assert rod.velocities[:2] == pytest.approx(np.tile([0.0, 2.5, 0.0], (2, 1)), abs=1e-12)
    rod.step(0.01, 2)  # the motion is done: the end stays
    assert rod.positions[:2] == pytest.approx(rest[:2] + np.array([0.0, 0.1, 0.0]), abs=1e-15)
    assert np.abs(rod.velocities[:2]).max() == 0.0


def test_rod_rests_on_a_plane_collider() -> None:
    from kinema.geometry import Plane

    rod = Rod.straight(11, 0.2, origin=(0.0, 0.02, 0.0), radius=2e-3, youngs_modulus=1e9)
    rod.add_collider(Plane(friction=0.3))
    rod.step(1.0 / 60.0, 120)
    sunk = 2e-3 - rod.positions[:, 1]
    assert (sunk > 0.0).all()
    weight = rod.masses.sum() * 9.81
    assert (1e4 * sunk).sum() == pytest.approx(weight, rel=1e-3)


def test_bad_clamp_and_collider_arguments_name_the_argument() -> None:
    from kinema.geometry import Plane, Sphere

    rod = Rod.straight(5, 1.0)
    rod.clamp(0)
    bad = [
        (lambda: rod.move_clamp(-1), "end"),
        (lambda: rod.move_clamp(2), "end"),
        (lambda: rod.move_clamp(0, None, (np.nan, 0.0, 0.0)), "translation"),
        (lambda: rod.add_collider(Plane(restitution=0.5)), "restitution"),
        (lambda: rod.add_collider(Sphere((0, 0, 0), 1.0, inside=True)), "inside"),
        (lambda: rod.add_collider(Sphere((0, 0, 0), -1.0)), "radius"),
        (lambda: rod.add_collider(Plane(friction=-1.0)), "friction"),
        (lambda: rod.add_collider(Plane(velocity=(1.0, 0.0, 0.0))), "velocity"),
        (lambda: Rod.straight(5, 1.0, contact_stiffness=0.0), "contact_stiffness"),
        (lambda: Rod.straight(5, 1.0, friction_velocity=-1.0), "friction_velocity"),
    ]
    for call, name in bad:
        with pytest.raises(ValueError, match=f"^{name}"):
            call()
    with pytest.raises(TypeError, match=r"^collider"):
        rod.add_collider(SECRET)  # type: ignore[arg-type]


def ring(edges: int = 24, g: float = 5e5) -> Rod:
    """A naturally straight ring of 1 m circumference (``r = 1 cm``, ``E = 1 MPa``) in the
    ``xy`` plane, no gravity (Michell's ring)."""
    phi = 2 * np.pi * np.arange(edges) / edges
    points = np.c_[np.cos(phi), np.sin(phi), np.zeros(edges)] / (2 * np.pi)
    rod = Rod(points, **{**SOFT, "shear_modulus": g, "gravity": (0, 0, 0)}, closed=True)
    rod.straighten()
    return rod


def twisted_ring(tw: float, g: float = 5e5) -> Rod:
    """The ring twisted to ``tw`` (rad) quasi-statically, in turns under a quarter turn."""
    rod = ring(g=g)
    turns = int(np.ceil(tw / 1.5))
    for _ in range(turns):
        rod.twist_ring(tw / turns)
        rod.step(0.02, 5)
    return rod


def test_a_twisted_ring_holds_its_twist_evenly() -> None:
    """A ring twisted by 4 rad stays planar, its twist angles step by ``Tw / n`` and its energy
    grows by ``C Tw² / (2 L)`` less the discrete twist–bend coupling (docs/rods.md)."""
    rod, still = twisted_ring(4.0), ring()
    assert len(rod.twists) == 24 and len(rod) == 24
    assert np.abs(rod.positions[:, 2]).max() < 1e-12
    np.testing.assert_allclose(np.diff(rod.twists), 4.0 / 24, atol=1e-9)
    c, bend = rod.stiffness["twisting"], still.energy()
    length = 24 * np.sin(np.pi / 24) / np.pi  # the 24-gon's perimeter
    want = c * 16.0 / (2.0 * length) - bend * np.sin(4.0 / 48) ** 2
    assert abs((rod.energy() - bend) / want - 1.0) < 1e-6


def michell_unstable(tw: float) -> bool:
    """Whether the ring twisted to ``tw`` leaves its plane (by 1 cm within 6 s) after a push in
    its two-wave mode (0.1 s of a force of 0.1 mN per vertex)."""
    rod = twisted_ring(tw)
    for i, p in enumerate(rod.positions):
        rod.set_force(i, (0, 0, 1e-4 * np.cos(2 * np.arctan2(p[1], p[0]))))
    rod.step(0.02, 5)
    for i in range(len(rod)):
        rod.set_force(i, (0, 0, 0))
    for _ in range(60):
        rod.step(0.02, 5)
        if np.abs(rod.positions[:, 2]).max() > 1e-2:
            return True
    return False


def test_a_twisted_ring_buckles_past_michells_twist() -> None:
    """Michell (1889): a naturally straight ring with ``B = C`` is stable below
    ``Tw_c = 2π √3 B / C`` and buckles above it: stable at 0.9 Tw_c, unstable at 1.1 Tw_c
    (24 edges; the Rust test bisects the threshold to within 5 %)."""
    twc = 2 * np.pi * np.sqrt(3)
    assert not michell_unstable(0.9 * twc)
    assert michell_unstable(1.1 * twc)


def test_ring_arguments_are_checked() -> None:
    with pytest.raises(ValueError, match="points"):
        Rod(np.eye(3)[:2], closed=True)
    with pytest.raises(TypeError, match="closed"):
        Rod(np.eye(3), closed="yes")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="model"):
        Rod(np.eye(3)).twist_ring(1.0)
    with pytest.raises(ValueError, match="angle"):
        ring().twist_ring(float("nan"))


def _strain(rod: Rod, rest: float) -> float:
    edges = np.linalg.norm(np.diff(rod.positions, axis=0), axis=1)
    return float(np.max(np.abs(edges / rest - 1.0)))


def test_inextensible_rope_keeps_its_edge_lengths() -> None:
    # A soft rope (EA = 31 N against 3 N of weight) clamped horizontally and dropped for 1 s
    # at dt = 1/60: elastic it stretches by per cents, inextensible by less than 1e-9.
    strains = []
    for inextensible in (False, True):
        rod = Rod.straight(
            21, 1.0, radius=0.01, youngs_modulus=1e5, shear_modulus=1e5, inextensible=inextensible
        )
        rod.clamp(0)
        rod.step(1 / 60, 60)
        assert rod.positions[-1, 1] < -0.2
        strains.append(_strain(rod, 1.0 / 20))
    assert strains[0] > 0.01 and strains[1] < 1e-9, strains


def test_quasistatic_twist_is_uniform_between_turned_clamps() -> None:
    # Bergou et al. 2008, sec. 6: without inertia the twists minimise the energy given the
    # centreline, here the analytic uniform twist, in the step the clamp turns.
    twists = []
    for quasistatic in (False, True):
        rod = Rod.straight(
            21, 1.0, radius=0.01, youngs_modulus=1e6, gravity=(0, 0, 0),
            quasistatic_twist=quasistatic,
        )  # fmt: skip
        rod.clamp(0)
        rod.clamp(-1)
        rod.move_clamp(-1, kinema.Rotation.from_rotvec([1.0, 0.0, 0.0]))
        rod.step(1 / 60)
        twists.append(rod.twists.copy())
    uniform = np.linspace(0.0, 1.0, 20)
    assert np.max(np.abs(twists[1] - uniform)) < 1e-9
    assert np.max(np.abs(twists[0] - uniform)) > 0.05


def test_quasistatic_twist_needs_the_implicit_integrator() -> None:
    with pytest.raises(ValueError, match="quasistatic_twist"):
        Rod.straight(5, 1.0, integrator="symplectic", quasistatic_twist=True)
    with pytest.raises(TypeError, match="inextensible"):
        Rod.straight(5, 1.0, inextensible="yes")  # type: ignore[arg-type]
