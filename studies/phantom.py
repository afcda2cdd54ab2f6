"""Why are the 4-camera synthetic walks wrong? A diagnostic of the phantom
extension.

    python studies/phantom.py [--setups 4,4p] [--seeds 41,42,43,44] [--frames 40] [--work DIR]
                                 [--out PATH]

On the real 4-camera recording the wrong frames hold a hand in a phantom volume of the hull: the
skeleton's arm branch passes by the real hand and continues through a tube that every
silhouette explains (two cameras see the hand against the background along nearly parallel
rays, the other two see the arm inside the trunk), so the hand ends at the far end of the tube
(``results/real_hands.md``). This benchmark asks whether the synthetic 4-camera walks of
``benchmarks/consistency.py`` (the ``body`` subject, set-ups ``4`` and ``4p``, as the run
writes them: :func:`consistency.sequence`, :func:`consistency.as_run`; its cache ``--work``)
fail the same way. For every frame that is not right (a true positive (TP) of the quality classes, 0.08 × height), every
wrong part (placed, farther than the tolerance from its ground-truth segment after the optimal
pairing of :func:`topopose.batch.quality.evaluate`) is tested for:

- **beyond**: the part's skeleton curve (``diagnostics["curves"]``, from the torso to the
  part) passes within the tolerance of the part's true segment before its end (the part lies
  further along its own branch than the truth); ``extension``: the curve's length from that
  closest point to the part;
- **phantom**: the part projects at least :data:`INTERIOR` px inside the silhouette (distance
  transform) in at least two cameras (it is in a region no camera sees against background in
  two views at least);
- **aligned**: every camera that sees the true part against the background (its projection at
  most :data:`BORDER` px inside the silhouette, or outside) has its ray through our part within
  :data:`RAY_ANGLE` of the error vector (ours − the truth), and there is at least one;
- other wrong parts: ``swap`` (within the tolerance of another part's true segment: the
  per-frame alignment labelled the limbs wrongly), ``short`` (within the tolerance of its own
  limb's other bones, upper arm / forearm, thigh / shank: the part stops short), else
  ``other``. Frames with two or more unplaced parts (``partial``/``none``) are counted apart.

Writes ``results/phantom.{md,json}``.

    python studies/phantom.py --effect [--setups 4,4p,4r,8] [--seeds ...] [--label NAME]

The effect of the hands' trim (:mod:`topopose.frame.trim`, the sequence stage ``topopose run``
runs with the capture's silhouettes): per set-up, right frames (all, as the run writes them),
precision of ``matched`` and of ``run --consistency``, without → with the trim. Writes
``results/phantom_trim_{label}.{md,json}``.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(1, str(Path(__file__).resolve().parents[1] / "benchmarks"))  # the benchmarks a study builds on

INTERIOR = 5.0      # px: a point this deep inside a silhouette is "inside its interior"
BORDER = 3.0        # px: the true part this close to the border (or outside) is seen against
#                     the background
RAY_ANGLE = 25.0    # degrees between the error and a camera's ray: along the ray
#: set-ups beside consistency.py's ("4", "4p": the even ring): the real recording's layout of two
#: facing pairs (``synth.camera_ring`` layout "pairs", as benchmarks/tracking.py's 4p) and the
#: same with every silhouette dilated by 3 px (tracking.py's 4pd: a hull as fat as the real one)
PAIRS = {"4r": ((4, (544, 960), 2), 0), "4rd": ((4, (544, 960), 2), 3)}


def capture(setup, seed, frames):
    """The synthetic capture of one sequence of a set-up (consistency.py's, or :data:`PAIRS`)."""
    import consistency as CB
    from topopose.synth.capture import synthetic_capture

    if setup in PAIRS:
        (cams, size, noise), dil = PAIRS[setup]
        layout = "pairs"
    else:
        (cams, size, noise), dil, layout = CB.SETUPS[setup], 0, "ring"
    cap = synthetic_capture("body", frames=frames, seed=seed, cameras=cams, size=size,
                            noise=noise, motion="walk", build=CB.BUILDS[seed % len(CB.BUILDS)],
                            layout=layout)
    if dil:
        import cv2

        ker = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * dil + 1, 2 * dil + 1))
        cap.masks = {f: [cv2.dilate(m.astype(np.uint8), ker) > 0 for m in ms]
                     for f, ms in cap.masks.items()}
    return cap


def sequence(setup, seed, frames, work=None):
    """Per-frame poses and ground truth (consistency.py's :func:`consistency.sequence`, its
    cache; the :data:`PAIRS` set-ups through :func:`capture`)."""
    import consistency as CB

    make = (lambda: capture(setup, seed, frames)) if setup in PAIRS else None
    return CB.sequence(setup, seed, frames, work, make=make)


def seg_dist(p, a, b) -> float:
    """Distance from ``p`` to the segment [a, b]."""
    ab = b - a
    den = float(ab @ ab)
    t = 0.0 if den == 0 else float(np.clip((p - a) @ ab / den, 0.0, 1.0))
    return float(np.linalg.norm(p - (a + t * ab)))


def depths(points, cameras, dts) -> np.ndarray:
    """(n_points, n_cams) px inside each silhouette (its distance transform; 0 outside or out of
    the image)."""
    out = np.zeros((len(points), len(cameras)))
    for c, (cam, dt) in enumerate(zip(cameras, dts)):
        uv = cam.project(np.asarray(points, float))
        for i, (u, v) in enumerate(uv):
            if not np.isfinite(u + v):
                continue
            x, y = int(round(u)), int(round(v))
            if 0 <= y < dt.shape[0] and 0 <= x < dt.shape[1]:
                out[i, c] = dt[y, x]
    return out


def part_mechanism(ours, curve, seg, true_pt, cameras, dts, tol) -> dict:
    """The tests of the module docstring for one wrong part."""
    a, b = (np.asarray(x, float) for x in seg)
    ours = np.asarray(ours, float)
    row = {"error": round(seg_dist(ours, a, b), 4)}
    if curve is not None:
        c = np.asarray(curve, float)
        d = np.array([seg_dist(q, a, b) for q in c])
        k = int(np.argmin(d))
        s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(c, axis=0), axis=1))])
        row["beyond"] = bool(d[k] <= tol and k < len(c) - 1)
        row["extension"] = round(float(s[-1] - s[k]), 4)
    else:
        row["beyond"] = None
    dep = depths([ours, true_pt], cameras, dts)
    row["depth_ours"] = dep[0].round(1).tolist()
    row["depth_true"] = dep[1].round(1).tolist()
    row["phantom"] = bool((dep[0] >= INTERIOR).sum() >= 2)
    e = ours - np.asarray(true_pt, float)
    en = e / max(np.linalg.norm(e), 1e-9)
    ang, px = [], []
    for cam in cameras:
        r = ours - cam.center
        r /= np.linalg.norm(r)
        ang.append(float(np.degrees(np.arccos(min(1.0, abs(float(r @ en)))))))
        uv = cam.project(np.stack([ours, np.asarray(true_pt, float)]))
        px.append(float(np.linalg.norm(uv[0] - uv[1])))
    row["ray_angle"] = np.round(ang, 1).tolist()
    row["px_error"] = np.round(px, 1).tolist()
    bg = [i for i in range(len(cameras)) if dep[1, i] <= BORDER]
    row["aligned"] = bool(bg) and all(ang[i] <= RAY_ANGLE for i in bg)
    row["n_background"] = len(bg)
    return row


#: the ground truth's bones of a limb before its end part (MakeHuman rig names, gt.json joints)
LIMB_BONES = {"hand": ("Arm", "ForeArm"), "foot": ("UpLeg", "Leg"), "head": ("Neck", "Neck1")}


def limb_bones(g, gp) -> list:
    """The bones of ``gp``'s limb (its side: the rig's hand or foot nearer the part)."""
    stem = gp.split("_")[0]
    if stem not in LIMB_BONES:
        return []
    if stem == "head":
        return list(LIMB_BONES["head"])
    end = {"hand": "Hand", "foot": "Foot"}[stem]
    x = np.asarray(g["parts"][gp], float)
    side = min(("Left", "Right"), key=lambda sd: min(
        np.linalg.norm(x - np.asarray(g["joints"][f"{sd}{end}_{e}"], float))
        for e in ("head", "tail")))
    return [side + b for b in LIMB_BONES[stem]]


def diagnose(setup, seed, frames, work, model, up) -> list:
    """Rows (one per wrong part of a wrong frame, or one per partial frame) of one sequence."""
    import consistency as CB
    from scipy.ndimage import distance_transform_edt
    from topopose.sequence.chirality import numbered
    from topopose.batch.quality import evaluate

    poses, gt = sequence(setup, seed, frames, work)
    ps = [numbered(p, model) for p in CB.as_run(poses, model, up)]
    judged, _ = CB.judged(ps, model, {})
    passing = {p.frame: p.status == "matched" for p in judged}
    tol = CB.TOLERANCE * float(gt["height"])
    ev = evaluate(gt, ps, model=model, tolerance=tol, junction_factor=1.0)
    cap = capture(setup, seed, frames)
    cameras = list(cap.cameras)
    rows = []
    for p, fs in zip(ps, ev.frames):
        if fs.quality in CB.TP_CLASSES:
            continue
        base = {"setup": setup, "seed": seed, "frame": p.frame, "quality": fs.quality,
                "status": p.status, "consistency": passing[p.frame]}
        if fs.quality in ("partial", "none"):
            rows.append({**base, "part": None, "kind": fs.quality})
            continue
        dts = [distance_transform_edt(m) for m in cap.silhouettes(p.frame)]
        g = gt["frames"][p.frame]
        for part, ok in fs.right.items():
            if ok is not False:
                continue
            gp = fs.assignment[part]
            row = {**base, "part": part, "stem": part.split("_")[0]}
            row.update(part_mechanism(p.parts[part], p.diagnostics.get("curves", {}).get(part),
                                      g["segments"][gp], g["parts"][gp], cameras, dts, tol))
            others = [q for q in g["segments"] if q != gp
                      and seg_dist(np.asarray(p.parts[part], float),
                                   *(np.asarray(x, float) for x in g["segments"][q])) <= tol]
            row["swap"] = others[0] if others else None
            x = np.asarray(p.parts[part], float)
            row["short"] = any(seg_dist(x, *(np.asarray(g["joints"][f"{b}_{e}"], float)
                                             for e in ("head", "tail"))) <= tol
                               for b in limb_bones(g, gp))
            if row["beyond"] and row["phantom"] and row["aligned"]:
                row["kind"] = "phantom extension"
            elif row["beyond"]:
                row["kind"] = "beyond (other)"
            elif others:
                row["kind"] = "swap"
            elif row["short"]:
                row["kind"] = "short"
            else:
                row["kind"] = "other"
            rows.append(row)
    tp = [f.quality in CB.TP_CLASSES for f in ev.frames]
    counts = {"frames": len(ps), "right": sum(tp),
              "matched": sum(p.status == "matched" for p in ps),
              "right_matched": sum(t and p.status == "matched" for t, p in zip(tp, ps)),
              "passing": sum(passing.values()),
              "right_passing": sum(t and passing[p.frame] for t, p in zip(tp, ps))}
    return rows, counts


def summary(rows) -> dict:
    """Per part stem: counts of the kinds and of each test."""
    out = {}
    for r in rows:
        k = r.get("stem") or r["kind"]
        s = out.setdefault(k, {"n": 0, "kinds": {}, "beyond": 0, "phantom": 0, "aligned": 0,
                               "error": []})
        s["n"] += 1
        s["kinds"][r["kind"]] = s["kinds"].get(r["kind"], 0) + 1
        for t in ("beyond", "phantom", "aligned"):
            s[t] += bool(r.get(t))
        if "error" in r:
            s["error"].append(r["error"])
    for s in out.values():
        e = s.pop("error")
        s["error_median"] = round(float(np.median(e)), 3) if e else None
    return out


def frame_kinds(rows) -> dict:
    """Wrong frames: by status, and how many hold a wrong part of each kind."""
    frames = {}
    for r in rows:
        f = frames.setdefault((r["seed"], r["frame"]), {"status": r["status"], "kinds": set(),
                                                         "passing": r["consistency"]})
        f["kinds"].add(r["kind"])
    out = {"all": {}, "kinds": {}, "passing": {}}
    for f in frames.values():
        out["all"][f["status"]] = out["all"].get(f["status"], 0) + 1
        for k in f["kinds"]:
            out["kinds"][k] = out["kinds"].get(k, 0) + 1
            if f["passing"]:
                out["passing"][k] = out["passing"].get(k, 0) + 1
    return out


def effect(setups, seeds, frames, work) -> dict:
    """Per set-up: counts without → with the trim (module docstring)."""
    import consistency as CB
    from topopose.pose.model import load_model

    model = load_model("human")
    up = np.array([0.0, 0.0, 1.0])
    out = {}
    for setup in setups:
        tot = {}
        for seed in seeds:
            poses, gt = sequence(setup, seed, frames, work)
            for key, trim in (("without", False), ("with", True)):
                ps = CB.as_run(poses, model, up, trim=trim)
                r = CB.right_frames(ps, gt, model)
                js, _ = CB.judged(ps, model, {})
                row = {"frames": len(ps), "right": sum(r),
                       "trimmed": sum(bool(p.diagnostics.get("trimmed")) for p in ps),
                       "matched": sum(p.status == "matched" for p in ps),
                       "right_matched": sum(a and p.status == "matched" for a, p in zip(r, ps)),
                       "passing": sum(p.status == "matched" for p in js),
                       "right_passing": sum(a and p.status == "matched" for a, p in zip(r, js))}
                d = tot.setdefault(key, {})
                for k, v in row.items():
                    d[k] = d.get(k, 0) + v
            print(f"{setup} seed {seed}: {tot}", file=sys.stderr, flush=True)
        out[setup] = tot
    return out


def effect_report(doc) -> str:
    def pr(d, a, b):
        return f"{d[a]}/{d[b]}" + (f" ({d[a] / d[b]:.1%})" if d[b] else "")
    L = [f"# The hands' trim out of the hull's phantom volume: {doc['label']} seeds", "",
         f"{doc['machine_line']}. Written by `studies/phantom.py --effect`; seeds "
         f"{', '.join(map(str, doc['seeds']))}, {doc['frames']} frames each, the `body` walks of "
         "`benchmarks/consistency.py` (set-ups 4, 4p: even ring; 4r: the real recording's two "
         "facing pairs, `synth.camera_ring` layout \"pairs\"; 8: 8 cameras), poses as the run "
         "writes them (sequence stages on), without → with the trim (`topopose.frame.trim`).", "",
         "| set-up | frames | frames trimmed | right (TP of the quality classes) | matched: right / all | "
         "`--consistency` passing: right / all |", "|---|---|---|---|---|---|"]
    for setup, d in doc["setups"].items():
        a, b = d["without"], d["with"]
        L.append(f"| {setup} | {a['frames']} | {b['trimmed']} | {a['right']} → {b['right']} | "
                 f"{pr(a, 'right_matched', 'matched')} → {pr(b, 'right_matched', 'matched')} | "
                 f"{pr(a, 'right_passing', 'passing')} → {pr(b, 'right_passing', 'passing')} |")
    return "\n".join(L) + "\n"


def main(argv=None):
    from _machine import machine, machine_line
    from topopose.pose.model import load_model

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--setups", default="4,4p")
    ap.add_argument("--seeds", default="41,42,43,44")
    ap.add_argument("--frames", type=int, default=40)
    ap.add_argument("--work", default=None, help="cache of the per-frame poses (consistency.py's)")
    ap.add_argument("--out", default=str(HERE / "results" / "phantom"))
    ap.add_argument("--effect", action="store_true", help="the trim's effect (module docstring)")
    ap.add_argument("--label", default="development")
    a = ap.parse_args(argv)
    if a.effect:
        seeds = [int(s) for s in a.seeds.split(",")]
        mach = machine()
        doc = {"machine": mach, "machine_line": machine_line(mach), "label": a.label,
               "seeds": seeds, "frames": a.frames,
               "setups": effect(a.setups.split(","), seeds, a.frames, a.work)}
        out = HERE / "results" / f"phantom_trim_{a.label}"
        out.with_suffix(".json").write_text(json.dumps(doc, indent=1))
        txt = effect_report(doc)
        out.with_suffix(".md").write_text(txt)
        print(txt)
        return 0
    model = load_model("human")
    up = np.array([0.0, 0.0, 1.0])
    seeds = [int(s) for s in a.seeds.split(",")]
    doc = {"machine": machine(), "seeds": seeds, "setups": {}}
    for setup in a.setups.split(","):
        rows, counts = [], {}
        for seed in seeds:
            r, c = diagnose(setup, seed, a.frames, a.work, model, up)
            rows += r
            counts = {k: counts.get(k, 0) + v for k, v in c.items()}
            print(f"{setup} seed {seed}: {c}, {len(r)} wrong rows", file=sys.stderr, flush=True)
        doc["setups"][setup] = {**counts, "rows": rows, "summary": summary(rows),
                                "frame_kinds": frame_kinds(rows),
                                "summary_passing": summary([r for r in rows
                                                            if r["consistency"]])}
    out = Path(a.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.with_suffix(".json").write_text(json.dumps(doc, separators=(",", ":")))   # compact rows
    L = ["# Why the 4-camera synthetic walks are wrong: the phantom extension", "",
         f"{machine_line(doc['machine'])}. Written by `studies/phantom.py`; development "
         f"seeds {', '.join(map(str, seeds))}, {a.frames} frames each, poses as the run writes "
         "them (sequence stages on, consistency off).", "",
         f"Tests (module docstring): beyond = the curve passes within the tolerance of the "
         f"truth before its end; phantom = ≥ {INTERIOR:g} px inside ≥ 2 silhouettes; aligned = "
         f"the error within {RAY_ANGLE:g}° of the rays of every camera that sees the true part "
         f"against the background (≤ {BORDER:g} px inside).", ""]
    for setup, d in doc["setups"].items():
        L += [f"## Set-up {setup}: {d['right']} right of {d['frames']} frames; matched (gate) "
              f"{d['right_matched']} right of {d['matched']}, passing `--consistency` "
              f"{d['right_passing']} right of {d['passing']}", "",
              "| wrong part | n | phantom extension | beyond (other) | swap | short | other | "
              "beyond | phantom | aligned | median error (m) |",
              "|---|---|---|---|---|---|---|---|---|---|---|"]
        for k, s in sorted(d["summary"].items(), key=lambda kv: -kv[1]["n"]):
            kd = s["kinds"]
            L.append(f"| {k} | {s['n']} | {kd.get('phantom extension', 0)} | "
                     f"{kd.get('beyond (other)', 0)} | {kd.get('swap', 0)} | "
                     f"{kd.get('short', 0)} | {kd.get('other', 0)} | {s['beyond']} | "
                     f"{s['phantom']} | {s['aligned']} | "
                     f"{s['error_median'] if s['error_median'] is not None else '–'} |")
        fk = frame_kinds(d["rows"])
        L += ["", f"Wrong frames ({sum(fk['all'].values())}) by status "
              f"({', '.join(f'{k} {v}' for k, v in sorted(fk['all'].items()))}); frames with at "
              "least one wrong part of a kind: "
              + ", ".join(f"{k} {v}" for k, v in sorted(fk["kinds"].items(), key=lambda kv: -kv[1]))
              + "; of the wrong frames passing `--consistency`: "
              + (", ".join(f"{k} {v}" for k, v in fk["passing"].items()) or "none") + ".", ""]
    out.with_suffix(".md").write_text("\n".join(L) + "\n")
    print("\n".join(L))
    return 0


if __name__ == "__main__":
    sys.exit(main())
