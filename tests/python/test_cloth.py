"""kinema.cloth from Python: the API, its numbers, and clear errors for bad input."""

from __future__ import annotations

import numpy as np
import pytest

import kinema
from kinema.cloth import Capsule, Cloth, Plane, Sphere

# The light, soft material of the explicit-integrator tests (the default before issue #21 made
# it cotton-like): their step sizes are tuned to it.
SOFT = {"density": 0.1, "shear": 1e2, "bend": 1e-5, "damping": 1e-3}


def test_grid_layout_masses_and_views_without_copies() -> None:
    cloth = Cloth.grid(5, 4, 2.0, 1.5, density=0.2)
    x = cloth.positions
    assert x.shape == (20, 3) and len(cloth) == 20
    # Vertex i + nx j at (-w/2 + i w/(nx-1), 0, -h/2 + j h/(ny-1)).
    np.testing.assert_allclose(x[2 + 5 * 3], [0.0, 0.0, 0.75])
    assert cloth.triangles.shape == (2 * 4 * 3, 3)
    assert cloth.masses.sum() == pytest.approx(0.2 * 2.0 * 1.5, rel=1e-12)
    assert not x.flags.writeable
    cloth.step(1 / 60)
    # The view follows the state: the same memory, updated in place.
    assert x[10, 1] < 0.0
    assert np.shares_memory(x, cloth.positions)


def test_free_fall_matches_implicit_euler_exactly() -> None:
    # Without internal forces' effect (rigid translation), a step is v += h g, x += h v.
    cloth = Cloth.grid(3, 3)
    h = 0.01
    cloth.step(h, 3)
    expected_v = 3 * h * -9.81
    expected_y = -9.81 * h * h * (1 + 2 + 3)
    np.testing.assert_allclose(cloth.velocities[:, 1], expected_v, rtol=1e-9)
    np.testing.assert_allclose(cloth.positions[:, 1], expected_y, rtol=1e-9)


def test_hanging_cloth_rests_and_pins_hold() -> None:
    cloth = Cloth.grid(8, 8, damping=0.02, air_damping=5.0)
    cloth.pin([0, 7])
    start = cloth.positions[[0, 7]].copy()
    energies = []
    for _ in range(480):
        cloth.step(1 / 60, tol=1e-8)
        e = cloth.energy()
        energies.append(e["kinetic"] + e["potential"] + e["elastic"])
    assert np.all(np.diff(energies) <= 1e-9)
    # The step writes the pins' positions; their velocities show that the solve held them.
    np.testing.assert_array_equal(cloth.positions[[0, 7]], start)
    np.testing.assert_array_equal(cloth.velocities[[0, 7]], 0.0)
    f = cloth.forces()
    weight = cloth.masses * 9.81
    free = np.setdiff1d(np.arange(64), [0, 7])
    assert np.max(np.linalg.norm(f[free], axis=1) / weight[free]) < 1e-3


def test_moving_pins_and_plane_constraints() -> None:
    cloth = Cloth.grid(6, 6)
    cloth.pin([0, 5])
    cloth.constrain([30, 35], plane_normal=(0, 0, 1))
    z_before = cloth.positions[[30, 35], 2].copy()
    target = cloth.positions[[0, 5]] + [0.0, 0.3, 0.0]
    start = cloth.positions[[0, 5]].copy()
    cloth.pin([0, 5], target)
    cloth.step(1 / 60, 10, solver="cholesky")
    # The step writes the pins' positions, so the velocities are what shows the solve: held.
    np.testing.assert_array_equal(cloth.positions[[0, 5]], target)
    np.testing.assert_array_equal(cloth.velocities[[0, 5]], 0.0)
    np.testing.assert_allclose(cloth.positions[[30, 35], 2], z_before, atol=1e-14)
    cloth.free([0, 5, 30, 35])
    cloth.step(1 / 60)
    # Freed, the former pin moves. (Up, since session 22: the pins' jump of 0.3 m in one step
    # yanks the sheet up, as the strain limiter now lets the plane-constrained vertices slide
    # instead of holding them, and the sheet carries the freed corner on; before, it fell.)
    assert np.linalg.norm(cloth.positions[0] - target[0]) > 1e-3
    # One step that is not subdivided takes the pins to a new target with the velocity that
    # gets them there.
    moved = Cloth.grid(6, 6)
    moved.pin([0, 5], target)
    moved.step(1 / 60, solver="cholesky", max_strain_change=float("inf"))
    np.testing.assert_allclose(moved.velocities[[0, 5]], (target - start) * 60, rtol=1e-12)


def test_prescribed_velocities_are_followed_exactly() -> None:
    for integrator in ("implicit_euler", "bdf2", "symplectic_euler"):
        cloth = Cloth.grid(5, 5, stretch=1e3, **SOFT)
        start = cloth.positions[[0, 4]].copy()
        cloth.prescribe([0, 4], [0.1, 0.2, -0.3])
        dt = 1e-3 if integrator == "symplectic_euler" else 1 / 60
        cloth.step(dt, 30, integrator=integrator)
        np.testing.assert_allclose(cloth.velocities[[0, 4]], [[0.1, 0.2, -0.3]] * 2, atol=1e-14)
        np.testing.assert_allclose(
            cloth.positions[[0, 4]], start + 30 * dt * np.array([0.1, 0.2, -0.3]), atol=1e-12
        )
    with pytest.raises(ValueError, match="velocities"):
        cloth.prescribe([0, 1], np.zeros((3, 3)))


def test_pcg_and_cholesky_agree() -> None:
    def run(solver: str) -> np.ndarray:
        cloth = Cloth.grid(7, 7, stretch=5e3)
        cloth.pin([0, 6])
        cloth.step(1 / 60, 20, solver=solver, tol=1e-10)
        assert cloth.stats["converged"]
        return cloth.positions.copy()

    for solver in ("multigrid", "block_ssor"):
        np.testing.assert_allclose(run(solver), run("cholesky"), atol=1e-8)


def test_drape_over_sphere_without_penetration_or_energy_spikes() -> None:
    cloth = Cloth.grid(14, 14, 1.4, 1.4, density=0.15, stretch=2e3, shear=2e2, air_damping=0.2)
    cloth.set_state(cloth.positions + np.array([0.0, 0.75, 0.0]))
    center = np.array([0.0, 0.3, 0.0])
    cloth.add_collider(Sphere(center, 0.3, friction=0.4))
    cloth.add_collider(Plane(friction=0.6))
    e0 = sum(cloth.energy().values())
    previous = e0
    for _ in range(90):
        cloth.step(1 / 60, tol=1e-4)
        x = cloth.positions
        assert np.min(np.linalg.norm(x - center, axis=1)) > 0.3 - 1e-3
        assert x[:, 1].min() > -1e-3
        now = sum(cloth.energy().values())
        # Contacts are inelastic; the linearised step may add a little (bounded by the
        # strain-change subdivision), never a spike.
        assert now <= previous + 1e-3 * e0
        previous = now
    assert cloth.stats["contacts"] > 10


def test_capsule_collider_and_moving_sphere() -> None:
    cloth = Cloth.grid(8, 8, 1.0, 1.0)
    cloth.set_state(cloth.positions + np.array([0.0, 0.3, 0.0]))
    cloth.add_collider(Capsule((-1.0, 0.0, 0.0), (1.0, 0.0, 0.0), 0.1))
    index = cloth.add_collider(Sphere((0.0, -2.0, 0.0), 0.1, velocity=(0.0, 0.0, 0.0)))
    cloth.step(1 / 60, 40)
    x = cloth.positions
    axis_distance = np.hypot(x[:, 1], x[:, 2])
    inside = (np.abs(x[:, 0]) <= 1.0) & (axis_distance < 0.1 - 1e-3)
    assert not inside.any()
    cloth.set_collider(index, Sphere((0.0, -2.0, 0.0), 0.2, velocity=(0.0, 1.0, 0.0)))
    cloth.step(1 / 60)


def test_obj_round_trip(tmp_path) -> None:
    cloth = Cloth.grid(4, 3)
    path = tmp_path / "cloth.obj"
    cloth.to_obj(path)
    back = Cloth.from_obj(path, stretch=2e3)
    np.testing.assert_array_equal(back.positions, cloth.positions)
    np.testing.assert_array_equal(back.triangles, cloth.triangles)
    (tmp_path / "bad.obj").write_text("v 0 0 0\nv 1 0 0\nf 1 2 3\n")
    with pytest.raises(kinema.ParseError, match=":3:"):
        Cloth.from_obj(tmp_path / "bad.obj")


def test_explicit_integrators_need_far_smaller_steps() -> None:
    def survives(integrator: str, dt: float) -> bool:
        cloth = Cloth.grid(6, 6, stretch=1e5, **SOFT)
        cloth.pin([0, 5])
        try:
            cloth.step(dt, round(0.2 / dt), integrator=integrator)
        except kinema.SimulationError:
            return False
        return bool(np.abs(cloth.positions).max() < 10.0)

    assert survives("implicit_euler", 1 / 30)
    assert survives("bdf2", 1 / 30)
    # The implicit step is 1/30 s; explicit symplectic Euler needs less than 1/30000 s.
    assert not survives("symplectic_euler", 1 / 3000)
    assert not survives("symplectic_euler", 1 / 30000)
    assert survives("symplectic_euler", 1 / 100000)


@pytest.mark.parametrize(
    ("make", "match"),
    [
        (lambda: Cloth([[0, 0, 0], [1, 0, 0], [2, 0, 0]], [[0, 1, 2]]), "zero area"),
        (lambda: Cloth([[0, 0, 0], [1, 0, 0], [0, 0, 1]], [[0, 1, 1]]), "repeats"),
        (lambda: Cloth([[0, 0, 0], [1, 0, np.nan], [0, 0, 1]], [[0, 1, 2]]), "NaN"),
        (lambda: Cloth([[0, 0, 0], [1, 0, 0], [0, 0, 1]], [[0, 1, 5]]), "out of range"),
        (lambda: Cloth([[0, 0, 0], [1, 0, 0], [0, 0, 1]], [[0.0, 1.0, 2.0]]), "integer"),
        (lambda: Cloth.grid(1, 5), "at least 2"),
        (lambda: Cloth.grid(3, 3, stretch=-1.0), "stretch"),
        (lambda: Cloth.grid(3, 3, model="cotton"), "model"),
        (lambda: Cloth.grid(3, 3, triangulation="diamond"), "triangulation"),
    ],
)
def test_bad_input_is_a_clear_value_error(make, match) -> None:
    with pytest.raises(ValueError, match=match):
        make()


def test_bad_arguments_leave_the_state_untouched() -> None:
    cloth = Cloth.grid(4, 4)
    start = cloth.positions.copy()
    with pytest.raises(ValueError, match="dt"):
        cloth.step(-1.0)
    with pytest.raises(ValueError, match="integrator"):
        cloth.step(0.01, integrator="leapfrog2")
    with pytest.raises(ValueError, match="solver"):
        cloth.step(0.01, solver="lu")
    with pytest.raises(ValueError, match="indices"):
        cloth.pin([99])
    with pytest.raises(ValueError, match="exactly one"):
        cloth.constrain([1])
    with pytest.raises(ValueError, match="radius"):
        cloth.add_collider(Sphere((0, 0, 0), -1.0))
    with pytest.raises(TypeError):
        cloth.add_collider("floor")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="positions"):
        cloth.set_state(np.zeros((3, 3)))
    np.testing.assert_array_equal(cloth.positions, start)
    # Divergence of an explicit method is reported, and the cloth keeps its last good state.
    stiff = Cloth.grid(4, 4, stretch=1e8)
    stiff.set_state(stiff.positions + np.random.default_rng(0).normal(0.0, 0.01, (16, 3)))
    with pytest.raises(kinema.SimulationError):
        stiff.step(0.01, 500, integrator="explicit_euler")
    assert np.isfinite(stiff.positions).all()


def test_box_collider_holds_the_cloth():
    from kinema import Rotation
    from kinema.cloth import Box

    cloth = Cloth.grid(12, 12, 0.5, 0.5)
    cloth.set_state(cloth.positions + np.array([0.0, 0.3, 0.0]))
    cloth.add_collider(
        Box([0, 0, 0], [0.4, 0.1, 0.4], orientation=Rotation.from_rotvec([0.0, 0.3, 0.0]))
    )
    cloth.step(1 / 60, 60)
    assert cloth.positions[:, 1].min() > 0.1 - 0.01  # on the top face, not through it
    with pytest.raises(ValueError, match="orientation"):
        cloth.add_collider(Box([0, 0, 0], [1, 1, 1], orientation=[1, 0, 0, 0]))
    with pytest.raises(ValueError, match="collider"):
        cloth.add_collider(Box([0, 0, 0], [1, -1, 1]))


def test_undo_point_puts_the_whole_state_back_in_place():
    # A scene's undo point (_mark / _rollback) copies the state only; put back, it resumes bit
    # for bit like a pickle taken at the mark (BDF2 history, PCG warm start, contact states,
    # pins and colliders included), and views taken before stay those of the cloth.
    import pickle

    c = Cloth.grid(6, 6, 1.0, 1.0)
    c.pin([0, 5])
    c.add_collider(Sphere((0.0, -0.35, 0.0), 0.3, velocity=(0.0, 0.1, 0.0), friction=0.4))
    c.step(0.01, 3, integrator="bdf2")
    copy, view = pickle.dumps(c), c.positions
    c._core._mark()
    c.step(0.01, 4, integrator="bdf2")
    c.pin([35])
    c.add_collider(Plane((0.0, -0.2, 0.0), (0.0, 1.0, 0.0)))
    c._core._rollback()
    other = pickle.loads(copy)
    assert c.time == other.time
    for cloth in (c, other):
        cloth.step(0.01, 5, integrator="bdf2")
    assert c.positions.tobytes() == other.positions.tobytes()
    assert c.velocities.tobytes() == other.velocities.tobytes()
    assert np.array_equal(view, c.positions) and view.base is not None


def test_self_intersections_finds_crossing_triangles_only() -> None:
    # Two separate triangles: the second pierces the first's interior, then is lifted clear.
    v = np.array(
        [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0.2, 0.2, -0.5], [0.2, 0.2, 0.5], [0.3, 0.6, 0.0]],
        float,
    )
    crossing = Cloth(v, np.array([[0, 1, 2], [3, 4, 5]]))
    pairs = crossing.self_intersections()
    assert pairs.dtype == np.int64 and pairs.tolist() == [[0, 1]]
    lifted = v + (np.arange(6) >= 3)[:, None] * np.array([0.0, 0.0, 1.0])
    clear = Cloth(lifted, np.array([[0, 1, 2], [3, 4, 5]]))
    assert clear.self_intersections().shape == (0, 2)
    # A flat sheet: adjacent triangles share vertices and do not count.
    assert Cloth.grid(6, 6, 1.0, 1.0).self_intersections().shape == (0, 2)
