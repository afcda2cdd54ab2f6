"""Pictures and interactive views: a frame (hull, skeleton, data tree, labelled parts, model
tree), distances per frame with quality classes, the threshold study (thesis Fig. 13.4–13.7)."""
from .figures import plot_distances, plot_quality
from .view import render_frame, view_cli

__all__ = ["plot_distances", "plot_quality", "render_frame", "view_cli"]
