"""A viewer in the browser for recorded animations, built on ``viser`` (the ``viewer`` extra).

``view(source)`` serves a page (``http://host:port``) that draws a recorded animation as
meshes, with a timeline: a ``frame`` slider to scrub, a ``play`` checkbox to play and pause at
the recorded rate. ``source`` is a :class:`kinema.Scene` that recorded ``"animation"`` (see
:mod:`kinema.io.scene`), the path of a checkpoint of one (:meth:`kinema.Scene.save`), or a
``(skin, motion)`` pair (a :class:`kinema.skin.Skin` and a motion of its skeleton). ``kinema
view FILE`` opens a checkpoint from the command line.
"""

from __future__ import annotations

import os
import threading
import time
from typing import Any

import numpy as np

__all__ = ["Viewer", "view"]


def _frames(source: Any) -> tuple[np.ndarray, dict[str, tuple[np.ndarray, np.ndarray]]]:
    """The animation of ``source`` as times ``(F,)`` s and named meshes: ``(frames (F, V, 3) m,
    triangles (T, 3))``."""
    from kinema.io.scene import scene_tracks
    from kinema.rotation import Rotation
    from kinema.scene import Scene
    from kinema.skin import Skin

    if isinstance(source, (str, os.PathLike)):
        source = Scene.load(source)
    if isinstance(source, tuple) and len(source) == 2 and isinstance(source[0], Skin):
        skin, motion = source
        unit = float(getattr(skin.skeleton, "metres_per_unit", 1.0))
        frames = skin.deform(motion) * unit
        times = np.arange(len(frames)) / float(motion.frame_rate)
        return times, {"skin": (frames, np.asarray(skin.triangles))}
    if not isinstance(source, Scene):
        raise TypeError("source: expected a Scene, a checkpoint path or a (Skin, motion) pair")
    rigid, sequences = scene_tracks(source)
    meshes = {s.name: (np.asarray(s.frames), np.asarray(s.triangles)) for s in sequences}
    for r in rigid:
        v = np.asarray(r.vertices, dtype=np.float64)
        q = Rotation.from_quat(np.asarray(r.orientations))
        moved = np.stack([q[k].apply(v) for k in range(len(q))])
        meshes[r.name] = (moved + np.asarray(r.positions)[:, None], np.asarray(r.triangles))
    times = np.asarray(source.records["animation"])[:, 0]
    return times, meshes


class Viewer:
    """A running viewer (see the module docs): ``url``, ``frame`` (the frame shown),
    ``show(k)`` to show frame ``k``, ``close()`` to stop the server."""

    def __init__(self, source: Any, host: str = "127.0.0.1", port: int = 8080) -> None:
        try:
            import viser
        except ImportError:
            raise ImportError("kinema.view needs viser: pip install 'kinema[viewer]'") from None
        self.times, self._meshes = _frames(source)
        self.server = viser.ViserServer(host=host, port=port, verbose=False)
        self.url = f"http://{host}:{self.server.get_port()}"
        self._handles = {
            name: self.server.scene.add_mesh_simple(
                f"/{name}",
                frames[0].astype(np.float32),
                tri.astype(np.uint32),
                color=(200, 150, 120),
            )
            for name, (frames, tri) in self._meshes.items()
        }
        last = len(self.times) - 1
        self.slider = self.server.gui.add_slider("frame", 0, max(last, 1), 1, 0)
        self.playing = self.server.gui.add_checkbox("play", False)
        self.slider.on_update(lambda _: self.show(int(self.slider.value)))
        self.frame = 0
        self._stop = threading.Event()
        threading.Thread(target=self._play, daemon=True).start()

    def show(self, k: int) -> None:
        """Draw frame ``k`` (clamped to the recording)."""
        k = min(max(int(k), 0), len(self.times) - 1)
        for name, (frames, _) in self._meshes.items():
            self._handles[name].vertices = frames[k].astype(np.float32)
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
