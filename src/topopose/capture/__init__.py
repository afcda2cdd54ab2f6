"""Capture input: calibration, capture folders, silhouettes."""
from topopose.geometry.camera import Camera
from topopose.capture.capture import Capture, axis_vector
from topopose.capture.calibration import read_calibration, read_capture_options
from topopose.capture.images import read_images
from topopose.capture.io import load_capture, prefetch, read_silhouettes
from topopose.capture.silhouettes import extract_silhouette, clean_mask

__all__ = ["Camera", "Capture", "axis_vector", "load_capture", "read_calibration",
           "read_capture_options", "read_silhouettes", "read_images", "prefetch", "extract_silhouette", "clean_mask"]

