"""topopose: markerless model-based pose initialization from multi-camera silhouettes.

Pipeline (one sub-package per stage, in the order data flows)::

    capture  -> hull -> topology (thinning) -> skeleton (data tree) -> match (AHA) -> pose

Public names are imported lazily so that ``import topopose`` stays fast and
compiles no Numba kernel until a stage is used.

Examples
--------
>>> import topopose as tp
>>> tp.InputError.__name__
'InputError'
"""
from importlib import import_module

from topopose.errors import InputError

__version__ = "0.1.0"

_LAZY = {
    # capture
    "Camera": "topopose.capture",
    "Capture": "topopose.capture",
    "load_capture": "topopose.capture",
    "synthesize": "topopose.synth",
    # hull
    "Volume": "topopose.hull",
    "visual_hull": "topopose.hull",
    # topology
    "thin": "topopose.topology",
    # skeleton
    "data_tree": "topopose.skeleton",
    # match
    "Tree": "topopose.match",
    "align": "topopose.match",
    "Alignment": "topopose.match",
    # pose
    "Model": "topopose.pose",
    "load_model": "topopose.pose",
    "estimate_pose": "topopose.frame",
    "Pose": "topopose.pose",
    "run": "topopose.batch",
    # options (frozen dataclasses, grouped by stage)
    "EstimatorOptions": "topopose.frame.options",
    "SequenceOptions": "topopose.sequence.options",
    "RunOptions": "topopose.batch.options",
    # applications (thesis §13.3)
    "segment": "topopose.apps.segment",
    "detect": "topopose.apps.detect",
    "cluster_poses": "topopose.apps.cluster",
    # kinematics
    "learn_model": "topopose.kinematics",
}

__all__ = ["InputError", "__version__", *_LAZY]


def __getattr__(name):
    if name in _LAZY:
        value = getattr(import_module(_LAZY[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'topopose' has no attribute {name!r}")


def __dir__():
    return sorted(__all__)
