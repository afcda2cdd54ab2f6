"""Development study: where random motion's joint error comes from, per joint and per
situation (trunk bent, arm raised / bent / straight / lost), with signed biases in the truth's
*trunk* frame, on the development sequences of ``benchmarks/tracking.py`` (walks 41–46, random
motion 51–56, unrelated random poses 21–32) — the per-frame results cached by
``studies/held_dev.py`` (``--work``), the tracking cached beside them, only the skeleton's
fit re-run per variant (seconds per sequence).

    python studies/motion_dev.py --work DIR [--only random-smooth] [--variants base,...]
                                    [--out benchmarks/results]

Per variant and motion: MPJPE median over the pooled matched frames (``tracking.py``'s figure)
and per joint (median error over joints × frames). Per situation: the trunk's true tilt from
the capture's up (hip centre → neck; < 20°, 20–45°, > 45°), each arm seen raised (wrist above
the shoulder along the true trunk), bent (elbow < 135°), straight, or lost (its joints held).
Signed biases: *out* (outward from the midline for a mirror joint, towards the left for the
neck), *fwd*, *up* along the true trunk (hip centre → neck), and along the true bone. Never the
held-out seeds. Writes ``motion_dev.md`` / ``.json`` when every motion and the base variant run
(``results/motion_dev.md``: ``--variants before,age8,smooth9_ageNone,smooth9_None,base``).
Variants: ``base`` kinematic_fit's defaults; ``before`` without ``HOLD_AGE`` and smoothing (the
earlier defaults); ``ageN`` ``HOLD_AGE`` N without smoothing; ``smoothW_M`` window W,
``SMOOTH_MOVE`` M (None: no move check); ``smooth9_ageN``; ``hold0``, ``noev``, ``noshoulder``,
``age8_nohint``; and ``held_dev.py``'s.
"""
import argparse
import json
import pickle
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
sys.path.insert(1, str(Path(__file__).resolve().parents[1] / "benchmarks"))  # the benchmarks a study builds on
import held_dev as H  # noqa: E402
import tracking as T  # noqa: E402
from _machine import machine, machine_line  # noqa: E402

from topopose.capture import load_capture  # noqa: E402
from topopose.pose.model import load_model  # noqa: E402
from topopose.sequence.track import track  # noqa: E402

ARM = (("shoulder", "Arm_head"), ("elbow", "ForeArm_head"), ("wrist", "Hand_head"),
       ("fingertip", None))
LEG = (("hip", "UpLeg_head"), ("knee", "Leg_head"), ("ankle", "Foot_head"), ("toe", None))
VARIANTS = dict(H.VARIANTS)
# "before": the earlier defaults (no HOLD_AGE, no smoothing); the others on top of
# the current defaults unless they set these two themselves
VARIANTS["before"] = H._with(hold_age=None, smooth=0)
VARIANTS["hold0"] = H._with(hold_frames=0, hold_age=None, smooth=0)
VARIANTS["noev"] = H._with(evidence=False, hold_age=None, smooth=0)
VARIANTS["noshoulder"] = H._with(shoulders=False, hold_age=None, smooth=0)
for _a in (1, 3, 5, 8, 12):
    VARIANTS[f"age{_a}"] = H._with(hold_age=_a, smooth=0)
VARIANTS["age8_nohint"] = H._with(hold_age=8, hints=False, smooth=0)
for _w in (5, 7, 9, 11, 13):
    for _m in (None, 0.1, 0.15, 0.25):
        VARIANTS[f"smooth{_w}_{_m}"] = H._with(smooth=_w, move=_m)
for _a in (None, 5, 12):
    VARIANTS[f"smooth9_age{_a}"] = H._with(hold_age=_a)


def tracked_sequence(work, motion, seed, build, model):
    """(capture folder, tracked poses, ground truth) of one development sequence, cached."""
    n = {"walk": 40}.get(motion, 60)
    d, raw = H.frames(work, motion, seed, build, n, model)
    f = d / "tracked.pkl"
    if not f.exists():
        f.write_bytes(pickle.dumps(track(raw, model)))
    return d, pickle.loads(f.read_bytes()), load_capture(d)


def trunk_axes(J, up):
    """The truth's trunk frame: across (right → left hip, ⊥ the trunk), forward, up along the
    trunk (hip centre → neck); and the trunk's tilt from the capture's ``up`` (degrees)."""
    hc = 0.5 * (J["LeftUpLeg_head"] + J["RightUpLeg_head"])
    ax = J["Neck_head"] - hc
    ax /= np.linalg.norm(ax)
    lat = J["LeftUpLeg_head"] - J["RightUpLeg_head"]
    lat = lat - np.dot(lat, ax) * ax
    lat /= np.linalg.norm(lat)
    up = np.asarray(up, float) / np.linalg.norm(up)
    tilt = float(np.degrees(np.arccos(np.clip(np.dot(ax, up), -1, 1))))
    return lat, np.cross(lat, ax), ax, tilt


def _angle(u, v):
    return float(np.degrees(np.arccos(np.clip(np.dot(u, v) / max(
        np.linalg.norm(u) * np.linalg.norm(v), 1e-12), -1.0, 1.0))))


def frame_rows(names, P, J, up, held, motion, seed, frame):
    """One frame's rows: a dict per joint of the MPJPE (plus skull, pelvis, tips), mirror limbs
    paired with the truth's sides by the smaller total error over the limb."""
    lat, fwd, ax, tilt = trunk_axes(J, up)
    tb = "upright" if tilt < 20 else ("leaning" if tilt < 45 else "bent")
    ix = {n: i for i, n in enumerate(names)}
    hc = 0.5 * (J["LeftUpLeg_head"] + J["RightUpLeg_head"])
    rows = []
    base = {"motion": motion, "seed": seed, "frame": frame, "tilt": tb, "lost": bool(held)}
    for j, t in (("neck", J["Neck_head"]), ("skull", J["Head_head"]), ("pelvis", hc)):
        e = P[ix[j]] - t
        rows.append({**base, "joint": j, "kind": "trunk", "err": float(np.linalg.norm(e)),
                     "bias": [float(e @ lat), float(e @ fwd), float(e @ ax)]})
    for limb, joints in (("arm", ARM), ("leg", LEG)):
        tip = "fingertip_" if limb == "arm" else "toe_"

        def rig(side, i):
            r = joints[i][1]
            return J[side + r] if r else J[tip + side[0].lower()]
        ks = ("1", "2")

        def total(k, side):
            return sum(np.linalg.norm(P[ix[f"{b}_{k}"]] - rig(side, i))
                       for i, (b, _) in enumerate(joints))
        sides = ("Left", "Right") if total("1", "Left") + total("2", "Right") <= \
            total("1", "Right") + total("2", "Left") else ("Right", "Left")
        for k, side in zip(ks, sides):
            sg = 1.0 if side == "Left" else -1.0
            T_ = [rig(side, i) for i in range(4)]
            O = [P[ix[f"{b}_{k}"]] for b, _ in joints]
            lost = any(f"{b}_{k}" in held for b, _ in joints)
            s, e, w = T_[:3]
            if lost:
                kind = "lost"
            elif np.dot(w - s, ax) > 0:
                kind = "raised"
            else:
                kind = "bent" if _angle(s - e, w - e) < 135 else "straight"
            for i, (b, _) in enumerate(joints):
                d = O[i] - T_[i]
                row = {**base, "joint": b, "kind": kind, "err": float(np.linalg.norm(d)),
                       "bias": [float(d @ lat) * sg, float(d @ fwd), float(d @ ax)]}
                if i > 0:
                    bt = T_[i] - T_[i - 1]
                    row["along"] = float(d @ bt / np.linalg.norm(bt))
                    row["ratio"] = float(np.linalg.norm(O[i] - O[i - 1]) / np.linalg.norm(bt))
                rows.append(row)
    return rows


def run_variant(v, seqs, work, model):
    """(MPJPE per-frame errors by motion, rows) of one variant over ``seqs``."""
    frames, rows = {}, []
    for motion, seed, build in seqs:
        d, tracked, cap = tracked_sequence(work, motion, seed, build, model)
        fitted, tree, _ = VARIANTS[v](tracked, model)
        err, _ = H.score(fitted, tree, cap.gt)
        frames.setdefault(motion, []).extend(T.mpjpe(err)[3])
        frames.setdefault(("seq", motion), []).append(T.mpjpe(err)[0])
        for p in fitted:
            if not (p.matched and p.joints) or p.diagnostics.get("interpolated"):
                continue
            J = {k: np.asarray(x, float) for k, x in cap.gt["frames"][p.frame]["joints"].items()}
            P = np.array([p.joints[n] for n in tree.names])
            rows += frame_rows(tree.names, P, J, cap.up_vector,
                               p.diagnostics.get("held_joints") or [], motion, seed, p.frame)
    return frames, rows


ORDER = ("neck", "skull", "pelvis", "shoulder", "elbow", "wrist", "fingertip", "hip", "knee",
         "ankle", "toe")


def _med(g, k, scale=100.0):
    x = [r[k] for r in g if k in r]
    return scale * float(np.median(x)) if x else float("nan")


def tables(rows, motions):
    """Markdown lines: per joint × situation, error and signed biases."""
    L = ["| motion | joint | situation | n | error | out | fwd | up | along | bone ratio |",
         "|---|---|---|---|---|---|---|---|---|---|"]
    for m in motions:
        for j in ORDER:
            g0 = [r for r in rows if r["motion"] == m and r["joint"] == j]
            groups = [("all", g0)]
            groups += [(f"trunk {t}", [r for r in g0 if r["tilt"] == t])
                       for t in ("upright", "leaning", "bent")]
            if j in ("shoulder", "elbow", "wrist", "fingertip", "hip", "knee", "ankle", "toe"):
                groups += [(k, [r for r in g0 if r["kind"] == k])
                           for k in ("raised", "bent", "straight", "lost")]
            else:
                groups += [("frame holds", [r for r in g0 if r["lost"]]),
                           ("frame sees all", [r for r in g0 if not r["lost"]])]
            for name, g in groups:
                if not g:
                    continue
                b = 100 * np.median([r["bias"] for r in g], axis=0)
                L.append(f"| {m} | {j} | {name} | {len(g)} | {_med(g, 'err'):.1f} | "
                         f"{b[0]:+.1f} | {b[1]:+.1f} | {b[2]:+.1f} | {_med(g, 'along'):+.1f} | "
                         f"{_med(g, 'ratio', 1):.2f} |")
    return L


def share(rows, frames, motions):
    """Markdown lines: each joint's share of the MPJPE (mean over frames of its error / 13)."""
    L = ["| motion | frames | MPJPE median | " + " | ".join(T.MPJPE_JOINTS) + " |",
         "|---|---|---|" + "---|" * len(T.MPJPE_JOINTS)]
    for m in motions:
        g = [r for r in rows if r["motion"] == m]
        med = {j: 100 * np.median([r["err"] for r in g if r["joint"] == j])
               for j in T.MPJPE_JOINTS}
        L.append(f"| {m} | {len(frames[m])} | {100 * np.median(frames[m]):.2f} | "
                 + " | ".join(f"{med[j]:.1f}" for j in T.MPJPE_JOINTS) + " |")
    return L


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--work", required=True)
    ap.add_argument("--only", default=None)
    ap.add_argument("--variants", default="base")
    ap.add_argument("--tables", action="store_true", help="print the situation tables")
    ap.add_argument("--out", default=str(Path(__file__).parent / "results"))
    a = ap.parse_args(argv)
    model = load_model("human")
    seqs = [s for s in T.DEV_SEQUENCES if a.only is None or s[0] in a.only.split(",")]
    motions = [m for m in ("random-smooth", "walk", "random") if any(s[0] == m for s in seqs)]
    out = {}
    for v in a.variants.split(","):
        frames, rows = run_variant(v, seqs, a.work, model)
        out[v] = (frames, rows)
        print(v, " / ".join(f"{m} {100 * np.median(frames[m]):.2f}" for m in motions), flush=True)
        print("   per sequence:", " | ".join(" ".join(f"{100 * x:.2f}" for x in frames[("seq", m)])
                                          for m in motions), flush=True)
        for line in share(rows, frames, motions)[2:]:
            print("   ", line, flush=True)
        if a.tables:
            print("\n".join(tables(rows, motions)), flush=True)
    if "base" in out and a.only is None:
        info = machine(resolution=100, cameras=8, noise=1, subject="body", confidence_gate=True)
        md = ["# Where random motion's joint error comes from (development seeds)", "",
              machine_line(info) + ". Written by `studies/motion_dev.py` on the per-frame "
              "results `held_dev.py` caches (walks 41–46, random motion 51–56, unrelated random "
              "poses 21–32; gate on); the sequence stage re-run per variant: *base* "
              "kinematic_fit's defaults (`HOLD_AGE` 8, `SMOOTH` 9 frames over runs of "
              "continuing motion), *before* the defaults before them (no age limit on a held "
              "joint, no smoothing).", "",
              "MPJPE median over the pooled matched frames, and per joint (median over joints × "
              "frames, cm):", ""]
        for v, (frames, rows) in out.items():
            md += [f"**{v}**", ""] + share(rows, frames, motions) + [""]
        md += ["Per joint and situation (cm, medians over joints × frames): *trunk* the "
               "truth's tilt from up (hip centre → neck: upright < 20°, leaning 20–45°, bent "
               "> 45°); an arm or leg *raised* (its end above its first joint along the true "
               "trunk), *bent* (middle joint < 135°), *straight*, *lost* (held joints); for "
               "neck / skull / pelvis whether the frame holds any joint. Signed bias in the "
               "truth's trunk frame: *out* (outward for a mirror joint, towards the left for "
               "the trunk's joints), *fwd*, *up* (along hip centre → neck); *along* the true "
               "bone from its parent; *bone ratio* ours / the rig's.", ""]
        for v in ("before", "base"):
            if v in out:
                md += [f"**{v}**", ""] + tables(out[v][1], motions) + [""]
        o = Path(a.out)
        (o / "motion_dev.md").write_text("\n".join(md))
        summ = {}
        for v, (frames, rows) in out.items():
            for m in motions:
                g = [r for r in rows if r["motion"] == m]
                summ.setdefault(v, {})[m] = {
                    "mpjpe": float(np.median(frames[m])),
                    "per_sequence": [float(x) for x in frames[("seq", m)]],
                    "joints": {f"{j} {k}": float(np.median([r["err"] for r in g
                                                             if r["joint"] == j
                                                             and r["kind"] == k]))
                               for j, k in sorted({(r["joint"], r["kind"]) for r in g})}}
        (o / "motion_dev.json").write_text(json.dumps({"machine": info, "variants": summ},
                                                      indent=1))


if __name__ == "__main__":
    main()
