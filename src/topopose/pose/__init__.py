"""Pose initialization (thesis ch. 12–13): model trees, per-frame estimation, batch runs,
exports, the demo and the quality study."""
from .estimate import FrameDetail, FrameEstimator, estimate_pose
from .model import BUILTIN, Model, load_model
from .pose import Pose, read_poses, write_poses
from .run import RunResult, run

__all__ = ["BUILTIN", "FrameDetail", "FrameEstimator", "Model", "Pose", "RunResult",
           "estimate_pose", "load_model", "read_poses", "run", "write_poses"]
