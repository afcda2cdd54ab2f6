"""Capture input: calibration, capture folders, silhouettes, synthetic captures."""
from .camera import Camera
from .capture import Capture, axis_vector

__all__ = ["Camera", "Capture", "axis_vector"]
