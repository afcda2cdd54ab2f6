"""Kinematic structure from a sequence of visual hulls (Mukasa et al., ELCVIA 2009).

``learn_model(capture) -> LearnedStructure`` finds the rigid parts, joints and their
time-invariant connectivity of a moving articulated subject with no model given, and
writes them as a model tree usable by ``topopose run``.
"""
from topopose.kinematics.deform import Deformer
from topopose.kinematics.learn import (LearnedStructure, joint_metrics, joint_positions, learn_model,
                    learn_structure)
from topopose.kinematics.reeb import (PERG, Atoms, Mesh, integral_geodesic, perg, prune_branches, reeb_levels,
                   surface_mesh, tset_atoms, vertex_atoms)
from topopose.kinematics.structure import (HUMAN_RULE, chains, coherence_rule, intervals, is_coherent, segment_chain,
                        velocity_correlation)

__all__ = ["Deformer", "LearnedStructure", "joint_metrics", "joint_positions", "learn_model",
           "learn_structure", "PERG", "Atoms", "Mesh", "integral_geodesic", "perg",
           "prune_branches", "reeb_levels", "surface_mesh", "tset_atoms", "vertex_atoms", "HUMAN_RULE",
           "chains", "coherence_rule", "intervals", "is_coherent", "segment_chain",
           "velocity_correlation"]
