"""Capture input: calibration, capture folders, silhouettes, synthetic captures."""
from .camera import Camera
from .capture import Capture, axis_vector
from .calibration import read_calibration, read_capture_options
from .io import load_capture, prefetch, read_images, read_silhouettes
from .silhouettes import extract_silhouette, clean_mask
from .synth import synthesize, synthetic_capture

__all__ = ["Camera", "Capture", "axis_vector", "load_capture", "read_calibration",
           "read_capture_options", "read_silhouettes", "read_images", "prefetch", "extract_silhouette", "clean_mask"]
__all__ += ["synthesize", "synthetic_capture"]

