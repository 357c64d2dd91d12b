"""A viewer in the browser for recorded animations, built on ``viser`` (the ``viewer`` extra).

``view(source)`` serves a page (``http://host:port``) that draws a recorded animation as
meshes, line segments and points (:mod:`kinema.io.playback`), with a timeline: a ``frame``
slider to scrub, a ``play`` checkbox to play and pause at the recorded rate. ``source`` is a
:class:`kinema.Scene` that recorded ``"animation"`` (see :mod:`kinema.io.scene`), the path of a
checkpoint of one (:meth:`kinema.Scene.save`), the path of a ``.glb`` file (evaluated frame by
frame as a glTF viewer plays it), or a ``(skin, motion)`` pair (a :class:`kinema.skin.Skin` and
a motion of its skeleton). ``kinema view FILE`` opens a checkpoint or a ``.glb`` file from the
command line.
"""

from __future__ import annotations

import os
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["Viewer", "view"]

_COLOUR = {"mesh": (200, 150, 120), "lines": (60, 60, 200), "points": (40, 120, 220)}


def _frames(source: Any) -> tuple[np.ndarray, dict[str, Any]]:
    """The animation of ``source``: times ``(F,)`` s and the :class:`kinema.io.playback.Drawn`
    things, by name."""
    from kinema.io import playback
    from kinema.scene import Scene
    from kinema.skin import Skin

    if isinstance(source, (str, os.PathLike)):
        if Path(source).suffix.lower() == ".glb":
            return playback.glb_frames(source)
        source = Scene.load(source)
    if isinstance(source, tuple) and len(source) == 2 and isinstance(source[0], Skin):
        return playback.skin_frames(*source)
    if not isinstance(source, Scene):
        raise TypeError(
            "source: expected a Scene, a checkpoint or .glb path, or a (Skin, motion) pair"
        )
    return playback.scene_frames(source)


class Viewer:
    """A running viewer (see the module docs): ``url``, ``frame`` (the frame shown),
    ``show(k)`` to show frame ``k``, ``close()`` to stop the server."""

    def __init__(self, source: Any, host: str = "127.0.0.1", port: int = 8080) -> None:
        try:
            import viser
        except ImportError:
            raise ImportError("kinema.view needs viser: pip install 'kinema[viewer]'") from None
        self.times, self._drawn = _frames(source)
        self.server = viser.ViserServer(host=host, port=port, verbose=False)
        self.url = f"http://{host}:{self.server.get_port()}"
        self.server.scene.set_up_direction("+y")  # kinema's scenes and glTF are Y up
        self._aim()
        self._handles: dict[str, Any] = {}
        self._indices: dict[str, Any] = {}
        self.frame = 0
        self.show(0)
        last = len(self.times) - 1
        self.slider = self.server.gui.add_slider("frame", 0, max(last, 1), 1, 0)
        self.playing = self.server.gui.add_checkbox("play", False)
        self.slider.on_update(lambda _: self.show(int(self.slider.value)))
        self._stop = threading.Event()
        threading.Thread(target=self._play, daemon=True).start()

    def _aim(self) -> None:
        """Point the camera of new pages at the first frame: from above and aside, far enough
        to see all of it."""
        shown = [d.frames[0][0] for d in self._drawn.values() if d.frames[0] is not None]
        points = np.concatenate([np.zeros((0, 3)), *shown])
        if len(points) == 0:
            return
        lo, hi = points.min(axis=0), points.max(axis=0)
        centre, radius = 0.5 * (lo + hi), max(0.5 * float(np.linalg.norm(hi - lo)), 0.1)
        camera = self.server.initial_camera
        camera.look_at = tuple(centre)
        camera.position = tuple(centre + 2.5 * radius * np.array([0.6, 0.5, 0.6]))
        camera.up = (0.0, 1.0, 0.0)

    def _draw(self, name: str, kind: str, x: np.ndarray, indices: Any) -> None:
        """Draw ``name`` at vertices ``x``: move the drawn vertices if its topology is the one
        drawn, else draw it anew."""
        handle: Any = self._handles.get(name)
        same = handle is not None and self._indices[name] is indices
        v = x.astype(np.float32)
        if kind == "lines":
            v = v[indices]
        if same and kind == "mesh":
            handle.vertices = v
        elif same:
            handle.points = v
        elif kind == "mesh":
            handle = self.server.scene.add_mesh_simple(
                f"/{name}", v, indices.astype(np.uint32), color=_COLOUR[kind], side="double"
            )
        elif kind == "lines":
            handle = self.server.scene.add_line_segments(f"/{name}", v, _COLOUR[kind])
        else:
            handle = self.server.scene.add_point_cloud(
                f"/{name}", v, _COLOUR[kind], point_size=0.02
            )
        handle.visible = True
        self._handles[name], self._indices[name] = handle, indices

    def show(self, k: int) -> None:
        """Draw frame ``k`` (clamped to the recording)."""
        k = min(max(int(k), 0), len(self.times) - 1)
        for name, drawn in self._drawn.items():
            frame = drawn.frames[k]
            if frame is not None and len(frame[0]):
                self._draw(name, drawn.kind, *frame)
            elif name in self._handles:
                self._handles[name].visible = False
        self.frame = k

    def _play(self) -> None:
        dt = float(np.mean(np.diff(self.times))) if len(self.times) > 1 else 0.1
        while not self._stop.wait(dt):
            if self.playing.value:
                # viser's value setter sends the new frame to the page and runs on_update.
                self.slider.value = (int(self.slider.value) + 1) % len(self.times)  # type: ignore[misc]

    def close(self) -> None:
        """Stop playing and stop the server."""
        self._stop.set()
        self.server.stop()


def view(source: Any, host: str = "127.0.0.1", port: int = 8080, block: bool = True) -> Viewer:
    """Serve ``source`` (see the module docs) at ``http://host:port``; with ``block``, until
    interrupted (Ctrl-C)."""
    viewer = Viewer(source, host, port)
    print(f"kinema viewer: {viewer.url}")
    if block:
        try:
            while True:
                time.sleep(1.0)
        except KeyboardInterrupt:
            viewer.close()
    return viewer
