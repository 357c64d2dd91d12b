"""scipy's own `test_rotation_spline.py`, run against kinema through `scipy_adapter`."""

from scipy_adapter import load

globals().update(load("test_rotation_spline.py"))
