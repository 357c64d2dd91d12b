"""Rotations in kinema: build, convert, compose, interpolate and meet gimbal lock.

Run: python examples/rotations_basics.py
"""

import warnings

import numpy as np

import kinema
from kinema import Rotation, Transform, slerp

# A camera yawed 90° about +Y (up), then pitched down 30° about its own X axis.
cam = Rotation.from_euler("YXZ", [90.0, -30.0, 0.0], degrees=True)
print("quaternion (w, x, y, z):", np.round(cam.as_quat(), 6))
print("forward (-Z) in the world:", np.round(cam.apply([0.0, 0.0, -1.0]), 6))

# The same rotation in other forms, and back.
assert cam.approx_equal(Rotation.from_matrix(cam.as_matrix()))
assert cam.approx_equal(Rotation.from_rotvec(cam.as_rotvec()))
axis, angle = cam.as_axis_angle()
print(f"axis {np.round(axis, 4)}, angle {np.degrees(angle):.3f}°")

# Intrinsic (upper case) XYZ equals extrinsic (lower case) zyx with the angles reversed.
a = Rotation.from_euler("XYZ", [10, 20, 30], degrees=True)
b = Rotation.from_euler("zyx", [30, 20, 10], degrees=True)
print("XYZ == zyx reversed:", bool(a.approx_equal(b)))

# Slerp: constant angular speed on the shorter arc.
path = slerp(Rotation.identity(), cam, np.linspace(0.0, 1.0, 5))
print("slerp angles (deg):", np.round(np.degrees(path.magnitude()), 3))

# Gimbal lock: pitch of exactly 90° merges the first and third axes.
locked = Rotation.from_euler("XYZ", [0.3, np.pi / 2, -0.4])
with warnings.catch_warnings(record=True) as caught:
    warnings.simplefilter("always")
    angles = locked.as_euler("XYZ")
print("angles at lock:", np.round(angles, 6), "warned:", caught[0].category.__name__)
assert issubclass(caught[0].category, kinema.GimbalLockWarning)
assert locked.approx_equal(Rotation.from_euler("XYZ", angles))

# Homogeneous transforms: scale, rotate, translate; compose and invert.
model = Transform(rotation=cam, translation=[0.0, 1.7, 5.0], scale=0.5)
point = model.apply([1.0, 0.0, 0.0])
print("model point in world:", np.round(point, 6))
print("and back:", np.round(model.inv().apply(point), 12))
