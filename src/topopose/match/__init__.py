"""Weighted trees and their alignments: α, homeomorphic alignment η, AHA (thesis ch. 8–11)."""
from .tree import INF, Constraint, Tree, as_tree

__all__ = ["INF", "Constraint", "Tree", "as_tree"]
