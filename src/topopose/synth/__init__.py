"""Synthetic subjects and their exact renderers: capsule subjects, the MakeHuman body, the walker."""
from topopose.synth.capture import synthesize, synthetic_capture

__all__ = ["synthesize", "synthetic_capture"]
