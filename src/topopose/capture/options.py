"""The options of a capture folder's ``capture.toml``: their defaults, types and checks."""
from __future__ import annotations

import math

from topopose.errors import InputError

#: Silhouette methods that need no empty-scene image (background learned from the sequence, or a
#: person segmenter)
SEQUENCE_METHODS = ("sequence", "selfie", "sequence+selfie", "person")

#: Defaults of the ``[silhouettes]`` table of ``capture.toml`` (background subtraction).
SILHOUETTE_DEFAULTS = {
    "method": "diff",      # "diff" (colour difference), "mog2" or "knn" (OpenCV subtractors)
    "threshold": 30.0,     # diff: max channel difference (0-255); mog2/knn: their varThreshold/dist2Threshold
    "median": 3,           # median filter size (odd, pixels; 0 = none) on image and background: noise
    "blur": 0.0,           # optional Gaussian sigma (pixels) after the median filter (0 = none)
    "open": 3,             # opening kernel size (pixels, 0 = none): removes specks
    "close": 7,            # closing kernel size (pixels, 0 = none): fills small holes and cracks
    "min_area": 100,       # connected blobs smaller than this (pixels) are dropped
    "fill_holes": 0,       # holes smaller than this many pixels are filled (0 = none)
    # methods "sequence", "selfie", "sequence+selfie": no empty scene (capture/background.py)
    "scale": 0.25,         # probabilities computed on images resized by this factor
    "samples": 25,         # frames spread over the sequence that the background is learned from
    "reveal": 40.0,        # a sample within this colour distance of the inpainted guess shows the background
    "shadow": 0.6,         # brightness ratio down to which a darker pixel of the same colour is shadow
    "uncertain": 0.5,      # weight of the vote of pixels whose background was never revealed
    "zone_margin": 0.15,   # growth (metres) of the 3D box the subject sweeps
    "fusion": "auto",      # "soft": Franco & Boyer occupancy grid from probabilities; "hard": p > 0.5 masks;
                           # "auto": hard for method "person" (sharp masks), soft for the others
    "p_detect": 0.99,      # soft fusion: P(pixel foreground | voxel occupied)
    "p_false": 0.4,        # soft fusion: P(pixel foreground | voxel empty)
    "occupancy": 0.5,      # soft fusion: posterior occupancy above which a voxel is in the hull
    "open3d": 1,           # soft fusion: 3D opening of the hull by a (2k + 1)³ cube (0: none)
    "selfie_floor": 0.0,   # selfie: the network's probability is raised to at least this (a weak "no")
    "person_track": False,  # person: MediaPipe's tracking mode (detector skipped between frames)
    "person_every": 1,     # person: each camera segmented every N-th frame, cameras staggered
    "cut": 0.5,            # hard fusion: a pixel is subject when its probability exceeds this
    "upsampled": True,     # the hull reads a segmenter's small mask where the full one is its upsampling
    # reading videos (any method; capture/sources.py)
    "decode_threads": 1,   # FFmpeg threads per video (0: FFmpeg's own choice, one per core)
    "decode_ahead": 2,     # frames decoded ahead of the silhouettes by a thread of their own (0: none)
}
_SIL_TYPES = {"method": str, "threshold": (int, float), "median": int, "blur": (int, float), "open": int,
              "close": int, "min_area": int, "fill_holes": int, "scale": (int, float),
              "samples": int, "reveal": (int, float), "shadow": (int, float), "uncertain": (int, float),
              "zone_margin": (int, float), "fusion": str, "p_detect": (int, float),
              "p_false": (int, float), "occupancy": (int, float), "open3d": int,
              "selfie_floor": (int, float), "person_track": bool, "person_every": int, "cut": (int, float), "upsampled": bool,
              "decode_threads": int, "decode_ahead": int}
_CAPTURE_KEYS = {"up", "units", "fps", "volume", "size_policy"}
#: What to do with an image whose size differs from its camera's calibration size
SIZE_POLICIES = ("error", "scale", "pad")
#: Length units of ``[capture] units`` in metres
UNITS = {"m": 1.0, "cm": 0.01, "mm": 0.001, "dm": 0.1, "km": 1000.0, "in": 0.0254, "ft": 0.3048}


def check_params(path, p) -> None:
    """Validate the sequence-method fields of ``[silhouettes]``."""
    if not 0.05 <= float(p["scale"]) <= 1.0:
        raise InputError(f"{path}: [silhouettes] field 'scale' must be in [0.05, 1], got {p['scale']!r}")
    if int(p["samples"]) < 3:
        raise InputError(f"{path}: [silhouettes] field 'samples' must be ≥ 3, got {p['samples']!r}")
    if not 0.0 < float(p.get("cut", 0.5)) < 1.0:
        raise InputError(f"{path}: [silhouettes] field 'cut' must be in (0, 1), got {p['cut']!r}")
    for k in ("p_detect", "p_false"):
        if not 0.0 < float(p[k]) < 1.0:
            raise InputError(f"{path}: [silhouettes] field {k!r} must be in (0, 1), got {p[k]!r}")
    if not float(p["p_false"]) < float(p["p_detect"]):
        raise InputError(f"{path}: [silhouettes] field 'p_false' must be below 'p_detect'")
    if not 0.0 < float(p["occupancy"]) < 1.0 or not math.isfinite(float(p["occupancy"])):
        raise InputError(f"{path}: [silhouettes] field 'occupancy' must be in (0, 1), got {p['occupancy']!r}")
