"""The order of frames: names compared as people read them (``2`` before ``10``)."""
from __future__ import annotations

import re

_DIGITS = re.compile(r"(\d+)")


def frame_key(name) -> tuple:
    """Sort key of a frame name: its runs of digits compared as numbers, the rest as text
    (``"2" < "10"``, ``"cam1_f9" < "cam1_f10"``; ``"007"`` and ``"7"`` are told apart by
    their text, after the number).

    Parameters
    ----------
    name : str or int
        A frame name (an integer is taken as its decimal text).

    Returns
    -------
    tuple
        Alternating text and ``(number, digits)`` items, comparable between any two names.
    """
    out = []
    for k, tok in enumerate(_DIGITS.split(str(name))):
        out.append((int(tok), tok) if k % 2 else tok)
    return tuple(out)


def sort_frames(names) -> list:
    """``names`` (frame names) in natural order (:func:`frame_key`)."""
    return sorted(names, key=frame_key)


def sort_poses(poses) -> list:
    """Objects with a ``frame`` attribute (poses) in the natural order of their frames."""
    return sorted(poses, key=lambda p: frame_key(p.frame))
