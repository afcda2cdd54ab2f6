"""Interactive recording of a run with the optional ``rerun-sdk`` (``topopose run --rerun FILE.rrd``).

Each frame is logged on the ``frame`` timeline: the visual hull's surface voxels, the curve
skeleton, the data tree, the labelled parts and the model edges between them. Open the file
with ``rerun FILE.rrd``.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from topopose.errors import InputError


def require_rerun():
    try:
        import rerun as rr
    except ImportError:
        raise InputError("--rerun: recording needs the optional package 'rerun-sdk'; install it "
                         "with `pip install topopose[rerun]`") from None
    return rr


def record_run(path, capture, poses, model="human", resolution=100, tolerance=None,
               max_points=20000):
    """Write ``path`` (.rrd) with every frame of ``poses`` (hull, skeleton, tree, parts)."""
    rr = require_rerun()
    from scipy import ndimage

    from topopose.capture import Capture, load_capture
    from topopose.frame.estimate import FrameEstimator
    from topopose.viz.view import part_colours

    cap = capture if isinstance(capture, Capture) else load_capture(capture)
    est = FrameEstimator(cap, model, resolution, tolerance=tolerance)
    m = est.model
    colours = {p: (np.array(c[:3]) * 255).astype(np.uint8) for p, c in part_colours(m.parts).items()}
    rec = rr.RecordingStream("topopose")        # its own stream: no global state
    rec.save(str(path))
    for i, pose in enumerate(sorted(poses, key=lambda p: p.frame)):
        try:
            rec.set_time("frame", sequence=i)
        except (AttributeError, TypeError):      # rerun-sdk < 0.23
            rec.set_time_sequence("frame", i)
        _, det = est.estimate(pose.frame, detail=True)
        if det.volume is not None:
            v = det.volume
            surf = np.argwhere(v.data & ~ndimage.binary_erosion(v.data, border_value=0))
            if len(surf) > max_points:
                surf = surf[np.random.default_rng(0).choice(len(surf), max_points, replace=False)]
            rec.log("hull", rr.Points3D(v.world(surf), colors=[158, 202, 225], radii=v.voxel_size / 3))
            if det.skeleton is not None:
                rec.log("skeleton", rr.Points3D(v.world(np.argwhere(det.skeleton)),
                                               colors=[60, 60, 60], radii=v.voxel_size / 2))
        if det.data is not None:
            t = det.data
            segs = [np.stack([t.positions[u], t.positions[w]]) for u, w, _ in t.edges
                    if t.positions.get(u) is not None and t.positions.get(w) is not None]
            if segs:
                rec.log("data_tree", rr.LineStrips3D(segs, colors=[117, 107, 177]))
        from topopose.sequence.chirality import numbered
        placed = {p: x for p, x in numbered(pose, m).parts.items() if x is not None}
        if placed:
            names = list(placed)
            rec.log("parts", rr.Points3D(np.stack([placed[p] for p in names]), labels=names,
                                        colors=np.stack([colours[p] for p in names]),
                                        radii=0.02 * max(1.0, float(np.ptp(np.stack(list(placed.values())), axis=0).max()))))
            bones = [np.stack([placed[a], placed[b]]) for a, b, _ in m.tree.edges
                     if a in placed and b in placed]
            if bones:
                rec.log("model_edges", rr.LineStrips3D(bones, colors=[0, 0, 0]))
        rec.log("status", rr.TextLog(f"{pose.frame}: {pose.status} d={pose.distance} {pose.error or ''}"))
    try:
        rec.flush()
    except TypeError:                            # older signature
        rec.flush(blocking=True)
    rec.disconnect()
    return Path(path)
