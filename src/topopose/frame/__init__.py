"""The per-frame estimator: hull → skeleton → data tree → alignment → placed parts, and its trust
(thesis ch. 12–13)."""
from topopose.frame.estimate import FrameDetail, FrameEstimator, estimate_pose

__all__ = ["FrameDetail", "FrameEstimator", "estimate_pose"]
