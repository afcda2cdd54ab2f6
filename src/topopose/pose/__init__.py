"""Model trees (thesis §12.2), the Pose and joint-skeleton types, their files and exports."""
from topopose.pose.model import BUILTIN, Model, load_model
from topopose.pose.pose import Pose, read_poses, write_poses

__all__ = ["BUILTIN", "Model", "Pose", "load_model", "read_poses", "write_poses"]
