"""scipy's own `test_rigid_transform.py`, run against kinema through `scipy_adapter`."""

from scipy_adapter import load

globals().update(load("test_rigid_transform.py"))
