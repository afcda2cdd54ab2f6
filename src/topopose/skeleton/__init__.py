"""Curve skeleton → data tree (thesis §7.3, Alg. 13) and data-tree statistics (§11.4.1)."""
from topopose.skeleton.tree import classify, data_tree, label_ndimage, skeleton_voxels

__all__ = ["classify", "data_tree", "label_ndimage", "skeleton_voxels", "tree_stats", "tree_stats_cli"]


def __getattr__(name):
    if name in ("tree_stats", "tree_stats_cli"):
        from topopose.skeleton import stats

        return getattr(stats, name)
    raise AttributeError(f"module 'topopose.skeleton' has no attribute {name!r}")
