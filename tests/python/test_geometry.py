"""One class per collision shape (kinema.geometry), shared by particles and cloth."""

from __future__ import annotations

import numpy as np
import pytest

from kinema import cloth, geometry, particles


def test_systems_re_export_the_one_class_of_each_shape() -> None:
    for name in ("Plane", "Sphere", "Capsule", "Box"):
        assert getattr(particles, name) is getattr(geometry, name)
        assert getattr(cloth, name) is getattr(geometry, name)


def test_defaults_are_those_of_the_system_a_shape_is_added_to() -> None:
    # Particles: restitution 0.5, friction 0; the same with the values spelled out.
    def bounce(plane: geometry.Plane) -> np.ndarray:
        ps = particles.ParticleSystem([[0.0, 0.05, 0.0]], velocities=[[1.0, -2.0, 0.0]])
        ps.add(plane)
        ps.step(0.05)
        return ps.velocities.copy()

    assert np.array_equal(
        bounce(geometry.Plane()), bounce(geometry.Plane(restitution=0.5, friction=0.0))
    )
    assert not np.array_equal(bounce(geometry.Plane()), bounce(geometry.Plane(friction=0.3)))

    # Cloth: friction 0.5.
    def drape(sphere: geometry.Sphere) -> np.ndarray:
        c = cloth.Cloth.grid(5, 5, 0.5, 0.5)
        c.set_state(c.positions + np.array([0.0, 0.2, 0.0]))
        c.add_collider(sphere)
        c.step(1 / 60, 20)
        return c.positions.copy()

    center = (0.05, 0.0, 0.0)
    assert np.array_equal(
        drape(geometry.Sphere(center, 0.2)), drape(geometry.Sphere(center, 0.2, friction=0.5))
    )
    assert not np.array_equal(
        drape(geometry.Sphere(center, 0.2)), drape(geometry.Sphere(center, 0.2, friction=0.0))
    )


def test_cloth_refuses_what_it_does_not_model() -> None:
    c = cloth.Cloth.grid(3, 3)
    with pytest.raises(ValueError, match="restitution"):
        c.add_collider(geometry.Plane(restitution=0.5))
    with pytest.raises(ValueError, match="inside"):
        c.add_collider(geometry.Sphere((0, 0, 0), 1.0, inside=True))
    with pytest.raises(TypeError):
        c.add_collider("floor")  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("shape", "arg"),
    [
        (geometry.Plane(normal=(0.0, 0.0, 0.0)), "normal"),
        (geometry.Plane(point=(np.inf, 0.0, 0.0)), "point"),
        (geometry.Sphere((0, 0, 0), 0.0), "radius"),
        (geometry.Sphere((0, 0, 0), np.nan), "radius"),
        (geometry.Capsule((0, 0, 0), (1, 0, 0), -0.1), "radius"),
        (geometry.Box((0, 0, 0), (1.0, 0.0, 1.0)), "half_extents"),
        (geometry.Box((0, 0, 0), (1, 1, 1), orientation=[2.0, 0.0, 0.0, 0.0]), "orientation"),
        (geometry.Sphere((0, 0, 0), 1.0, restitution=1.5), "restitution"),
        (geometry.Sphere((0, 0, 0), 1.0, friction=-1.0), "friction"),
        (geometry.Sphere((0, 0, 0), 1.0, velocity=(0.0, np.nan, 0.0)), "velocity"),
    ],
)
def test_each_mistake_is_named_the_same_way_by_every_system(
    shape: geometry.Shape, arg: str
) -> None:
    ps = particles.ParticleSystem(np.zeros((1, 3)))
    systems = [ps.add]
    if arg != "restitution":
        systems.append(cloth.Cloth.grid(3, 3).add_collider)
    for add in systems:
        with pytest.raises(ValueError, match=f"^{arg}"):
            add(shape)
