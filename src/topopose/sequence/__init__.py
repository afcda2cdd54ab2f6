"""Sequence stages: the subject's capsule body tracked through every frame (:mod:`.follow`)."""
