"""Export of kinema results to the files animation tools open, in metres and seconds:
glTF 2.0 binary (``.glb``, :func:`write_glb`, with ``pygltflib``) and USD (:func:`write_usd`,
with ``usd-core``): skinned meshes with skeletal animation, rigid bodies moved by their
transform, deforming meshes, polylines and points (morph targets in glTF, time-sampled points
in USD), meshes and points whose size changes (one node per frame in glTF, time-sampled
topology in USD). Both need the
``export`` extra."""

from kinema.io._tracks import FrameMeshes, MeshSequence, RigidTrack
from kinema.io.gltf import write_glb
from kinema.io.usd import write_usd

__all__ = ["FrameMeshes", "MeshSequence", "RigidTrack", "write_glb", "write_usd"]
