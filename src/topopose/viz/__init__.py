"""Pictures and interactive views: a frame (hull, skeleton, data tree, labelled parts, model
tree), distances per frame with quality classes, the threshold study (thesis Fig. 13.4–13.7)."""
from topopose.viz.figures import plot_distances, plot_quality
from topopose.viz.view import render_frame

__all__ = ["plot_distances", "plot_quality", "render_frame"]
