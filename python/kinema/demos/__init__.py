"""Demos run by ``kinema demo [NAME]``: each writes pictures and returns a summary.

``DEMOS`` maps a demo's name to a one-line description; the module ``kinema.demos.<name>``
provides ``run(out_dir, quick) -> dict``.
"""

DEMOS: dict[str, str] = {
    "showcase": "one scene: cloth over a moving sphere, a fountain, a rigid stack, a mocap walk",
    "rotations": "gimbal lock of Euler angles against quaternion slerp",
    "particles": "a fountain with an emitter, a vortex, turbulence and a ground plane",
    "integrators": "stability regions and a work-precision diagram of the ODE methods",
    "constraints": "a bead on a wire with and without drift feedback, and a rope of rods",
    "keyframes": "a bouncing ball and a camera path under several interpolation schemes",
    "rigid": "the tumbling T-handle and the drift of each rotation integrator",
    "cloth": "a cotton sheet dropping and folding onto itself, with self-collision (GIF)",
    "mocap": "a CMU walk on its skeleton, edited by IK to step over an obstacle (GIF)",
    "fluid": "an SPH dam break (DFSPH), particles coloured by speed (GIF)",
    "crowd": "ORCA circle crossing and a social-force bottleneck (GIFs), boids round spheres",
    "biped": "the 3-D SIMBICON walker pushed from the side, a ragdoll down stairs (GIFs)",
    "skin": "a CMU walk skinned on a procedural body, written as glTF (.glb) and a GIF",
    "hair": "a sphere head turning and nodding with thousands of elastic-rod strands (GIF)",
}
