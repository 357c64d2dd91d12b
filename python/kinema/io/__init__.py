"""Export of kinema results to the files animation tools open, in metres and seconds:
glTF 2.0 binary (``.glb``, :func:`write_glb`, with ``pygltflib``) and USD (:func:`write_usd`,
with ``usd-core``): skinned meshes with skeletal animation, rigid bodies moved by their
transform, deforming meshes (morph targets in glTF, time-sampled points in USD). Both need the
``export`` extra."""

from kinema.io._tracks import MeshSequence, RigidTrack
from kinema.io.gltf import write_glb
from kinema.io.usd import write_usd

__all__ = ["MeshSequence", "RigidTrack", "write_glb", "write_usd"]
