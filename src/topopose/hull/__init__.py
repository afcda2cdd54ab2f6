"""Volumetric visual hull (thesis §2.3.2.2)."""
from .volume import Volume

__all__ = ["Volume"]
