"""Volumetric visual hull (thesis §2.3.2.2)."""
from topopose.hull.volume import Volume
from topopose.geometry.carver import HullCarver
from topopose.hull.components import fill_cavities, keep_largest_component
from topopose.hull.hull import capture_box, fit_box, grid_for_box, uses_soft_fusion, visual_hull

__all__ = ["Volume", "HullCarver", "visual_hull", "fit_box", "capture_box", "grid_for_box",
           "keep_largest_component", "fill_cavities", "uses_soft_fusion"]
