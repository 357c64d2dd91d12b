"""The viewer started headless on a recorded scene: its page is served, and the timeline
(the frame slider) moves the drawn mesh to the recorded frame."""

from __future__ import annotations

import socket
import urllib.request

import numpy as np
import pytest

pytest.importorskip("viser")

from kinema import cloth
from kinema.scene import Scene
from kinema.view import Viewer


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def test_the_viewer_serves_the_scene_and_scrubs_its_frames():
    scene = Scene(dt=1 / 30)
    c = cloth.Cloth.grid(4, 4, 0.5, 0.5)
    c.set_state(c.positions + np.array([0.0, 1.0, 0.0]))
    scene.add(c)
    scene.record("animation")
    scene.record("cloth", lambda: c.positions)
    scene.run(frames=5, progress=False)
    viewer = Viewer(scene, port=free_port())
    try:
        page = urllib.request.urlopen(viewer.url, timeout=10).read()
        assert b"<html" in page.lower()
        handle = viewer._handles["cloth0"]
        viewer.slider.value = 3
        assert viewer.frame == 3
        assert np.allclose(handle.vertices, scene.records["cloth"][3], atol=1e-6)
        viewer.show(99)  # clamped to the last frame
        assert np.allclose(handle.vertices, scene.records["cloth"][4], atol=1e-6)
    finally:
        viewer.close()


def test_the_viewer_refuses_what_it_cannot_draw():
    with pytest.raises(TypeError, match="source"):
        Viewer(42, port=free_port())
    with pytest.raises(ValueError, match="scene"):
        Viewer(Scene(), port=free_port())
