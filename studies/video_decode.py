"""Video decoding speed of the capture's frame source (part 1).

Usage: ``python studies/video_decode.py VIDEOS_FOLDER [--quick]`` — a folder of videos, one per
camera (e.g. the Pose2Sim recording's ``videos/``: 4 × 100 frames, 1088×1920 mp4). Without the
folder the benchmark says so and stops (the recording is not part of the repository).

Measured in one run, same files:

- **ours**: :meth:`VideoSource.sequential` — every frame of every camera, decoded forward
  (the reader thread's path);
- **peer**: random access with a seek per frame (``CAP_PROP_POS_FRAMES`` then ``read``), what a
  reader without a sequential path does (``topopose hull --frame F`` style);
- **overlap**: the :class:`Prefetcher` thread decoding ahead while the main thread "computes"
  (a ``time.sleep`` of the measured sequential decoding time per frame — a stand-in that leaves
  the cores to the decoder): total time against decode + compute one after the other.

Frame rates count *frame sets* (all cameras of one frame); images/s = frame sets/s × cameras.
Results: ``benchmarks/results/video_decode[_quick].{md,json}``.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import cv2

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(1, str(Path(__file__).resolve().parents[1] / "benchmarks"))  # the benchmarks a study builds on
from _machine import machine  # noqa: E402

from topopose.capture.sources import VIDEO_EXTENSIONS, Prefetcher, VideoSource  # noqa: E402


def _seek_each(videos: dict, n: int) -> float:
    t0 = time.perf_counter()
    for p in videos.values():
        vc = cv2.VideoCapture(str(p))
        for i in range(n):
            vc.set(cv2.CAP_PROP_POS_FRAMES, float(i))
            ok, _ = vc.read()
            assert ok
        vc.release()
    return time.perf_counter() - t0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("videos", nargs="?", help="folder with one video per camera")
    ap.add_argument("--quick", action="store_true", help="first 30 frames, one repetition")
    a = ap.parse_args(argv)
    if not a.videos or not Path(a.videos).is_dir():
        print("video_decode: no videos folder given (or not found): nothing measured. "
              "Usage: python studies/video_decode.py VIDEOS_FOLDER")
        return 0
    videos = {p.stem: p for p in sorted(Path(a.videos).iterdir())
              if p.suffix.lower() in VIDEO_EXTENSIONS}
    src = VideoSource(videos)
    n = min(30, src.count) if a.quick else src.count
    frames = src.frames[:n]
    reps = 1 if a.quick else 3
    seq, seek, over = [], [], []
    for _ in range(reps):
        t0 = time.perf_counter()
        for _f, imgs in src.sequential(frames):
            assert all(not isinstance(v, Exception) for v in imgs.values())
        seq.append(time.perf_counter() - t0)
        seek.append(_seek_each(videos, n))
        per = min(seq) / n
        t0 = time.perf_counter()
        pf = Prefetcher(frames, lambda f, imgs: len(imgs), src, depth=4)
        for f in frames:
            pf.take(f)
            time.sleep(per)
        pf.close()
        over.append(time.perf_counter() - t0)
    cams = len(videos)
    ts, tk, to = min(seq), min(seek), min(over)
    res = {"videos": str(a.videos), "cameras": cams, "frames": n,
           "sizes": {c: list(s) for c, s in src.sizes.items()},
           "sequential_s": ts, "sequential_fps": n / ts, "sequential_images_per_s": cams * n / ts,
           "seek_each_s": tk, "seek_each_fps": n / tk, "speedup_vs_seek": tk / ts,
           "prefetch_overlap_s": to, "decode_plus_compute_serial_s": 2 * ts,
           "overlap_ratio": to / (2 * ts), "repetitions": reps,
           "machine": machine(opencv=cv2.__version__)}
    out = Path(__file__).resolve().parent / "results"
    out.mkdir(exist_ok=True)
    stem = "video_decode_quick" if a.quick else "video_decode"
    (out / f"{stem}.json").write_text(json.dumps(res, indent=1))
    m = res["machine"]
    md = [f"# Video decoding ({cams} cameras × {n} frames, {a.videos})", "",
          f"Machine: {m['cpu']}, {m['cores']} cores, load {m['load_average']}, OpenCV "
          f"{m['opencv']}, {m['date']}. Best of {reps}.", "",
          "| reader | time (s) | frame sets/s | images/s | ratio |", "| --- | --- | --- | --- | --- |",
          f"| ours: sequential (VideoSource.sequential) | {ts:.2f} | {n / ts:.1f} | "
          f"{cams * n / ts:.0f} | 1 |",
          f"| peer: seek + read per frame | {tk:.2f} | {n / tk:.1f} | {cams * n / tk:.0f} | "
          f"{tk / ts:.2f}× slower |", "",
          f"Overlap: reader thread decoding while the main thread spends the same time again per "
          f"frame: {to:.2f} s against {2 * ts:.2f} s one after the other "
          f"({to / (2 * ts):.2f} of the serial time; 0.5 = perfect overlap).", ""]
    (out / f"{stem}.md").write_text("\n".join(md))
    print("\n".join(md))
    return 0


if __name__ == "__main__":
    sys.exit(main())
