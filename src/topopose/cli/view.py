"""`topopose view`: a picture of one frame."""
from __future__ import annotations

from topopose.errors import InputError
from topopose.pose.model import guess_model
from topopose.viz.view import render_frame


def view_cli(a) -> int:
    """``topopose view CAPTURE --poses POSES.jsonl --frame F --out PICTURE.png``."""
    from topopose.capture import load_capture
    from topopose.frame.estimate import FrameEstimator
    from topopose.pose.pose import read_poses

    cap = load_capture(a.capture)
    frame = cap.frame_name(a.frame)
    poses = {p.frame: p for p in read_poses(a.poses)}
    if frame not in poses:
        raise InputError(f"{a.poses}: no pose for frame {frame!r}")
    pose = poses[frame]
    model = guess_model(pose, a.model)
    res = a.resolution or int(pose.diagnostics.get("resolution", 100))
    tol = pose.diagnostics.get("hull_tolerance")
    est = FrameEstimator(cap, model, res, tolerance=None if tol is None else int(tol))
    _, det = est.estimate(frame, detail=True)
    from topopose._paths import atomic_output

    with atomic_output(a.out, "--out") as tmp:   # an existing picture is replaced only when done
        if getattr(a, "segmentation", False):
            from topopose.apps.segment import segmentation_figure

            segmentation_figure(tmp, cap, frame, model, det, up=cap.up_vector, pose=pose)
        else:
            render_frame(tmp, model, pose, det, cap=cap, silhouettes=a.silhouettes,
                         up=cap.up_vector)
    print(f"wrote {a.out}")
    return 0
