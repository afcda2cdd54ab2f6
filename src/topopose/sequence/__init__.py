"""What reads a run of frames: identities, left/right, consistency, the joint skeleton over time."""
