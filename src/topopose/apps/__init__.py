"""Applications of the per-frame poses (thesis §13.3): hull segmentation, pose detection, pose clustering."""
