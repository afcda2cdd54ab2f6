"""Rendering time of the ``body`` subject (MakeHuman mesh, 26,756 triangles): one frame = 8
cameras at 640×480 (half of them with lens distortion), against the capsule ``human`` renderer
(round cones and ellipsoids) in the same run. Also times the posing (skinning + ground truth).

    python benchmarks/synth_body.py [--frames 20] [--out benchmarks/results]

Writes ``synth_body.md`` and ``synth_body.json`` (machine noted).
"""
import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from _machine import machine  # noqa: E402

from topopose.synth.capture import synthetic_capture  # noqa: E402
from topopose.synth.body import body_random, make_build, pose_body  # noqa: E402
from topopose.synth.geometry import ray_table, render  # noqa: E402


def frame_times(cap, fn, repeats=3):
    tables = [ray_table(c) for c in cap.cameras]
    out = []
    for body in cap.options["bodies"]:
        best = np.inf
        for _ in range(repeats):
            t = time.perf_counter()
            for cam, tab in zip(cap.cameras, tables):
                fn(body, cam, tab)
            best = min(best, time.perf_counter() - t)
        out.append(best)
    return np.array(out) * 1000


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=20)
    ap.add_argument("--out", default=str(Path(__file__).parent / "results"))
    a = ap.parse_args(argv)
    body = synthetic_capture("body", frames=a.frames, seed=1)
    human = synthetic_capture("human", frames=a.frames, seed=1)
    frame_times(body, lambda b, c, t: b.render(c, t), 1)        # compile / warm up
    frame_times(human, lambda b, c, t: render(c, t, b.prims), 1)
    tb = frame_times(body, lambda b, c, t: b.render(c, t))
    th = frame_times(human, lambda b, c, t: render(c, t, b.prims))
    rng = np.random.default_rng(0)
    build = make_build("random", rng)
    t = time.perf_counter()
    for _ in range(a.frames):
        pose_body(body_random(rng), build).clearances()
    tp = (time.perf_counter() - t) / a.frames * 1000
    res = {"machine": machine(), "frames": a.frames, "cameras": 8, "size": [640, 480],
           "body_render_ms": {"median": float(np.median(tb)), "max": float(tb.max())},
           "human_render_ms": {"median": float(np.median(th)), "max": float(th.max())},
           "ratio_body_over_human": float(np.median(tb) / np.median(th)),
           "body_pose_and_clearances_ms": tp}
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "synth_body.json").write_text(json.dumps(res, indent=1))
    m = res["machine"]
    md = (f"# body subject: rendering time per frame (8 cameras, 640×480)\n\n"
          f"Machine: {m['cpu']}, {m['cores']} cores, load {m['load_average']}, {m['date']}; "
          f"best of 3 per frame, {a.frames} frames.\n\n"
          "| renderer | median ms/frame | max ms/frame |\n|---|---:|---:|\n"
          f"| body (mesh rasterizer, 26,756 triangles) | {np.median(tb):.1f} | {tb.max():.1f} |\n"
          f"| human (capsules, ray tests) | {np.median(th):.1f} | {th.max():.1f} |\n\n"
          f"Ratio body / human (median): {res['ratio_body_over_human']:.2f}. Posing the body "
          f"(skinning, ground truth, limb clearances): {tp:.1f} ms per frame.\n")
    (out / "synth_body.md").write_text(md)
    print(md)


if __name__ == "__main__":
    main()
