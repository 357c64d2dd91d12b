"""kinema's exception tree: one root, ``KinemaError``, and each error still the builtin it was."""

from pathlib import Path

import numpy as np
import pytest

import kinema
from kinema.mocap import read_asf
from kinema.rigid import Box, World
from kinema.scene import Scene


def _diverge() -> None:
    """An explicit Euler step of a body spinning at 1e150 rad/s overflows: a SimulationError."""
    world = World(integrator="explicit_euler")
    world.add_body(Box([1.0, 0.6, 0.2]), angular_velocity=[1e150, 1e150, 1e150])
    world.step(1.0, 3)


def _bad_asf(tmp: Path) -> None:
    path = tmp / "bad.asf"
    path.write_text(":version 1.10\n:units\n  mass nonsense\n")
    read_asf(path)


def _bad_checkpoint(tmp: Path) -> None:
    path = tmp / "bad.kin"
    path.write_bytes(b"not a checkpoint at all")
    Scene.load(path)


@pytest.mark.parametrize(
    ("raise_it", "error", "builtin"),
    [
        (lambda tmp: _diverge(), kinema.SimulationError, RuntimeError),
        (_bad_asf, kinema.ParseError, ValueError),
        (_bad_checkpoint, kinema.CheckpointError, ValueError),
    ],
)
def test_every_kinema_error_is_caught_by_the_root_and_by_its_old_builtin(
    tmp_path: Path, raise_it, error, builtin
):
    for catch in (kinema.KinemaError, error, builtin):
        with pytest.raises(catch) as info:
            raise_it(tmp_path)
        assert type(info.value) is error


def test_the_tree_is_the_documented_one():
    assert issubclass(kinema.KinemaError, Exception)
    assert not issubclass(kinema.KinemaError, (ValueError, RuntimeError))
    assert kinema.SimulationError.__mro__[1:3] == (kinema.KinemaError, RuntimeError)
    assert kinema.ParseError.__mro__[1:3] == (kinema.KinemaError, ValueError)
    assert kinema.CheckpointError.__mro__[1:3] == (kinema.KinemaError, ValueError)
    assert kinema.ParseError is kinema._kinema.ParseError
    # A plain bad argument stays a ValueError, not a kinema error.
    with pytest.raises(ValueError) as info:
        World().add_body(Box([1.0, 0.6, 0.2]), velocity=[np.nan, 0.0, 0.0])
    assert not isinstance(info.value, kinema.KinemaError)


def test_kinema_errors_survive_pickling():
    import pickle

    for error in (kinema.SimulationError, kinema.ParseError, kinema.KinemaError):
        again = pickle.loads(pickle.dumps(error("step 3")))
        assert type(again) is error and str(again) == "step 3"
