"""Digital topology and thinning (thesis ch. 4–6).

* :func:`thin` / :func:`thinning`: PKD6, D6I1D, D6U, D6I2D, ACK3 (``method=``).
* :func:`border_constraint`: keep mask for incomplete models (§12.1).
* :func:`t26`, :func:`t6bar`, :func:`is_simple`, :func:`is_isthmus_1d`,
  :func:`is_isthmus_2d`: connectivity numbers (§4.1) of one configuration.
* :mod:`.neighbourhood`: the 26-bit neighbourhood order and the masks;
  :mod:`.tables`: the 2^26 look-up tables and their disk cache.
"""
from topopose.topology.connectivity import config_of, is_isthmus_1d, is_isthmus_2d, is_simple, t6bar, t26
from topopose.topology.neighbourhood import DIRECTION_NAMES, DIRECTIONS, OFFSETS, config_cube, config_index
from topopose.topology.engine import METHODS, Thinning, border_constraint, thin, thinning

__all__ = [
    "thin", "thinning", "Thinning", "border_constraint", "METHODS",
    "t26", "t6bar", "is_simple", "is_isthmus_1d", "is_isthmus_2d", "config_of",
    "config_index", "config_cube", "OFFSETS", "DIRECTIONS", "DIRECTION_NAMES",
]
