"""Batch runs end to end on a synthetic capture folder: incremental output, resume, failures
with reasons (corrupt PNG, missing frame, empty silhouette, subject leaving the volume), exit
statuses, exports, Dask workers, pictures."""
import json
import re

import cv2
import numpy as np
import pytest

from topopose.cli import main
from topopose.pose import read_poses
from topopose.batch import run
from topopose.pose.export import read_trc

FRAMES = 6


def _volume_cutting_one_frame(gt, lo, hi):
    """A capture volume (lo', hi') that cuts the subject of exactly one frame, else None."""
    ext = {}
    for f, fr in gt["frames"].items():
        pts = np.array(list(fr["parts"].values()) + list(fr["joints"].values()))
        ext[f] = (pts.min(0) - 0.12, pts.max(0) + 0.12)          # + limb radius
    for f in ext:
        for ax in (0, 1):
            others_hi = max(ext[g][1][ax] for g in ext if g != f)
            if ext[f][1][ax] - others_hi > 0.15:
                hi2 = np.array(hi, float)
                hi2[ax] = (ext[f][1][ax] + others_hi) / 2
                return f, lo, hi2
            others_lo = min(ext[g][0][ax] for g in ext if g != f)
            if others_lo - ext[f][0][ax] > 0.15:
                lo2 = np.array(lo, float)
                lo2[ax] = (ext[f][0][ax] + others_lo) / 2
                return f, lo2, hi
    return None


@pytest.fixture(scope="module")
def capture_dir(tmp_path_factory):
    from topopose.synth import synthesize

    out = tmp_path_factory.mktemp("cap") / "human"
    synthesize(out, subject="human", frames=FRAMES, seed=3, cameras=8, size=(320, 240),
               noise=0, separated=True)
    return out


@pytest.fixture(scope="module")
def broken_dir(capture_dir, tmp_path_factory):
    """The same capture with one problem per frame 1–4."""
    import shutil

    out = tmp_path_factory.mktemp("broken") / "human"
    shutil.copytree(capture_dir, out)
    gt = json.loads((out / "gt.json").read_text())
    cut = _volume_cutting_one_frame(gt, [-1.25, -1.25, -0.05], [1.25, 1.25, 2.3])
    assert cut is not None, "seed 3 should give a frame far from the others"
    leaving, lo, hi = cut
    toml = (out / "capture.toml").read_text()
    toml = re.sub(r"min = \[.*\]", f"min = [{lo[0]}, {lo[1]}, {lo[2]}]", toml)
    toml = re.sub(r"max = \[.*\]", f"max = [{hi[0]}, {hi[1]}, {hi[2]}]", toml)
    (out / "capture.toml").write_text(toml)
    others = [f"{i:06d}" for i in range(FRAMES) if f"{i:06d}" != leaving]
    corrupt, missing, empty = others[1:4]
    (out / "silhouettes" / "cam_01" / f"{corrupt}.png").write_bytes(b"\x89PNG\r\n\x1a\n garbage")
    (out / "silhouettes" / "cam_02" / f"{missing}.png").unlink()
    cv2.imwrite(str(out / "silhouettes" / "cam_03" / f"{empty}.png"), np.zeros((240, 320), np.uint8))
    return out, {"corrupt": corrupt, "missing": missing, "empty": empty, "leaving": leaving}


def test_run_good_capture_writes_poses_and_exports(capture_dir, tmp_path, capsys):
    out = tmp_path / "poses.jsonl"
    trc, csvp, bvh = tmp_path / "p.trc", tmp_path / "p.csv", tmp_path / "p.bvh"
    code = main(["run", str(capture_dir), "--model", "human", "--resolution", "80",
                 "--output", str(out), "--trc", str(trc), "--csv", str(csvp), "--bvh", str(bvh)])
    assert code == 0
    poses = read_poses(out)
    assert [p.frame for p in poses] == [f"{i:06d}" for i in range(FRAMES)]
    assert all(p.status in ("matched", "rejected") for p in poses)
    for p in poses:
        assert set(p.timings_ms) >= {"hull", "thinning", "tree", "alignment", "total"}
        if p.matched:     # the identities' track segments, and the followed body's own record
            assert set(p.diagnostics["track"]) == {"hand", "foot"}
            assert p.diagnostics["follow"]["confirmed"] is True
    printed = capsys.readouterr().out
    assert f"{FRAMES} frames" in printed and "matched" in printed
    assert "no motion was tracked" not in printed
    names, times, a = read_trc(trc)
    assert names[0] == "Head" and len(times) == FRAMES        # OpenSim marker names
    assert "torso" in names and "Neck" in names               # Neck: the fitted neck joint
    m = [i for i, p in enumerate(poses) if p.status == "matched"]
    assert m, "at least one matched frame"
    i = m[0]
    # TRC is y-up metres: its y is the capture's z
    assert np.isclose(a[i, 0, 1], poses[i].parts["head"][2], atol=1e-5)
    # the full skeleton: every joint of the model in every matched frame, and in the TRC
    assert len(poses[i].joints) == 20 and "Neck" in names and "chest" in names
    text = bvh.read_text()
    assert text.startswith("HIERARCHY\nROOT chest") and f"Frames: {FRAMES}" in text
    assert "JOINT left_elbow" in text
    assert len(csvp.read_text().splitlines()) == FRAMES + 1


@pytest.mark.parametrize("threshold, reason", [(None, "confidence gate"),
                                               (0.01, "AHA distance")])
def test_a_run_no_frame_of_which_passed_the_gate_is_tracked_from_the_rejected_alignments(
        capture_dir, threshold, reason):
    """A gate that rejects every frame (and with a tiny threshold, the AHA distance too): the
    tracker starts from the alignments the run rejected; every frame has a skeleton near the
    synthetic truth, ``tracked`` (never ``matched``), the reason kept and the track marked
    unconfirmed; with ``unconfirmed`` off, none."""
    from topopose.batch.run import summary_text
    from topopose.frame.confidence import GateOptions
    from topopose.sequence.follow import FollowOptions

    shut = GateOptions(max_unexplained=-1.0, far_unexplained=-1.0)
    gt = json.loads((capture_dir / "gt.json").read_text())
    res = run(capture_dir, model="human", resolution=80, threshold=threshold, progress=False,
              gate_rule=shut, consistency=False)
    assert [p.status for p in res.poses] == ["tracked"] * FRAMES
    errors = []                  # each part from the truth's (the two hands, feet: either way)
    for p in res.poses:
        assert p.error.startswith(reason) and len(p.joints) == 20
        assert p.diagnostics["follow"]["confirmed"] is False
        truth = gt["frames"][p.frame]["parts"]
        errors += [np.linalg.norm(np.subtract(p.parts[k], truth[k]))
                   for k in ("head", "torso", "crotch")]
        for limb in ("hand", "foot"):
            ours = [np.asarray(v) for k, v in p.parts.items() if limb in k]
            theirs = [np.asarray(truth[f"{limb}_{k}"]) for k in (1, 2)]
            errors += min(([np.linalg.norm(ours[0] - a), np.linalg.norm(ours[1] - b)]
                           for a, b in (theirs, theirs[::-1])), key=sum)
    # the gate-on run of this capture: mean 0.046, largest 0.096 × the height (this: 0.032, 0.114)
    assert np.mean(errors) < 0.06 * gt["height"] and np.max(errors) < 0.15 * gt["height"]
    assert f"{FRAMES} frames tracked from alignments the run rejected" in summary_text(res)
    off = run(capture_dir, model="human", resolution=80, threshold=threshold, progress=False,
              gate_rule=shut, consistency=False, follow=FollowOptions(unconfirmed=False))
    assert [p.status for p in off.poses] == ["rejected"] * FRAMES
    assert not any(p.joints for p in off.poses)


def test_a_run_without_a_skeleton_runs_its_sequence_stage_once(capture_dir, monkeypatch):
    """Nothing to track without the kinematic skeleton: no frame matched, and the sequence
    stage is not run again on the rejected alignments."""
    import topopose.sequence.motion as motion
    from topopose.frame.confidence import GateOptions

    calls = []
    real = motion.process_sequence
    monkeypatch.setattr(motion, "process_sequence",
                        lambda *a, **k: calls.append(1) or real(*a, **k))
    shut = GateOptions(max_unexplained=-1.0, far_unexplained=-1.0)
    res = run(capture_dir, model="human", resolution=80, progress=False, gate_rule=shut,
              consistency=False, skeleton=False, track=True)
    assert len(calls) == 1 and {p.status for p in res.poses} == {"rejected"}
    run(capture_dir, model="human", resolution=80, progress=False, gate_rule=shut,
        consistency=False)
    assert len(calls) == 3                  # with the skeleton: once more, on those alignments


def test_a_run_with_no_frame_matched_says_why_nothing_was_tracked():
    """Every frame rejected: the summary says the tracker had nothing to start from and which
    options accept more frames; one frame matched or tracked, and it does not."""
    from topopose.batch.run import RunResult, summary_text
    from topopose.pose import Pose

    poses = [Pose(frame=f"{i:06d}", status="rejected") for i in range(FRAMES)]
    text = summary_text(RunResult(poses, None, counts={"rejected": len(poses)}))
    assert "0 matched" in text and "no frame matched, so no motion was tracked" in text
    assert "--confidence-gate off" in text and "--threshold" in text
    for k in ("matched", "tracked"):
        counts = {"rejected": len(poses) - 1, k: 1}
        assert "no motion" not in summary_text(RunResult(poses, None, counts=counts))


def test_bad_input_frames_fail_with_reasons_and_run_completes(broken_dir, tmp_path, capsys):
    """The frames with no hull (a corrupt image, a missing one, an empty silhouette) fail
    with their reasons; the frame whose subject leaves the capture volume fails the per-frame
    stage but keeps its hull, so the tracker follows the body into it: it has joints, its
    reason stays in ``error`` and the summary names it."""
    folder, bad = broken_dir
    out = tmp_path / "poses.jsonl"
    # strict hull (tolerance 0): the empty silhouette empties the hull
    code = main(["run", str(folder), "--resolution", "64", "--output", str(out), "--tolerance", "0"])
    assert code == 1
    poses = {p.frame: p for p in read_poses(out)}
    assert len(poses) == FRAMES
    failed = {f for f, p in poses.items() if p.status == "failed"}
    assert failed == {bad[k] for k in ("corrupt", "missing", "empty")}
    assert "cam_01" in poses[bad["corrupt"]].error and poses[bad["corrupt"]].error.startswith("hull")
    assert "cam_02" in poses[bad["missing"]].error
    assert "empty visual hull" in poses[bad["empty"]].error
    leaving = poses[bad["leaving"]]
    assert "border of the capture volume" in leaving.error
    assert leaving.status in ("tracked", "lost") and len(leaving.joints) == 20
    assert leaving.diagnostics["follow"]["before"] == "failed"
    assert all(v is None for v in poses[bad["empty"]].parts.values())
    printed = capsys.readouterr().out
    assert "3 failed" in printed and bad["corrupt"] in printed
    assert f"1 frame the per-frame stage failed, followed in the hull it kept (first " \
        f"{bad['leaving']}: hull: the subject crosses the border" in printed
    # default tolerance (1 with 8 cameras): one camera's empty silhouette no longer matters
    again = run(folder, "human", resolution=64, frames=[bad["empty"]], progress=False)
    assert again.poses[0].status != "failed"


def test_incremental_output_and_resume(capture_dir, tmp_path):
    out = tmp_path / "poses.jsonl"
    partial = tmp_path / "poses.jsonl.partial"
    seen = []

    def check(pose):                       # each finished frame is already on disk (partial file)
        seen.append(pose.frame)
        lines = partial.read_text().splitlines()
        assert "topopose" in json.loads(lines[0])                  # header line first
        assert len(lines) == 1 + len(seen) and json.loads(lines[-1])["frame"] == pose.frame

    r1 = run(capture_dir, "human", resolution=64, output=out, frames="0:2", progress=False,
             on_pose=check)
    assert r1.computed == 2 and len(seen) == 2 and not partial.exists()
    assert len(out.read_text().splitlines()) == 1 + 2
    # a killed run (frame 000002 done, 000003 half-written) leaves its partial file beside
    lines = out.read_text().splitlines()
    one = run(capture_dir, "human", resolution=64, output=None, frames="2", progress=False).poses[0]
    partial.write_text("\n".join(lines[:1] + [one.to_json(), '{"frame": "000003", "status": "matc']))
    seen.clear()
    r2 = run(capture_dir, "human", resolution=64, output=out, resume=True, progress=False)
    assert r2.skipped == 3 and r2.computed == FRAMES - 3 and not partial.exists()
    poses = read_poses(out)
    assert [p.frame for p in poses] == [f"{i:06d}" for i in range(FRAMES)]
    assert len(out.read_text().splitlines()) == 1 + FRAMES
    # the resumed frames equal a fresh run's
    fresh = run(capture_dir, "human", resolution=64, output=None, progress=False)
    for a, b in zip(poses, fresh.poses):
        assert a.status == b.status and a.distance == pytest.approx(b.distance)


def test_dask_workers_same_results(capture_dir, tmp_path):
    seq = run(capture_dir, "human", resolution=64, frames="0:4", progress=False)
    par = run(capture_dir, "human", resolution=64, frames="0:4", workers=2, progress=False,
              output=tmp_path / "p.jsonl")
    assert [p.frame for p in par.poses] == [p.frame for p in seq.poses]
    for a, b in zip(par.poses, seq.poses):
        assert a.status == b.status and a.distance == pytest.approx(b.distance)
        for k in a.parts:
            assert (a.parts[k] is None) == (b.parts[k] is None)
    assert len(read_poses(tmp_path / "p.jsonl")) == 4
    # a running cluster, by address (the same code path as --scheduler tcp://host:8786)
    from dask.distributed import LocalCluster

    with LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                      dashboard_address=None) as cluster:
        by_addr = run(capture_dir, "human", resolution=64, frames="0:2",
                      scheduler=cluster.scheduler_address, progress=False)
    for a, b in zip(by_addr.poses, seq.poses[:2]):
        assert a.frame == b.frame and a.distance == pytest.approx(b.distance)


def test_malformed_calibration_and_model_exit_2(capture_dir, tmp_path, capsys):
    import shutil

    bad = tmp_path / "cap"
    shutil.copytree(capture_dir, bad)
    cal = (bad / "calibration.toml").read_text()
    cal = re.sub(r"matrix = \[\[.*\]\]", "matrix = [[1.0, 2.0], [3.0]]", cal, count=1)
    (bad / "calibration.toml").write_text(cal)
    assert main(["run", str(bad), "--output", str(tmp_path / "p.jsonl")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "calibration.toml" in err[0] and "matrix" in err[0]
    model = tmp_path / "m.toml"
    model.write_text('[model]\nname = "x"\n[[edge]]\nparts = ["a", "b"]\nlenght = 1\n')
    assert main(["run", str(capture_dir), "--model", str(model)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "m.toml" in err[0] and "lenght" in err[0]


def test_view_and_evaluate_cli(capture_dir, tmp_path, capsys):
    out = tmp_path / "poses.jsonl"
    assert main(["run", str(capture_dir), "--resolution", "64", "--output", str(out),
                 "--frames", "0:2"]) == 0
    png = tmp_path / "frame.png"
    assert main(["view", str(capture_dir), "--poses", str(out), "--frame", "000001",
                 "--out", str(png), "--silhouettes"]) == 0
    img = cv2.imread(str(png))
    assert img is not None and img.shape[0] > 600 and img.shape[1] > 900
    assert img.std() > 10                   # not a blank picture
    assert main(["evaluate", str(capture_dir), "--poses", str(out), "--out", str(tmp_path)]) == 0
    text = capsys.readouterr().out
    assert "classes:" in text and "threshold" in text
    assert (tmp_path / "poses_quality.png").exists()
    assert main(["evaluate", str(capture_dir), "--poses", str(out), "--out", str(tmp_path),
                 "--tolerance", "0.08"]) == 0
    assert "= 0.08 x height, junctions x 1" in capsys.readouterr().out
    with pytest.raises(SystemExit) as exc:          # argparse: mutually exclusive options
        main(["evaluate", str(capture_dir), "--poses", str(out), "--tolerance", "0.08",
              "--tolerance-m", "0.1"])
    assert exc.value.code == 2


def test_rerun_recording_or_clear_message(capture_dir, tmp_path, capsys):
    rrd = tmp_path / "run.rrd"
    args = ["run", str(capture_dir), "--resolution", "64", "--frames", "0:2",
            "--output", str(tmp_path / "p.jsonl"), "--rerun", str(rrd)]
    try:
        import rerun  # noqa: F401
    except ImportError:
        assert main(args) == 2
        assert "pip install topopose[rerun]" in capsys.readouterr().err
    else:
        assert main(args) == 0
        assert rrd.stat().st_size > 5000


def test_demo_writes_what_it_says(tmp_path):
    from topopose.batch.demo import run_demo

    lines = []
    code = run_demo(tmp_path / "demo", frames=2, resolution=64, subjects=["human"],
                    size=(320, 240), progress=False, print_fn=lines.append)
    text = "\n".join(lines)
    assert code in (0, 1) and "human" in text and "good" in text
    d = tmp_path / "demo" / "human"
    for name in ("poses.jsonl", "poses.trc", "poses.csv", "distances.png", "quality.png",
                 "gt.json", "calibration.toml"):
        assert (d / name).exists(), name
    assert list(d.glob("frame_*_typical.png")) and str(d) in text


def test_gate_options_recorded_and_resumed(capture_dir, tmp_path):
    """A gate given as GateOptions is written into the header as its fields; a resume with the
    same gate continues, with another gate it is refused."""
    from topopose.errors import InputError
    from topopose.frame.confidence import GateOptions

    out = tmp_path / "poses.jsonl"
    gate = GateOptions(max_foot_rise=None)
    run(capture_dir, "human", resolution=64, output=out, frames="0:1", progress=False,
        gate_rule=gate)
    header = json.loads(out.read_text().splitlines()[0])
    assert header["settings"]["gate_rule"]["max_foot_rise"] is None
    r = run(capture_dir, "human", resolution=64, output=out, frames="0:2", progress=False,
            gate_rule=gate, resume=True)
    assert r.skipped == 1 and r.computed == 1
    with pytest.raises(InputError, match="another settings"):
        run(capture_dir, "human", resolution=64, output=out, frames="0:3", progress=False,
            resume=True)
