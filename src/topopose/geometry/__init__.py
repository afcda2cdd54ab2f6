"""Cameras, projection and carving: what capture/ and hull/ share."""
from topopose.geometry.camera import Camera

__all__ = ["Camera"]
