"""A real 10-camera studio capture as it comes, end to end, against the peer in the same run.

    python benchmarks/_real_child.py CHILD_ROPE [--pose2sim RECORDING] [--peer PEER_SRC]
                                    [--frames A:B] [--memory-frames N] [--out PREFIX]

CHILD_ROPE: the recording's folder (``cam00`` … ``cam09``, each with ``cam_par.txt`` — the
camera's name and its 3×4 projection matrix — and the masks ``0.png`` … ``409.png``, 1624×1224).
It is set up as a user would, in a temporary folder: ``topopose calib import`` of the ten
``cam_par.txt`` files in one call (each camera named by its file: ``cam00`` … ``cam05``,
``cam09``, ``cam10``, ``cam12``, ``cam13``), ``silhouettes/<camera>`` linked to the folder its
file lies in.
Nothing of the recording is copied.

PEER_SRC: the ``src`` folder of the tree measured against (the current main, e.g. a worktree
of it); each side runs in its own process with ``PYTHONPATH`` set to its ``src``
(``benchmarks/_capture_run.py``), one after the other, so both see the machine's load of that
moment; the machine (cores, CPU, load) is recorded.

Figures, per side:

- the whole run (``topopose run CAPTURE --model human``, resolution 100, as ``run`` does it:
  its reader decoding ahead, the sequence stages, the tracker) against one thread's bare
  ``cv2.imread`` of the same mask files, measured in the same process just before (ratio;
  target ≤ 1.5); the frame loop and what follows it (sequence stage, tracker, output) apart,
  and the tracker's CPU time a frame by step;
- the first frame: from the call of ``run`` to the first pose, caches warm (target ≤ 3 s),
  and from the process start;
- frames matched, rejected, failed (with the reasons), frames carved beyond the fitted volume;
- per-stage medians (ms);
- compute alone: frames spread over the recording, their masks decoded beforehand, one core
  (``NUMBA_NUM_THREADS=1``), frames/s at 100³ (target ≥ 25);
- a contact sheet of this branch's matched frames, the parts drawn on two cameras' masks.

With ``--pose2sim``: Pose2Sim's balancing trial with ``person`` silhouettes (MediaPipe), end to
end from the 4 videos (decoding and segmentation included): frames/s, per-stage medians, and
the two sides' poses compared field by field (``benchmarks/_same_poses.py``).

With ``--synthetic N``: a synthetic capture (human, N frames, smooth random motion, noise 1,
8 cameras 640×480) run by both sides and scored against its ground truth
(:func:`topopose.batch.quality.evaluate`): the accuracy the mask resolution keeps.

Writes ``PREFIX.md`` / ``.json`` and ``PREFIX_sheet.png`` (default
``benchmarks/results/real_child``).
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
OURS = HERE.parent / "src"


def side(src: Path, *args, single_core=False) -> dict:
    """``_capture_run.py`` with ``src`` on ``PYTHONPATH``; its JSON line."""
    env = dict(os.environ, PYTHONPATH=str(src))
    if single_core:
        env.update(NUMBA_NUM_THREADS="1", OMP_NUM_THREADS="1", OPENCV_FOR_THREADS_NUM="1")
    r = subprocess.run([sys.executable, str(HERE / "_capture_run.py"), *map(str, args)],
                       env=env, capture_output=True, text=True)
    if r.returncode != 0:
        raise RuntimeError(f"{src}: {' '.join(map(str, args))} failed:\n{r.stderr[-3000:]}")
    return json.loads(r.stdout.strip().splitlines()[-1])


def child_capture(rec: Path, out: Path) -> Path:
    """The recording set up as a user would (module docstring); ``topopose calib import`` of
    this branch (the peer's refuses the ten same-named files)."""
    files = sorted(rec.glob("cam*/cam_par.txt"))
    (out / "silhouettes").mkdir(parents=True)
    env = dict(os.environ, PYTHONPATH=str(OURS))
    subprocess.run([sys.executable, "-m", "topopose.cli", "calib", "import", *map(str, files),
                    "--size", "1624x1224", "--out", str(out / "calibration.toml")],
                   env=env, check=True, capture_output=True)
    for f in files:                # each camera's masks under the name its file gives
        name = f.read_text().split()[0]
        (out / "silhouettes" / name).symlink_to(f.parent.resolve(), target_is_directory=True)
    return out


def peer_calib_import(peer: Path, rec: Path) -> str:
    """What the peer's ``calib import`` says of the ten files."""
    files = sorted(rec.glob("cam*/cam_par.txt"))
    with tempfile.TemporaryDirectory() as tmp:
        r = subprocess.run([sys.executable, "-m", "topopose.cli", "calib", "import",
                            *map(str, files), "--size", "1624x1224", "--out",
                            str(Path(tmp) / "c.toml")],
                           env=dict(os.environ, PYTHONPATH=str(peer)), capture_output=True,
                           text=True)
    return (r.stdout + r.stderr).strip().splitlines()[-1] if (r.stdout + r.stderr).strip() else ""


def contact_sheet(capture: Path, poses_file: Path, out: Path, cams=(0, 5), height=150,
                  columns=10) -> int:
    """Every matched frame: the masks of two cameras around the subject (its box and a quarter
    more, ``height`` px high), the parts projected on them (a dot each, the model's edges as
    lines), the frame's name. Returns the number of frames drawn."""
    import cv2

    from topopose.capture import load_capture
    from topopose.pose.model import load_model
    from topopose.pose.pose import read_poses

    cap = load_capture(capture)
    model = load_model("human")
    edges = {(_stem(u), _stem(v)) for u in model.parts for v, _ in model.tree.adjacency()[u]}
    poses = [p for p in read_poses(poses_file) if p.status == "matched"]
    tiles = []
    for p in poses:
        masks = cap.silhouettes(p.frame)
        views = []
        for c in cams:
            cam, m = cap.cameras[c], masks[c]
            x, y, w, h = cv2.boundingRect(np.ascontiguousarray(m, dtype=np.uint8))
            side = int(1.25 * max(w, h, 8))
            x0, y0 = x + w // 2 - side // 2, y + h // 2 - side // 2
            crop = np.full((side, side), 40, np.uint8)
            sx0, sy0 = max(x0, 0), max(y0, 0)
            sx1, sy1 = min(x0 + side, m.shape[1]), min(y0 + side, m.shape[0])
            crop[sy0 - y0:sy1 - y0, sx0 - x0:sx1 - x0] = np.where(m[sy0:sy1, sx0:sx1], 200, 40)
            scale = height / side
            img = cv2.cvtColor(cv2.resize(crop, (height, height), interpolation=cv2.INTER_AREA),
                               cv2.COLOR_GRAY2BGR)
            pts = {}
            for name, X in p.parts.items():
                if X is not None:
                    uv = (cam.project(np.asarray(X, float)[None])[0] - [x0, y0]) * scale
                    if np.all(np.isfinite(uv)):
                        pts[name] = tuple(int(round(t)) for t in uv)
            for a, ua in pts.items():         # the model's edges, by part stems
                for b, ub in pts.items():
                    if (_stem(a), _stem(b)) in edges:
                        cv2.line(img, ua, ub, (0, 160, 255), 1, cv2.LINE_AA)
            for name, uv in pts.items():
                col = ((0, 0, 255) if "left" in name else (255, 0, 0) if "right" in name
                       else (0, 200, 0))
                cv2.circle(img, uv, 3, col, -1, cv2.LINE_AA)
            views.append(img)
        tile = np.hstack(views)
        cv2.putText(tile, str(p.frame), (4, 14), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (0, 255, 255), 1)
        tiles.append(tile)
    if not tiles:
        return 0
    rows = []
    blank = np.zeros_like(tiles[0])
    for i in range(0, len(tiles), columns):
        row = tiles[i:i + columns]
        rows.append(np.hstack(row + [blank] * (columns - len(row))))
    cv2.imwrite(str(out), np.vstack(rows))
    return len(tiles)


def _stem(name) -> str:
    """``hand_1``, ``left_hand`` → ``hand``."""
    name = name.rstrip("_0123456789")
    for side in ("left_", "right_"):
        if name.startswith(side):
            return name[len(side):]
    return name


def _ratio(a, b):
    return round(a / b, 3) if a is not None and b else None


def machine_now() -> dict:
    from _machine import machine

    cpu = ""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return machine(nproc=os.cpu_count(), cpuinfo=cpu)


def child(rec: Path, peer: Path, frames, memory_frames: int, out: Path, tmp: Path) -> dict:
    cap = child_capture(rec, tmp / "child")
    doc = {"recording": str(rec), "frames_selected": frames or "all",
           "peer_calib_import": peer_calib_import(peer, rec), "sides": {}}
    for name, src in (("peer", peer), ("ours", OURS)):
        load = os.getloadavg()[0]
        dec = side(src, "decode", cap)
        run = side(src, "run", cap, tmp / f"{name}_child.jsonl",
                   *(["--frames", frames] if frames else []))
        mem = side(src, "memory", cap, "--frames", memory_frames, single_core=True)
        n_files = dec["files"] * (run["frames"] / max(1, len(list((cap / "silhouettes" /
                                                                    "cam00").glob("*.png")))))
        dec_s = dec["seconds"] * n_files / dec["files"]          # the frames run, decoded
        doc["sides"][name] = {"load_before": round(load, 2), "decode": dec,
                              "decode_s_for_frames_run": round(dec_s, 3), "run": run,
                              "run_over_decode": _ratio(run["run_s"], dec_s),
                              "memory": mem}
        print(name, json.dumps(doc["sides"][name]))
    o, p = doc["sides"]["ours"], doc["sides"]["peer"]
    doc["ratios_ours_to_peer"] = {
        "run_s": _ratio(o["run"]["run_s"], p["run"]["run_s"]),
        "first_frame_s": _ratio(o["run"]["first_frame_s"], p["run"]["first_frame_s"]),
        "memory_fps": _ratio(o["memory"]["fps_median"], p["memory"]["fps_median"])}
    sheet = out.parent / f"{out.name}_sheet.png"
    doc["contact_sheet"] = {"file": sheet.name,
                            "frames": contact_sheet(cap, tmp / "ours_child.jsonl", sheet)}
    from _same_poses import compare
    c = compare(tmp / "peer_child.jsonl", tmp / "ours_child.jsonl")
    doc["same_as_peer"] = {"identical": c["identical"], "frames": c["frames"]}
    return doc


def memory_compare(rec: Path, peer: Path, n: int, out: Path) -> int:
    """``benchmarks/pipeline.py --child``: compute alone (masks in memory, one core, 100³) on
    ``n`` frames spread over the recording, this branch against the peer; writes ``out``.md /
    .json."""
    from _machine import machine_line

    with tempfile.TemporaryDirectory() as tmp:
        cap = child_capture(rec, Path(tmp) / "child")
        doc = {"machine": machine_now(), "peer": str(peer), "recording": str(rec),
               "order": "peer, ours, ours, peer (a load that drifts weighs on both alike)",
               "runs": {"peer": [], "ours": []}, "sides": {}}
        for name in ("peer", "ours", "ours", "peer"):
            load = round(os.getloadavg()[0], 2)
            r = side(peer if name == "peer" else OURS, "memory", cap, "--frames", n,
                     single_core=True)
            r["load_before"] = load
            doc["runs"][name].append(r)
            print(name, json.dumps(r))
    for name, runs in doc["runs"].items():        # each figure: the mean of the two runs
        same = {k for k in runs[0] if all(r[k] == runs[0][k] for r in runs)}
        doc["sides"][name] = {
            k: (runs[0][k] if k in same or isinstance(runs[0][k], dict)
                else round(float(np.mean([r[k] for r in runs])), 2)) for k in runs[0]}
        doc["sides"][name]["stage_ms"] = {
            k: round(float(np.mean([r["stage_ms"][k] for r in runs])), 2)
            for k in runs[0]["stage_ms"]}
    o, p = doc["sides"]["ours"], doc["sides"]["peer"]
    m = doc["machine"]
    text = ["# Compute alone on a real studio capture (child_rope, masks in memory, one core, "
            "100³)", "", machine_line(m) + f"; nproc {m['nproc']}; {m['cpuinfo']}", "",
            f"{o['frames']} frames spread over the recording; each side in its own process "
            "(`benchmarks/_capture_run.py memory`), `NUMBA_NUM_THREADS=1`, twice, in the order "
            "peer, ours, ours, peer; each figure the mean of a side's two runs (1-minute load "
            "average before each run: "
            + ", ".join(f"{n} {r['load_before']}" for n in ("peer", "ours")
                        for r in doc["runs"][n]) + "). On a shared machine the wall-clock "
            "figures follow the load; the CPU time is the process' own.", "",
            "| figure | ours | peer | ours / peer |", "|---|---|---|---|",
            _row("frames/s (median frame; target ≥ 25)", o["fps_median"], p["fps_median"]),
            _row("frames/s (mean)", o["fps_mean"], p["fps_mean"]),
            _row("median ms/frame", o["median_ms"], p["median_ms"]),
            _row("median CPU ms/frame (the process' own time)", o.get("cpu_median_ms"),
                 p.get("cpu_median_ms")),
            _row("first frame (s)", o["setup_s"], p["setup_s"]), "",
            _stage_table([("child_rope in memory (ours)", o["stage_ms"]),
                          ("child_rope in memory (peer)", p["stage_ms"])]), ""]
    out.with_suffix(".json").write_text(json.dumps(doc, indent=1))
    out.with_suffix(".md").write_text("\n".join(text))
    print(f"wrote {out}.md / .json")
    return 0


def pose2sim(rec: Path, peer: Path, tmp: Path) -> dict:
    import real

    got = real.person_recording(rec)
    if not isinstance(got, tuple):
        return {"skipped": "recording or mediapipe absent"}
    cap = tmp / "p2s"
    real.make_capture(rec, cap, "person")
    doc = {"recording": str(rec), "sides": {}}
    for name, src in (("peer", peer), ("ours", OURS)):
        r = side(src, "run", cap, tmp / f"{name}_p2s.jsonl")
        r["fps_frame_loop"] = round(r["frames"] / r["frame_loop_s"], 2)
        r["fps_run"] = round(r["frames"] / r["run_s"], 2)
        doc["sides"][name] = r
        print(name, json.dumps(r))
    from _same_poses import compare
    c = compare(tmp / "peer_p2s.jsonl", tmp / "ours_p2s.jsonl")
    doc["same_as_peer"] = {"identical": c["identical"], "frames": c["frames"],
                           "differ": {f: v[:4] for f, v in list(c["differ"].items())[:5]}}
    doc["ratio_fps_ours_to_peer"] = _ratio(doc["sides"]["ours"]["fps_run"],
                                           doc["sides"]["peer"]["fps_run"])
    return doc


def synthetic(n: int, peer: Path, tmp: Path) -> dict:
    from topopose.capture import load_capture
    from topopose.pose.pose import read_poses
    from topopose.batch.quality import evaluate

    cap = tmp / "synth"
    env = dict(os.environ, PYTHONPATH=str(OURS))
    subprocess.run([sys.executable, "-m", "topopose.cli", "synth", str(cap), "--frames", str(n),
                    "--motion", "random-smooth", "--noise", "1", "--seed", "5"], env=env,
                   check=True, capture_output=True)
    gt = load_capture(cap).gt
    doc = {"capture": f"human, {n} frames, random-smooth, noise 1, seed 5, 8 cameras 640x480",
           "sides": {}}
    for name, src in (("peer", peer), ("ours", OURS)):
        r = side(src, "run", cap, tmp / f"{name}_synth.jsonl")
        ev = evaluate(gt, read_poses(tmp / f"{name}_synth.jsonl"))
        pe = ev.part_errors()
        r["quality"] = ev.counts
        r["rates_T2"] = {k: round(v, 4) for k, v in ev.rates(2.0).items()}
        r["median_part_error_cm"] = round(100 * float(np.median(
            [v for v in pe.values() if v == v])), 2) if pe else None
        doc["sides"][name] = r
        print(name, json.dumps({k: r[k] for k in ("counts", "quality", "rates_T2")}))
    return doc


def _row(label, o, p, fmt="{:.2f}"):
    f = (lambda x: "–" if x is None else fmt.format(x))
    return f"| {label} | {f(o)} | {f(p)} | {f(_ratio(o, p))} |"


def report(doc) -> str:
    from _machine import machine_line

    m = doc["machine"]
    out = ["# A real studio capture as it comes (child_rope), against the current main", "",
           machine_line(m) + f"; nproc {m['nproc']}; /proc/cpuinfo: {m['cpuinfo']}", "",
           "Produced by `benchmarks/_real_child.py` (also `benchmarks/real.py --child`). Each side "
           "runs in its own process, one after the other, in the same run; a shared machine's "
           "load moves both.", ""]
    ch = doc.get("child")
    if ch:
        o, p = ch["sides"]["ours"], ch["sides"]["peer"]
        out += ["## child_rope end to end (`topopose run CAPTURE --model human`, 100³)", "",
                f"Frames: {ch['frames_selected']}. The peer's `calib import` of the ten "
                f"`cam_par.txt`: \"{ch['peer_calib_import']}\" (the capture is set up with "
                "this branch's; both sides run on it).", "",
                "| figure | ours | peer | ours / peer |", "|---|---|---|---|",
                _row("whole run (s)", o["run"]["run_s"], p["run"]["run_s"]),
                _row("one thread's bare PNG decoding of the same files (s)",
                     o["decode_s_for_frames_run"], p["decode_s_for_frames_run"]),
                _row("whole run / decoding (target ≤ 1.5)", o["run_over_decode"],
                     p["run_over_decode"]),
                _row("of the whole run: the frame loop (s)", o["run"]["frame_loop_s"],
                     p["run"]["frame_loop_s"]),
                _row("of the whole run: after the frame loop — sequence stage, tracker, "
                     "output (s)", o["run"].get("after_loop_s"), p["run"].get("after_loop_s")),
                _row("peak resident memory of the run (MB)", o["run"].get("max_rss_mb"),
                     p["run"].get("max_rss_mb")),
                _row("first frame from `run` (s, target ≤ 3)", o["run"]["first_frame_s"],
                     p["run"]["first_frame_s"]),
                _row("first frame from process start (s)", o["run"]["first_frame_since_start_s"],
                     p["run"]["first_frame_since_start_s"]),
                _row("compute, masks in memory, one core: frames/s (target ≥ 25)",
                     o["memory"]["fps_median"], p["memory"]["fps_median"]),
                _row("compute, masks in memory: median ms/frame", o["memory"]["median_ms"],
                     p["memory"]["median_ms"]),
                _row("frames matched", o["run"]["counts"].get("matched"),
                     p["run"]["counts"].get("matched"), "{:.0f}"),
                _row("frames rejected", o["run"]["counts"].get("rejected"),
                     p["run"]["counts"].get("rejected"), "{:.0f}"),
                _row("frames failed", o["run"]["counts"].get("failed"),
                     p["run"]["counts"].get("failed"), "{:.0f}"),
                _row("frames carved beyond the fitted volume", o["run"]["beyond"],
                     p["run"]["beyond"], "{:.0f}"),
                _row("load average before the side", o["load_before"], p["load_before"]), "",
                f"Failed frames — ours: {_failed(o['run'])}; peer: {_failed(p['run'])}.", "",
                f"Poses identical to the peer's, field by field (timings excluded): "
                f"{ch['same_as_peer']['identical']} of {ch['same_as_peer']['frames']} frames.",
                "",
                f"Contact sheet of this branch's {ch['contact_sheet']['frames']} matched frames "
                f"(cameras cam00 and cam05, the parts as dots, the model's edges as lines): "
                f"`{ch['contact_sheet']['file']}`.", "",
                "Per-stage medians (ms; `placement` includes trim, centre and support):", "",
                _stage_table([("child_rope, run (ours)", o["run"]["stage_ms"]),
                              ("child_rope, run (peer)", p["run"]["stage_ms"]),
                              ("child_rope, masks in memory (ours)", o["memory"]["stage_ms"]),
                              ("child_rope, masks in memory (peer)", p["memory"]["stage_ms"])]),
                "", "The tracking stage, after the frame loop: its CPU time a frame (ms, the "
                "stage's mean over the run; `track_hull`: the frames' hulls and silhouettes "
                "read, or carved again; `track_data`: the fit's points and rays; `track_fit`: "
                "the fits; `track_quality`: the silhouette IoU):", "",
                _stage_table([("child_rope, run (ours)", o["run"]["stage_ms"]),
                              ("child_rope, run (peer)", p["run"]["stage_ms"])], TRACK_KEYS),
                ""]
    ps = doc.get("pose2sim")
    if ps and "sides" in ps:
        o, p = ps["sides"]["ours"], ps["sides"]["peer"]
        out += ["## Pose2Sim balancing trial, `person` silhouettes, end to end from the 4 videos",
                "", "| figure | ours | peer | ours / peer |", "|---|---|---|---|",
                _row("frames/s, whole `run` (decoding, MediaPipe, sequence stages)",
                     o["fps_run"], p["fps_run"]),
                _row("frames/s, frame loop", o["fps_frame_loop"], p["fps_frame_loop"]),
                _row("peak resident memory of the run (MB)", o.get("max_rss_mb"),
                     p.get("max_rss_mb")),
                _row("after the frame loop — sequence stage, tracker, output (s)",
                     o.get("after_loop_s"), p.get("after_loop_s")),
                _row("first frame from `run` (s)", o["first_frame_s"], p["first_frame_s"]),
                _row("frames matched", o["counts"].get("matched"), p["counts"].get("matched"),
                     "{:.0f}"), "",
                f"Poses identical to the peer's, field by field (timings excluded): "
                f"{ps['same_as_peer']['identical']} of {ps['same_as_peer']['frames']} frames.", "",
                _stage_table([("Pose2Sim person (ours)", o["stage_ms"]),
                              ("Pose2Sim person (peer)", p["stage_ms"])]), "",
                "The tracking stage's CPU time a frame (ms):", "",
                _stage_table([("Pose2Sim person (ours)", o["stage_ms"]),
                              ("Pose2Sim person (peer)", p["stage_ms"])], TRACK_KEYS), ""]
    elif ps:
        out += ["## Pose2Sim", "", ps["skipped"], ""]
    sy = doc.get("synthetic")
    if sy:
        o, p = sy["sides"]["ours"], sy["sides"]["peer"]
        out += ["## Accuracy on a synthetic capture with ground truth", "", sy["capture"], "",
                "| figure | ours | peer |", "|---|---|---|"]
        for k in o["quality"]:
            out.append(f"| frames {k} | {o['quality'][k]} | {p['quality'][k]} |")
        for k in o["rates_T2"]:
            out.append(f"| {k} (T_d 2) | {o['rates_T2'][k]} | {p['rates_T2'][k]} |")
        out += [f"| median part error of matched frames (cm) | {o['median_part_error_cm']} | "
                f"{p['median_part_error_cm']} |", ""]
    return "\n".join(out) + "\n"


def _failed(r) -> str:
    f = r["failed"]
    if not f:
        return "none"
    reasons = {}
    for k, v in f.items():
        reasons.setdefault(v.split(";")[0][:90], []).append(k)
    return "; ".join(f"{len(v)} × {k} ({', '.join(v[:5])}{'…' if len(v) > 5 else ''})"
                     for k, v in reasons.items())


TRACK_KEYS = ("track_hull", "track_data", "track_fit", "track_quality")


def _stage_table(rows, keys=("hull", "thinning", "tree", "alignment", "placement", "trim",
                             "centre", "support", "total")) -> str:
    lines = ["| recording | " + " | ".join(keys) + " |", "|---" * (len(keys) + 1) + "|"]
    for label, st in rows:
        lines.append(f"| {label} | " + " | ".join(
            "–" if st.get(k) is None else f"{st[k]:.1f}" for k in keys) + " |")
    return "\n".join(lines)


def missing_inputs(rec: Path, peer: Path) -> str | None:
    """What is missing among the child recording ``rec`` and the peer's ``src`` folder, said
    plainly, or None."""
    if not (rec / "cam00" / "cam_par.txt").is_file():
        return f"{rec}: child_rope recording not found (cam00/cam_par.txt …); pass its path"
    if not (peer / "topopose" / "__init__.py").is_file():
        return f"{peer}: no peer tree (its src folder holding topopose/); pass --peer"
    return None


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("child", help="the child_rope recording's folder")
    ap.add_argument("--pose2sim", help="Pose2Sim's balancing trial (videos/, Calib.toml, "
                                       "reference/)")
    ap.add_argument("--peer", default=str(HERE.parent.parent / "peer-capture" / "src"),
                    help="src folder of the peer tree (the current main)")
    ap.add_argument("--frames", help="a slice of the frames, e.g. 0:410:5 (default all)")
    ap.add_argument("--memory-frames", type=int, default=30)
    ap.add_argument("--synthetic", type=int, default=0, help="frames of the synthetic capture "
                                                             "(0: none)")
    ap.add_argument("--out", default=str(HERE / "results" / "real_child"))
    a = ap.parse_args(argv)
    rec, peer = Path(a.child), Path(a.peer)
    bad = missing_inputs(rec, peer)
    if bad:
        print(bad)
        return 2
    out = Path(a.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    doc = {"machine": machine_now(), "peer": str(peer)}
    t = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        doc["child"] = child(rec, peer, a.frames, a.memory_frames, out, tmp)
        if a.pose2sim:
            doc["pose2sim"] = pose2sim(Path(a.pose2sim), peer, tmp)
        if a.synthetic:
            doc["synthetic"] = synthetic(a.synthetic, peer, tmp)
    doc["machine_after"] = {"load_average": round(os.getloadavg()[0], 2)}
    doc["seconds"] = round(time.perf_counter() - t, 1)
    out.with_suffix(".json").write_text(json.dumps(doc, indent=1))
    out.with_suffix(".md").write_text(report(doc))
    print(f"wrote {out}.md / .json")
    return 0


if __name__ == "__main__":
    sys.exit(main())
