"""`topopose segment`, `detect` and `cluster` (thesis §13.3)."""
from __future__ import annotations

import json
import numpy as np
import time

from topopose.apps.cluster import cluster_figure, cluster_poses
from topopose.apps.detect import ExpressionError, _margin, detect, header_up, intervals, load_library, parse, read_poses_file
from topopose.apps.segment import arc_names, camera_masks, label_colours, segment, write_label_mesh
from topopose.errors import InputError


def segment_cli(a) -> int:
    """``topopose segment CAPTURE --poses P.jsonl --out DIR [--frames ...]``."""
    from PIL import Image

    from topopose import _paths
    from topopose.capture import load_capture
    from topopose.pose.model import guess_model
    from topopose.apps.detect import read_poses_file
    from topopose.frame.estimate import FrameEstimator

    inputs = [*_paths.capture_inputs(a.capture), ("--poses", a.poses),
              ("--model", _paths.file_input(a.model))]
    out = _paths.writable_folder(a.out, "--out", inputs=inputs)
    cap = load_capture(a.capture)
    poses, _ = read_poses_file(a.poses)
    if not poses:
        raise InputError(f"{a.poses}: no pose in the file")
    if a.frames:
        want = {cap.frame_name(f) for f in a.frames.split(",")}
        poses = [p for p in poses if p.frame in want]
    files = {"segmentation.jsonl": out / "segmentation.jsonl"}    # every file, checked first
    for p in poses:
        if p.status == "matched":
            files.update({f"{p.frame} labels": out / f"{p.frame}_labels.npz",
                          f"{p.frame} mesh": out / f"{p.frame}.ply",
                          **{f"{p.frame} {c.name}": out / f"{p.frame}_{c.name}.png"
                             for c in cap.cameras}})
    _paths.check_outputs({f"--out ({k})": v for k, v in files.items()}, inputs)
    model = guess_model(poses[0], a.model)
    res = a.resolution or int(poses[0].diagnostics.get("resolution", 100))
    tol = poses[0].diagnostics.get("hull_tolerance")
    est = FrameEstimator(cap, model, res, tolerance=None if tol is None else int(tol))

    def write(path, how):
        with _paths.atomic_output(path, "--out") as tmp:
            how(tmp)

    names_all = arc_names(model)
    cols = label_colours(len(names_all))
    n_done, summary = 0, []
    for p in poses:
        if p.status != "matched":
            continue
        pose, det = est.estimate(p.frame, detail=True)
        if pose.status != "matched" or det.alignment is None:
            summary.append({"frame": p.frame, "status": pose.status, "error": pose.error})
            continue
        t0 = time.perf_counter()
        labels, names = segment(det.volume, det.skeleton, det.alignment, det.data, names=names_all,
                                pose=pose, model=model)
        ms = (time.perf_counter() - t0) * 1e3
        vol = det.volume
        write(out / f"{p.frame}_labels.npz", lambda t: np.savez_compressed(
            t, labels=labels.astype(np.uint8), names=np.array(names), origin=vol.origin,
            voxel_size=vol.voxel_size))
        write(out / f"{p.frame}.ply",
              lambda t: write_label_mesh(t, labels, names, vol.origin, vol.voxel_size))
        sils = cap.silhouettes(p.frame)
        for cam, img in zip(cap.cameras, camera_masks(cap, labels, vol.origin, vol.voxel_size, sils)):
            write(out / f"{p.frame}_{cam.name}.png", lambda t: Image.fromarray(cols[img]).save(t))
        counts = np.bincount(labels.ravel(), minlength=len(names) + 1)[1:]
        summary.append({"frame": p.frame, "status": "segmented", "segment_ms": round(ms, 3),
                        "voxels": {n: int(c) for n, c in zip(names, counts)}})
        n_done += 1
    write(out / "segmentation.jsonl",
          lambda t: t.write_text("".join(json.dumps(s) + "\n" for s in summary)))
    print(f"segmented {n_done} matched frames into {out} (labels: "
          + ", ".join(f"{i + 1}={n}" for i, n in enumerate(names_all)) + ")")
    return 0


def detect_cli(a) -> int:
    """``topopose detect POSES.jsonl "EXPR" | --pose NAME [--output F.jsonl] [--csv F.csv]``."""
    import csv
    import sys

    from topopose import _paths

    outs = _paths.check_outputs({"--output": a.output, "--csv": a.csv},
                                [("POSES", a.poses), ("--library", a.library)])
    margin = _margin(getattr(a, "margin", 0.0))
    library, aliases = load_library(a.library)
    if a.list:
        for p in library.values():
            print(f"{p.name}: {p.expr}" + (f"   # {p.description}" if p.description else ""))
        return 0
    if (a.expr is None) == (a.pose is None):
        raise InputError("detect: give an expression or --pose NAME (one of them)")
    if a.pose is not None:
        if a.pose.lower() not in library:
            raise InputError(f"--pose: unknown pose {a.pose!r}; the library has "
                             f"{', '.join(p.name for p in library.values())}")
        expr = library[a.pose.lower()].expr
    else:
        expr = a.expr
    try:
        node = parse(expr)
    except ExpressionError as exc:
        print(f"topopose: error: {exc}", file=sys.stderr)       # keep the caret's line
        return 2
    poses, header = read_poses_file(a.poses)
    up = a.up or header_up(header) or "+z"
    res = detect(poses, node, up=up, aliases=aliases, margin=margin)
    if a.output:
        with _paths.atomic_output(outs["--output"], "--output") as tmp:
            tmp.write_text("".join(json.dumps(r) + "\n" for r in res))
    else:
        for r in res:
            print(json.dumps(r))
    if a.csv:
        with _paths.atomic_output(outs["--csv"], "--csv") as tmp, open(tmp, "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(["frame", "value"])
            for r in res:
                w.writerow([r["frame"], "" if r["value"] is None else int(r["value"])])
    n_true = sum(r["value"] is True for r in res)
    n_none = sum(r["value"] is None for r in res)
    runs = intervals(res)
    out = sys.stdout if a.output else sys.stderr
    print(f"{n_true} of {len(res)} frames true ({n_none} undecided), up {up}: {expr}", file=out)
    for first, last, n in runs:
        print(f"  {first} .. {last}  ({n} frames)", file=out)
    return 0


def cluster_cli(a) -> int:
    """``topopose cluster POSES.jsonl [--output F.jsonl] [--clusters K | --threshold T]``."""
    from topopose import _paths
    from topopose.apps.detect import header_up, read_poses_file

    if a.clusters is not None and a.threshold is not None:
        raise InputError("cluster: give --clusters or --threshold, not both")
    _paths.check_number(a.clusters, "--clusters", low=1, integer=True)
    _paths.check_number(a.threshold, "--threshold", low=0)
    outs = _paths.check_outputs({"--output": a.output, "--figure": a.figure},
                                [("POSES", a.poses)], suffixes={"--figure": ".png"})
    poses, header = read_poses_file(a.poses)
    if not poses:
        raise InputError(f"{a.poses}: no pose in the file")
    res = cluster_poses(poses, clusters=a.clusters, threshold=a.threshold, auto=a.auto)
    lines = "".join(json.dumps({"frame": f, "cluster": c}) + "\n" for f, c in zip(res.frames, res.labels))
    if a.output:
        with _paths.atomic_output(outs["--output"], "--output") as tmp:
            tmp.write_text(lines)
    else:
        print(lines, end="")
    import sys

    out = sys.stdout if a.output else sys.stderr
    print(f"{res.k} clusters over {len(res.used)} matched frames ({res.method})", file=out)
    for c, m in enumerate(res.medoids):
        print(f"  cluster {c}: {sum(v == c for v in res.labels)} frames, medoid {m}", file=out)
    if a.figure:
        with _paths.atomic_output(outs["--figure"], "--figure") as tmp:
            cluster_figure(poses, res, tmp, up=a.up or header_up(header) or "+z")
    return 0
