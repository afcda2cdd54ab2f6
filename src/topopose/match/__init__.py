"""Weighted trees and their alignments: α, homeomorphic alignment η, AHA (thesis ch. 8–11)."""
from topopose.match.align import Alignment, Matcher, align, make_gamma
from topopose.match.betweenness import apply_betweenness, betweenness
from topopose.match.tree import INF, Constraint, Tree, as_tree

__all__ = ["INF", "Alignment", "Constraint", "Matcher", "Tree", "align", "apply_betweenness",
           "as_tree", "betweenness", "make_gamma"]
