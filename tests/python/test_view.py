"""The viewer started headless on a recorded scene or a .glb file: its page is served, the
timeline (the frame slider) moves the drawn mesh to the recorded frame, and a screenshot in
headless Chromium shows the scene (Debian's ``chromium`` driven by playwright; `.ci/run`
installs it, and under CI a missing browser fails the test instead of skipping it)."""

from __future__ import annotations

import io
import os
import shutil
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


def _falling_cloth(frames: int) -> Scene:
    scene = Scene(dt=1 / 30)
    c = cloth.Cloth.grid(10, 10, 1.0, 1.0)
    c.set_state(c.positions + np.array([-0.5, 0.5, -0.5]))
    scene.add(c)
    scene.record("animation")
    scene.record("cloth", lambda: c.positions)
    scene.run(frames=frames, progress=False)
    return scene


def test_the_viewer_plays_a_glb_file(tmp_path):
    """``kinema view out.glb``: the file is evaluated frame by frame and the timeline shows
    each frame's vertices (here the morph targets of a cloth)."""
    pytest.importorskip("pygltflib")
    scene = _falling_cloth(4)
    path = tmp_path / "cloth.glb"
    scene.export(path)
    viewer = Viewer(path, port=free_port())
    try:
        assert len(viewer.times) == 4
        viewer.slider.value = 2
        handle = viewer._handles["cloth0"]
        assert np.allclose(handle.vertices, scene.records["cloth"][2], atol=1e-5)
        assert urllib.request.urlopen(viewer.url, timeout=10).status == 200
    finally:
        viewer.close()


def _cloth_pixels(png: bytes) -> np.ndarray:
    """Row and column of the pixels of the cloth's colour (warm grey, not the white
    background) below the page's panels."""
    from PIL import Image

    rgb = np.asarray(Image.open(io.BytesIO(png)).convert("RGB")).astype(int)[160:, 60:]
    r, g, b = rgb[..., 0], rgb[..., 1], rgb[..., 2]
    return np.argwhere((r > g + 15) & (g > b + 5) & (r < 250))


def test_a_screenshot_in_headless_chromium_shows_the_cloth_and_the_timeline_moves_it():
    """The page, rendered by Chromium (software WebGL), shows the recorded cloth where an
    empty scene shows none; moving the timeline to the last frame draws it lower (it fell)."""
    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    if chromium is None:
        if os.environ.get("KINEMA_CI"):  # .ci/run installs Debian's chromium
            pytest.fail("no Chromium on this machine, and CI must run this test")
        pytest.skip("no Chromium on this machine (apt-get install chromium)")
    from playwright import sync_api as sync  # in the test extra

    scene = _falling_cloth(10)
    viewer = Viewer(scene, port=free_port())
    args = ["--use-gl=angle", "--use-angle=swiftshader", "--enable-unsafe-swiftshader"]
    try:
        with sync.sync_playwright() as p:
            browser = p.chromium.launch(executable_path=chromium, args=[*args, "--no-sandbox"])
            page = browser.new_page(viewport={"width": 800, "height": 600})
            page.goto(viewer.url)

            def settle(ok):  # the page draws asynchronously: look until it shows `ok`
                for _ in range(60):
                    shown = _cloth_pixels(page.screenshot(timeout=180_000))
                    if ok(shown):
                        return shown
                    page.wait_for_timeout(1000)
                raise AssertionError("the page never showed what was expected")

            first = settle(lambda px: len(px) > 5000)
            viewer.slider.value = 9
            last = settle(lambda px: len(px) > 5000 and px[:, 0].mean() > first[:, 0].mean() + 30)
            for handle in viewer._handles.values():
                handle.visible = False
            settle(lambda px: len(px) == 0)
            browser.close()
    finally:
        viewer.close()
    assert last[:, 0].mean() > first[:, 0].mean() + 30
