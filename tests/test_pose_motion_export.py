"""Exports of a motion: BVH re-read by forward kinematics, TRC and C3D round trips with every
joint and OpenSim marker names."""
import warnings

import numpy as np
import pytest

from topopose.pose.export import (OPENSIM_LABELS, marker_names, read_trc, write_bvh, write_c3d,
                                  write_trc, y_up_rotation)
from topopose.pose.pose import Pose


def _rot(axis, deg):
    a = np.radians(deg)
    c, s = np.cos(a), np.sin(a)
    i, j = [(1, 2), (2, 0), (0, 1)]["XYZ".index(axis)]
    m = np.eye(3)
    m[i, i], m[i, j], m[j, i], m[j, j] = c, -s, s, c
    return m


def parse_bvh(text):
    """A small independent BVH reader: joint names, world positions (n_frames, n_joints, 3)."""
    tok = text.split()
    k = 0
    joints = []            # (name, parent, offset, channels)
    stack = []
    while tok[k] != "MOTION":
        t = tok[k]
        if t in ("ROOT", "JOINT"):
            joints.append([tok[k + 1], stack[-1] if stack else -1, None, []])
            k += 2
        elif t == "End":
            joints.append(["<end>", stack[-1], None, []])
            k += 2
        elif t == "{":
            stack.append(len(joints) - 1)
            k += 1
        elif t == "}":
            stack.pop()
            k += 1
        elif t == "OFFSET":
            joints[stack[-1]][2] = np.array([float(x) for x in tok[k + 1:k + 4]])
            k += 4
        elif t == "CHANNELS":
            nc = int(tok[k + 1])
            joints[stack[-1]][3] = tok[k + 2:k + 2 + nc]
            k += 2 + nc
        else:
            k += 1
    n_frames = int(tok[k + 2])
    k += 6                                  # MOTION Frames: n Frame Time: dt
    vals = np.array([float(x) for x in tok[k:]]).reshape(n_frames, -1)
    names = [j[0] for j in joints if j[0] != "<end>"]
    out = np.zeros((n_frames, len(names), 3))
    for f in range(n_frames):
        col = 0
        pos, rot = {}, {}
        for i, (name, par, off, chans) in enumerate(joints):
            local_t = off.copy()
            local_r = np.eye(3)
            for c in chans:
                v = vals[f, col]
                col += 1
                if c.endswith("position"):
                    local_t["XYZ".index(c[0])] += v
                else:
                    local_r = local_r @ _rot(c[0], v)
            if par < 0:
                pos[i], rot[i] = local_t, local_r
            else:
                pos[i] = pos[par] + rot[par] @ local_t
                rot[i] = rot[par] @ local_r
        out[f] = [pos[i] for i, j in enumerate(joints) if j[0] != "<end>"]
    return names, out


def _chain_motion(n_frames=12, seed=0):
    """A branching skeleton with constant bone lengths moving at random (capture z up)."""
    rng = np.random.default_rng(seed)
    names = ["crotch", "torso", "head", "l_sh", "l_el", "r_sh", "hip", "knee", "ankle"]
    parents = [-1, 0, 1, 1, 3, 1, 0, 6, 7]
    lengths = rng.uniform(0.1, 0.5, len(names))
    P = np.zeros((n_frames, len(names), 3))
    for f in range(n_frames):
        P[f, 0] = rng.normal(size=3)
        for c in range(1, len(names)):
            d = rng.normal(size=3)
            if c == 4 and f == 3:
                d = P[f, 3] - P[f, 1]           # straight on: parallel to the parent bone
            elif c == 7 and f == 4:
                d = -(P[f, 6] - P[f, 0])        # folded back: antiparallel
            P[f, c] = P[f, parents[c]] + lengths[c] * d / np.linalg.norm(d)
    return names, parents, P


def test_bvh_reread_gives_the_same_joint_positions(tmp_path):
    names, parents, P = _chain_motion()
    path = write_bvh(tmp_path / "m.bvh", names, parents, P, fps=30, units="m", up="+z")
    text = path.read_text()
    assert "Zrotation Xrotation Yrotation" in text and "Frame Time: 0.033333333" in text
    got_names, Q = parse_bvh(text)
    idx = [got_names.index(n) for n in names]            # helper joints are extra nodes
    expect = P @ y_up_rotation("+z").T                    # y up, metres
    assert np.abs(Q[:, idx] - expect).max() < 1e-6
    # the offsets are the bone lengths: constant by construction of the format
    assert len(got_names) > len(names)


def test_bvh_units_and_missing_frames(tmp_path):
    names, parents, P = _chain_motion(5, seed=1)
    P = P * 100.0                                         # centimetres
    P[2, 4] = np.nan                                      # an incomplete frame repeats frame 1
    path = write_bvh(tmp_path / "m.bvh", names, parents, P, units="cm", up="+z", y_up=False)
    got_names, Q = parse_bvh(path.read_text())
    idx = [got_names.index(n) for n in names]
    assert np.abs(Q[:, idx][[0, 1, 3, 4]] - P[[0, 1, 3, 4]] / 100).max() < 1e-6
    assert np.abs(Q[2, idx] - P[1] / 100).max() < 1e-6


def _poses():
    rng = np.random.default_rng(2)
    out = []
    for i in range(4):
        parts = {"head": rng.normal(size=3), "left_hand": rng.normal(size=3),
                 "hand_2": None if i == 1 else rng.normal(size=3)}
        joints = {"left_elbow": rng.normal(size=3), "neck": rng.normal(size=3)}
        out.append(Pose(f"{i:06d}", "rejected" if i == 2 else "matched", 0.1, parts,
                        joints=joints, diagnostics={"interpolated": i == 2}))
    return out


def test_trc_round_trip_every_joint_opensim_names(tmp_path):
    poses = _poses()
    names = marker_names(poses, ["head"])
    assert names == ["head", "left_hand", "hand_2", "left_elbow", "neck"]
    trc = write_trc(tmp_path / "m.trc", poses, names, fps=50, up="+z", labels=OPENSIM_LABELS)
    got, times, a = read_trc(trc)
    assert got == ["Head", "LHand", "hand_2", "LElbow", "Neck"]
    R = y_up_rotation("+z")
    for i, p in enumerate(poses):
        for j, n in enumerate(names):
            v = p.parts.get(n) if p.status == "matched" else None
            v = p.joints.get(n) if v is None else v
            if v is None:
                assert np.isnan(a[i, j]).all()
            else:
                assert np.allclose(a[i, j], R @ v, atol=1e-6)
    assert np.isnan(a[2, 0]).all() and not np.isnan(a[2, 3]).any()   # interpolated joints kept
    # a round trip through Pose JSON keeps the joints
    p2 = Pose.from_dict(poses[0].to_dict())
    assert set(p2.joints) == {"left_elbow", "neck"}
    assert np.allclose(p2.joints["neck"], poses[0].joints["neck"])


def test_c3d_round_trip_every_joint(tmp_path):
    try:
        import c3d
    except ImportError:
        pytest.skip("optional extra c3d not installed (pip install topopose[c3d])")
    poses = _poses()
    names = marker_names(poses, ["head"])
    write_c3d(tmp_path / "m.c3d", poses, names, fps=50, units="m", labels=OPENSIM_LABELS)
    with open(tmp_path / "m.c3d", "rb") as fh, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = c3d.Reader(fh)
        assert [str(x).strip() for x in r.point_labels] == ["Head", "LHand", "hand_2", "LElbow",
                                                               "Neck"]
        frames = [pts for _, pts, _ in r.read_frames()]
    for i, p in enumerate(poses):
        for j, n in enumerate(names):
            v = p.parts.get(n) if p.status == "matched" else None
            v = p.joints.get(n) if v is None else v
            if v is None:
                assert frames[i][j, 3] < 0
            else:
                assert np.allclose(frames[i][j, :3], np.asarray(v) * 1000, atol=0.05)


def test_read_trc_of_pose2sim_layout(tmp_path):
    """Pose2Sim writes the data right after the X1/Y1/Z1 line (no empty line)."""
    text = ("PathFileType\t4\t(X/Y/Z)\tt.trc\n"
            "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\t"
            "OrigDataStartFrame\tOrigNumFrames\n60\t60\t2\t2\tm\t60\t0\t2\n"
            "Frame#\tTime\tRHip\t\t\tNeck\t\t\n\t\tX1\tY1\tZ1\tX2\tY2\tZ2\n"
            "1\t0.0166\t1\t2\t3\t4\t5\t6\n2\t0.0333\t7\t8\t9\t10\t11\t12\n")
    (tmp_path / "t.trc").write_text(text)
    names, times, a = read_trc(tmp_path / "t.trc")
    assert names == ["RHip", "Neck"] and len(times) == 2
    assert np.allclose(a[1, 1], [10, 11, 12]) and np.allclose(a[0, 0], [1, 2, 3])
