"""Skinning demo: the CMU slow walk (subject 07, clip 05, shipped in ``kinema/data``) on a
procedural body (capsules around the bones merged into one surface, ``kinema.skin.body_mesh``),
skinned by dual quaternions.

Writes ``skin.glb`` (the skinned mesh, its skeleton and the walk as a glTF animation: open it in
Blender or any glTF viewer) and ``skin.gif`` (the skinned body, seen from the side).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from kinema import mocap, skin

DATA = Path(__file__).resolve().parent.parent / "data"


def run(out_dir: Path, quick: bool) -> dict[str, object]:
    """Build the body, skin the walk, write the glTF file and the GIF."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.animation import FuncAnimation, PillowWriter

    sk = mocap.read_asf(DATA / "07-walk.asf")
    motion = mocap.read_amc(DATA / "07_05-walk.amc", sk)
    if quick:
        motion = motion.slice(0, 120)
    body = skin.body_mesh(sk, 1.0, cell=0.8 if quick else 0.5)
    frames = body.deform(motion) * sk.metres_per_unit
    summary: dict[str, object] = {
        "vertices": len(body.vertices),
        "triangles": len(body.triangles),
        "frames": motion.frames,
    }
    try:
        from kinema import io

        glb = out_dir / "skin.glb"
        io.write_glb(glb, skins=[(body, motion)])
        summary["glb"] = str(glb)
    except ImportError:
        summary["glb"] = "skipped (pip install 'kinema[export]')"

    shown = range(0, motion.frames, 12)
    lo, hi = frames.min(axis=(0, 1)), frames.max(axis=(0, 1))
    fig = plt.figure(figsize=(6, 4))
    ax = fig.add_subplot(projection="3d")

    def draw(f: int) -> None:
        ax.cla()
        v = frames[f]
        ax.plot_trisurf(
            v[:, 0], -v[:, 2], v[:, 1], triangles=body.triangles, color="tan", linewidth=0
        )
        ax.set_xlim(lo[0], hi[0])
        ax.set_ylim(-hi[2], -lo[2])
        ax.set_zlim(lo[1], hi[1])
        ax.set_box_aspect(np.maximum(hi - lo, 1e-3)[[0, 2, 1]])
        ax.set_axis_off()
        ax.set_title(f"CMU 07_05 walk, DQS on a procedural body: t = {f / motion.frame_rate:.2f} s")

    gif = out_dir / "skin.gif"
    FuncAnimation(fig, draw, frames=list(shown)).save(gif, writer=PillowWriter(fps=15))
    plt.close(fig)
    summary["gif"] = str(gif)
    return summary
