"""The full skeleton's systematic error per joint on the development sequences: signed
bias in the truth's body frame and along the true bone, and the tips (fingertips, toes) taken
apart, with and without :func:`~topopose.sequence.kinematic_fit.tip_targets`.

    python studies/joint_bias.py [--work DIR] [--frames 40] [--out benchmarks/results]

Development sequences only (``tracking.py``'s ``DEV_SEQUENCES``: random poses seeds 21–32, walks
41–46; ``body`` subject, 100³, 8 cameras, noise 1, confidence gate on): the per-frame result is
run once per sequence and kept in ``--work`` (``poses.jsonl`` beside the capture), so a re-run
measures the sequence stage alone. Per joint (mirror limbs paired with the truth's Left/Right
by the smaller total error over the limb's four joints), split by whether the frame saw the
limb (``held_joints``: an unseen limb's joints are guesses) and, for arms, the true arm's kind
(raised / bent / straight, as ``tracking.py``):

* error (median distance), signed bias (median) outward / forward / up in the truth's body
  frame (hips' line across, the capture's up), and along the true bone from the parent joint;
* the bone from the parent, ours / the rig's (median ratio) and the angle between them;
* the tips (seen limbs): error along the true tip bone (wrist → fingertip, ankle → toe), across
  it towards up and sideways; the tip bone's length ratio; its pitch and yaw against the true
  one; the bend at the parent joint (the angle between the bone above and the tip bone), ours
  minus the truth's — for the fit, the fit without the tips' correction and the initial
  placement (:func:`~topopose.sequence.kinematic_fit.initial_placement`, before the correction).

Writes ``joint_bias_dev.md`` and ``joint_bias_dev.json`` (the medians per group).
"""
import argparse
import json
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
sys.path.insert(1, str(Path(__file__).resolve().parents[1] / "benchmarks"))  # the benchmarks a study builds on
from _machine import machine, machine_line  # noqa: E402
from tracking import DEV_SEQUENCES, fit_without_tips, make_sequence  # noqa: E402

from topopose.capture import load_capture  # noqa: E402
from topopose.batch import run  # noqa: E402
from topopose.sequence.kinematic_fit import fit_sequence, initial_placement  # noqa: E402
from topopose.pose.model import load_model  # noqa: E402
from topopose.pose.pose import read_poses  # noqa: E402
from topopose.sequence.track import track  # noqa: E402

# limb → (our joint base, the rig's name: side + this, or a tip vertex prefix + l/r)
LIMBS = {"arm": (("shoulder", "Arm_head"), ("elbow", "ForeArm_head"), ("wrist", "Hand_head"),
                 ("fingertip", "fingertip_")),
         "leg": (("hip", "UpLeg_head"), ("knee", "Leg_head"), ("ankle", "Foot_head"),
                 ("toe", "toe_"))}
TRUNK = (("neck", "Neck_head"), ("skull", "Head_head"), ("pelvis", None))


def rig_name(side, r):
    """The rig joint of ``r`` on ``side`` (Left/Right): ``LeftForeArm_head``, ``fingertip_l``."""
    return r + side[0].lower() if r.endswith("_") else side + r


def body_axes(J, up):
    """The truth's body frame: across (right → left hip, ⊥ up), forward, up."""
    up = np.asarray(up, float) / np.linalg.norm(up)
    lat = J["LeftUpLeg_head"] - J["RightUpLeg_head"]
    lat = lat - np.dot(lat, up) * up
    lat /= np.linalg.norm(lat)
    return lat, np.cross(lat, up), up


def _angle(u, v):
    return float(np.degrees(np.arccos(np.clip(np.dot(u, v) / max(
        np.linalg.norm(u) * np.linalg.norm(v), 1e-12), -1.0, 1.0))))


def frame_rows(names, P, J, up, held, motion):
    """One frame's rows: a dict per placed joint (limb joints paired with the truth's sides)."""
    lat, fwd, up = body_axes(J, up)
    ix = {n: i for i, n in enumerate(names)}
    rows = []
    for base, r in TRUNK:
        if base not in ix:
            continue
        t = J[r] if r else 0.5 * (J["LeftUpLeg_head"] + J["RightUpLeg_head"])
        e = P[ix[base]] - t
        rows.append({"motion": motion, "joint": base, "seen": True, "kind": "trunk",
                     "err": float(np.linalg.norm(e)),
                     "bias": [float(e @ lat), float(e @ fwd), float(e @ up)]})
    for limb, joints in LIMBS.items():
        ks = sorted({n.rpartition("_")[2] for n in names if n.startswith(joints[1][0] + "_")})
        if len(ks) != 2:
            continue

        def total(k, side):
            return sum(np.linalg.norm(P[ix[f"{b}_{k}"]] - J[rig_name(side, r)]) for b, r in joints)
        sides = ("Left", "Right") if total(ks[0], "Left") + total(ks[1], "Right") <= \
            total(ks[0], "Right") + total(ks[1], "Left") else ("Right", "Left")
        for k, side in zip(ks, sides):
            sg = 1.0 if side == "Left" else -1.0
            seen = not any(f"{b}_{k}" in held for b, _ in joints)
            T = [J[rig_name(side, r)] for _, r in joints]
            O = [P[ix[f"{b}_{k}"]] for b, _ in joints]
            kind = "seen" if seen else "held"
            if limb == "arm" and seen:
                s, e, w = T[:3]
                kind = "raised" if np.dot(w - s, up) > 0 else (
                    "bent" if _angle(s - e, w - e) < 135 else "straight")
            for i, (b, _) in enumerate(joints):
                e = O[i] - T[i]
                row = {"motion": motion, "joint": b, "seen": seen, "kind": kind,
                       "err": float(np.linalg.norm(e)),
                       "bias": [float(e @ lat) * sg, float(e @ fwd), float(e @ up)]}
                if i > 0:
                    bt, bo = T[i] - T[i - 1], O[i] - O[i - 1]
                    row.update(along=float(e @ bt / np.linalg.norm(bt)),
                               ratio=float(np.linalg.norm(bo) / np.linalg.norm(bt)),
                               bone_angle=_angle(bo, bt))
                rows.append(row)
    return rows


def tip_rows(names, P, J, up, held, motion, key):
    """The seen tips of one frame taken apart (see the module docstring)."""
    up = np.asarray(up, float) / np.linalg.norm(up)
    ix = {n: i for i, n in enumerate(names)}
    out = []
    for base, par, gpar, r_tip, r_par, r_gpar in (
            ("fingertip", "wrist", "elbow", "fingertip_", "Hand_head", "ForeArm_head"),
            ("toe", "ankle", "knee", "toe_", "Foot_head", "Leg_head")):
        for k in ("1", "2"):
            n = f"{base}_{k}"
            if n not in ix or n in held or np.isnan(P[[ix[n], ix[f"{par}_{k}"],
                                                        ix[f"{gpar}_{k}"]]]).any():
                continue
            x, a, g = P[ix[n]], P[ix[f"{par}_{k}"]], P[ix[f"{gpar}_{k}"]]
            side = min(("Left", "Right"), key=lambda s: np.linalg.norm(x - J[rig_name(s, r_tip)]))
            t, ta, tg = J[rig_name(side, r_tip)], J[side + r_par], J[side + r_gpar]
            d = (t - ta) / np.linalg.norm(t - ta)
            u = up - np.dot(up, d) * d
            u /= np.linalg.norm(u)
            lat = np.cross(d, u)
            e, seg = x - t, x - a
            out.append({"motion": motion, "tip": base, "key": key, "err": float(np.linalg.norm(e)),
                        "along": float(e @ d), "up": float(e @ u), "side": float(e @ lat),
                        "ratio": float(np.linalg.norm(seg) / np.linalg.norm(t - ta)),
                        "pitch": float(np.degrees(np.arctan2(seg @ u, seg @ d))),
                        "yaw": float(np.degrees(np.arctan2(seg @ lat, seg @ d))),
                        "bend": _angle(a - g, seg) - _angle(ta - tg, t - ta)})
    return out


def sequence(work, motion, seed, build, frames, model):
    """Rows of one development sequence (the per-frame result cached in its capture folder)."""
    d = make_sequence(work, motion, seed, build, frames)
    cap = load_capture(d)
    if not (d / "poses.jsonl").exists() or not (d / "poses.done").exists():
        run(cap, model=model, resolution=100, output=d / "poses.jsonl", progress=False,
            track=False, sides=False, skeleton=False, gate=True)
        (d / "poses.done").write_text("")
    tracked = track(read_poses(d / "poses.jsonl"), model)
    fitted, tree, _ = fit_sequence(tracked, model)
    bare, _, _ = fit_without_tips(tracked, model)
    rows, tips, frames_err = [], [], []
    for p, q in zip(fitted, bare):
        if not (p.matched and p.joints) or p.diagnostics.get("interpolated"):
            continue
        J = {k: np.asarray(v, float) for k, v in cap.gt["frames"][p.frame]["joints"].items()}
        held = p.diagnostics.get("held_joints") or []
        P = np.array([p.joints[n] for n in tree.names])
        rows += frame_rows(tree.names, P, J, cap.up_vector, held, motion)
        for key, Q in (("fit", P), ("fit without tip_targets", np.array(
                [q.joints[n] for n in tree.names]) if q.joints else None),
                       ("initial placement", initial_placement(p, tree))):
            if Q is not None:
                tips += tip_rows(tree.names, Q, J, cap.up_vector, held, motion, key)
    return rows, tips


def _m(xs, scale=100.0, fmt="{:+.1f}"):
    xs = [x for x in xs if x is not None and not np.isnan(x)]
    return fmt.format(scale * float(np.median(xs))) if xs else "–"


def report(rows, tips, info, seqs) -> str:
    L = ["# The full skeleton's systematic error per joint (development sequences)", "",
         machine_line(info) + ". Written by `studies/joint_bias.py`; `body` subject, 100³, 8 "
         "cameras, noise 1, confidence gate on; development sequences only: "
         + ", ".join(f"{m} {s}" for m, s, _ in seqs) + ".", "",
         "Per joint, median over joints × frames (cm): error; signed bias in the truth's body "
         "frame (*out*: outward from the midline for a mirror joint, towards the left for "
         "neck/skull/pelvis; *fwd*; *up*); *along*: along the true bone from its parent; the "
         "bone from the parent, ours / the rig's, and the angle between the two (degrees). "
         "*seen*: the frame saw the limb; *held*: a guess (rest pose, last frame, hints).", ""]
    L += ["| motion | joint | limb | n | error | out | fwd | up | along | bone ratio | "
          "bone angle |", "|---|---|---|---|---|---|---|---|---|---|---|"]
    order = ["neck", "skull", "pelvis", "shoulder", "elbow", "wrist", "fingertip", "hip", "knee",
             "ankle", "toe"]
    for motion in ("walk", "random"):
        for j in order:
            for kinds in (("trunk",), ("seen", "raised", "bent", "straight"), ("held",)):
                g = [r for r in rows if r["motion"] == motion and r["joint"] == j
                     and r["kind"] in kinds]
                if not g:
                    continue
                b = np.median([r["bias"] for r in g], axis=0) * 100
                limb = "held" if kinds[0] == "held" else "seen"
                L.append(f"| {motion} | {j} | {limb} | {len(g)} "
                         f"| {_m([r['err'] for r in g], fmt='{:.1f}')} | {b[0]:+.1f} | "
                         f"{b[1]:+.1f} | {b[2]:+.1f} | {_m([r.get('along') for r in g])} | "
                         f"{_m([r.get('ratio') for r in g], 1, '{:.2f}')} | "
                         f"{_m([r.get('bone_angle') for r in g], 1, '{:.0f}')} |")
    L += ["", "Seen arms by the true arm's kind (raised: wrist above the shoulder; bent: elbow "
          "angle < 135°):", "",
          "| motion | joint | kind | n | error | out | fwd | up | along |",
          "|---|---|---|---|---|---|---|---|---|"]
    for motion in ("walk", "random"):
        for j in ("shoulder", "elbow", "wrist", "fingertip"):
            for kind in ("raised", "bent", "straight"):
                g = [r for r in rows
                     if r["motion"] == motion and r["joint"] == j and r["kind"] == kind]
                if g:
                    b = np.median([r["bias"] for r in g], axis=0) * 100
                    L.append(f"| {motion} | {j} | {kind} | {len(g)} | "
                             f"{_m([r['err'] for r in g], fmt='{:.1f}')} | {b[0]:+.1f} | "
                             f"{b[1]:+.1f} | {b[2]:+.1f} | {_m([r.get('along') for r in g])} |")
    L += ["", "Seen tips taken apart (median; cm and degrees): error along the true tip bone "
          "(wrist → fingertip, ankle → toe), across it towards up and sideways; the tip bone's "
          "length ours / the rig's; its pitch (towards up) and yaw against the true one; the bend "
          "at its parent (elbow → wrist → fingertip, knee → ankle → toe), ours minus the truth's; "
          "the initial placement is the tips' targets before `tip_targets`.",
          "", "| motion | tip | placement | n | error | along | up | side | length ratio | pitch "
          "| yaw | bend |", "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for motion in ("walk", "random"):
        for tip in ("fingertip", "toe"):
            for key in ("fit", "fit without tip_targets", "initial placement"):
                g = [r for r in tips
                     if r["motion"] == motion and r["tip"] == tip and r["key"] == key]
                if g:
                    L.append(f"| {motion} | {tip} | {key} | {len(g)} | "
                             f"{_m([r['err'] for r in g], fmt='{:.1f}')} | "
                             f"{_m([r['along'] for r in g])} | {_m([r['up'] for r in g])} | "
                             f"{_m([r['side'] for r in g])} | "
                             f"{_m([r['ratio'] for r in g], 1, '{:.2f}')} | "
                             f"{_m([r['pitch'] for r in g], 1, '{:+.0f}')} | "
                             f"{_m([r['yaw'] for r in g], 1, '{:+.0f}')} | "
                             f"{_m([r['bend'] for r in g], 1, '{:+.0f}')} |")
    return "\n".join(L) + "\n"


def summary(rows, tips) -> dict:
    """Medians per (motion, joint, kind) and per (motion, tip, placement), for the JSON."""
    out = {"joints": [], "tips": []}
    groups = {}
    for r in rows:
        groups.setdefault((r["motion"], r["joint"], r["kind"]), []).append(r)
    for (motion, joint, kind), g in sorted(groups.items()):
        d = {"motion": motion, "joint": joint, "kind": kind, "n": len(g),
             "error": float(np.median([r["err"] for r in g])),
             "bias_out_fwd_up": [float(x) for x in np.median([r["bias"] for r in g], axis=0)]}
        for k in ("along", "ratio", "bone_angle"):
            v = [r[k] for r in g if k in r]
            if v:
                d[k] = float(np.median(v))
        out["joints"].append(d)
    groups = {}
    for r in tips:
        groups.setdefault((r["motion"], r["tip"], r["key"]), []).append(r)
    for (motion, tip, key), g in sorted(groups.items()):
        out["tips"].append({"motion": motion, "tip": tip, "placement": key, "n": len(g),
                            **{k: float(np.median([r[k] for r in g]))
                               for k in ("err", "along", "up", "side", "ratio", "pitch", "yaw",
                                         "bend")}})
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--work", default=None, help="captures and per-frame results (kept)")
    ap.add_argument("--frames", type=int, default=40)
    ap.add_argument("--out", default=str(Path(__file__).parent / "results"))
    a = ap.parse_args(argv)
    model = load_model("human")
    work = a.work or tempfile.mkdtemp(prefix="topopose_joint_bias_")
    rows, tips = [], []
    for motion, seed, build in DEV_SEQUENCES:
        r, t = sequence(work, motion, seed, build, a.frames, model)
        rows += r
        tips += t
        print(motion, seed, build, len(r), flush=True)
    info = machine(resolution=100, cameras=8, noise=1, subject="body", confidence_gate=True,
                   frames=a.frames)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    text = report(rows, tips, info, DEV_SEQUENCES)
    (out / "joint_bias_dev.md").write_text(text)
    (out / "joint_bias_dev.json").write_text(json.dumps({"machine": info, **summary(rows, tips)},
                                                        indent=1))
    print(text)


if __name__ == "__main__":
    main()
