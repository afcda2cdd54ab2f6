"""The faults users make: nothing lost, no traceback, no hang.

Every refused command exits 2 with one line on standard error naming the file or option, and
leaves every file it was given byte for byte as it was (the whole folder is compared before
and after). An output never replaces an input or a complete result unless the run completes:
an interrupted rerun (SIGINT to a child process) and a run whose every frame failed keep the
old file. Property tests (Hypothesis) feed the poses reader and the detection grammar random
and mutated inputs: an InputError or a result, never another exception, never a NaN.
"""
import json
import math
import os
import re
import shutil
import socket
import stat
import struct
import threading
import time
import zlib
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from topopose import InputError
from topopose.cli import main
from topopose.apps import detect as D
from topopose.pose.pose import Pose, read_poses

import _sigint


# ----------------------------------------------------------------------------- helpers
def snapshot(*roots) -> dict:
    """Every file under ``roots`` (files or folders): path -> bytes."""
    out = {}
    for r in map(Path, roots):
        for p in ([r] if r.is_file() else sorted(r.rglob("*")) if r.is_dir() else []):
            if p.is_file():
                out[str(p)] = p.read_bytes()
    return out


def cli(capsys, argv):
    """(exit status, stderr lines without the progress bar, stdout) of ``topopose argv``."""
    try:
        code = main([str(a) for a in argv])
    except SystemExit as e:                       # argument errors
        code = e.code
    cap = capsys.readouterr()
    err = [x for x in cap.err.replace("\r", "\n").splitlines()
           if x.strip() and "frame/s" not in x and "frame]" not in x and "s/frame" not in x]
    return code, err, cap.out


def refused(capsys, argv, *must, keep=()):
    """``argv`` exits 2 with one line naming ``must``; the files under ``keep`` unchanged."""
    before = snapshot(*keep)
    code, err, _ = cli(capsys, argv)
    assert code == 2, (argv, code, err)
    assert len(err) == 1 and err[0].startswith("topopose: error:"), err
    for m in must:
        assert str(m) in err[0], (m, err[0])
    assert snapshot(*keep) == before
    return err[0]


@pytest.fixture(scope="module")
def cap(tmp_path_factory):
    from topopose.synth import synthesize

    out = tmp_path_factory.mktemp("faults") / "cap"
    synthesize(out, subject="human", frames=3, seed=1, cameras=4, size=(120, 90), separated=True)
    return out


@pytest.fixture(scope="module")
def poses(cap, tmp_path_factory):
    """A finished run, the complete result the faulty commands must leave as it is."""
    out = tmp_path_factory.mktemp("done") / "poses.jsonl"
    assert main(["run", str(cap), "--resolution", "32", "--output", str(out)]) == 0
    return out


@pytest.fixture
def copy(cap, tmp_path):
    """A fresh copy of the capture (for tests that change it)."""
    def make(name="c"):
        shutil.copytree(cap, tmp_path / name)
        return tmp_path / name
    return make


def poses_file(path, coords=None, n=6):
    """A small poses file; ``coords`` (a JSON value) replaces hand_1's position in frame 1."""
    lines = []
    for i in range(n):
        parts = {"head": [0, 0, 1.7], "torso": [0, 0, 1.2], "crotch": [0, 0, 0.9],
                 "hand_1": [0.3 * i, 0.1, 1.0 + 0.2 * i], "hand_2": [-0.4, 0.2, 1.1]}
        if i == 1 and coords is not None:
            parts["hand_1"] = coords
        lines.append(json.dumps({"frame": f"{i:06d}", "status": "matched", "distance": 0.1,
                                 "parts": parts}))
    path.write_text("\n".join(lines) + "\n")
    return path


def write_png_header(path, w, h):
    """A PNG whose header claims w x h (the data is a 12 x 10 image's)."""
    import cv2

    buf = bytearray(cv2.imencode(".png", np.zeros((10, 12), np.uint8))[1].tobytes())
    buf[16:24] = struct.pack(">II", w, h)
    buf[29:33] = struct.pack(">I", zlib.crc32(bytes(buf[12:29])) & 0xFFFFFFFF)
    Path(path).write_bytes(bytes(buf))


# ----------------------------------------------------------------------------- files lost
@pytest.mark.parametrize("target", ["calibration.toml", "capture.toml",
                                    "silhouettes/cam_02/000001.png", "silhouettes/cam_02/new.png",
                                    "gt.json"])
def test_run_output_onto_the_capture_is_refused(cap, capsys, target):
    refused(capsys, ["run", cap, "--resolution", "32", "--output", cap / target],
            "--output", keep=[cap])
    refused(capsys, ["run", cap, "--resolution", "32", "--output", cap.parent / "x.jsonl",
                     "--csv", cap / target], "--csv", keep=[cap])
    assert not (cap.parent / "x.jsonl").exists()


def test_outputs_on_devices_fifos_and_each_other_are_refused(cap, poses, tmp_path, capsys):
    base = ["run", cap, "--resolution", "32"]
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    refused(capsys, base + ["--output", fifo], "--output", "FIFO")
    assert stat.S_ISFIFO(os.stat(fifo).st_mode)
    full = tmp_path / "full"          # a copy of /dev/full's node (root), never the system's own
    try:
        os.mknod(full, stat.S_IFCHR | 0o666, os.makedev(1, 7))
    except PermissionError:
        full = None                   # not root: only the FIFO can be made here
    if full is not None:
        refused(capsys, base + ["--output", full], "--output", "device")
        assert stat.S_ISCHR(os.stat(full).st_mode)
    refused(capsys, base + ["--output", poses, "--trc", tmp_path / "m.trc", "--bvh", fifo], "--bvh")
    for opt in ("--csv", "--trc"):
        refused(capsys, base + ["--output", poses, opt, poses], opt, "--output", keep=[poses])


def test_ctrl_c_of_a_rerun_keeps_the_complete_file(tmp_path, capsys):
    """SIGINT to a child rerunning over a complete poses file: the file is unchanged, the
    frames computed are kept beside it, and --resume continues from them."""
    from topopose.synth import synthesize

    capt = tmp_path / "long"
    synthesize(capt, subject="human", frames=12, seed=3, cameras=4, size=(120, 90), separated=True)
    out = tmp_path / "p.jsonl"
    assert main(["run", str(capt), "--resolution", "32", "--output", str(out)]) == 0
    before = out.read_bytes()
    code, err = interrupt(["run", capt, "--resolution", "32", "--output", out], n=12)
    assert code == 130 and len(err) == 1 and err[0].startswith("topopose: interrupted"), err
    assert "left as it was" in err[0]
    assert out.read_bytes() == before
    partial = out.with_name(out.name + ".partial")
    assert partial.exists() and str(partial) in err[0]
    capsys.readouterr()
    assert main(["run", str(capt), "--resolution", "32", "--output", str(out), "--resume"]) == 0
    assert "resumed" in capsys.readouterr().out and not partial.exists()
    assert len(read_poses(out)) == 12
    # a first run interrupted: what it computed is the output
    fresh = tmp_path / "fresh.jsonl"
    code, err = interrupt(["run", capt, "--resolution", "32", "--output", fresh], n=12)
    assert code == 130 and err == ["topopose: interrupted"], err
    assert 2 <= len(read_poses(fresh)) < 12 and not fresh.with_name("fresh.jsonl.partial").exists()


DRIVER = r"""
import signal, sys, time
signal.signal(signal.SIGINT, signal.default_int_handler)   # as a terminal's Ctrl-C
from topopose.frame.estimate import FrameEstimator
estimate = FrameEstimator.estimate
def slow(self, *a, **k):                 # frames slow enough to be interrupted mid-run
    time.sleep(0.4)
    return estimate(self, *a, **k)
FrameEstimator.estimate = slow
from topopose.cli import main
sys.exit(main(sys.argv[1:]))
"""


def interrupt(argv, n):
    """SIGINT to ``topopose argv`` (frames slowed by :data:`DRIVER`) after 2 of ``n`` frames:
    (exit status, stderr lines without the progress bar)."""
    code, err = _sigint.interrupt(DRIVER, argv, n)
    assert "Traceback" not in err, err[-3000:]
    return code, [x for x in err.splitlines() if x.strip() and f"/{n} [" not in x]


def test_every_frame_failed_keeps_the_old_file(copy, poses, tmp_path, capsys):
    c = copy()
    out = tmp_path / "p.jsonl"
    shutil.copy(poses, out)
    trc = tmp_path / "m.trc"
    trc.write_text("an export of the complete run\n")
    before = snapshot(tmp_path)
    for f in (c / "silhouettes" / "cam_01").iterdir():       # every frame of a camera unreadable
        f.write_bytes(b"not a picture")
    code, err, stdout = cli(capsys, ["run", c, "--resolution", "32", "--output", out, "--trc", trc])
    assert code == 1 and snapshot(tmp_path) == {**before, **snapshot(c)}
    assert len(err) == 1 and "every frame failed" in err[0] and str(out) in err[0], err
    assert "failed 000000" in stdout and "cam_01" in stdout and str(out) not in stdout


def test_masks_at_the_wrong_size_stop_before_any_write(copy, poses, tmp_path, capsys):
    import cv2

    c = copy()
    for f in (c / "silhouettes" / "cam_03").iterdir():
        cv2.imwrite(str(f), np.zeros((45, 60), np.uint8))
    out = tmp_path / "p.jsonl"
    shutil.copy(poses, out)
    refused(capsys, ["run", c, "--resolution", "32", "--output", out], "cam_03", "60x45", "size",
            keep=[out])


def test_commands_never_overwrite_their_input(cap, poses, tmp_path, capsys):
    P = tmp_path / "P.jsonl"
    shutil.copy(poses, P)
    refused(capsys, ["detect", P, "above hand_1 head", "--output", P], "--output", keep=[P])
    refused(capsys, ["detect", P, "above hand_1 head", "--csv", P], "--csv", keep=[P])
    refused(capsys, ["cluster", P, "--output", P], "--output", keep=[P])
    refused(capsys, ["segment", cap, "--poses", P, "--out", P], "--out", keep=[P, cap])
    seg = tmp_path / "seg"
    seg.mkdir()
    S = seg / "segmentation.jsonl"                 # the poses where segment writes its summary
    shutil.copy(poses, S)
    refused(capsys, ["segment", cap, "--poses", S, "--out", seg], "--out", keep=[seg, cap])
    refused(capsys, ["segment", cap, "--poses", P, "--out", cap / "silhouettes"], "--out",
            keep=[cap])
    refused(capsys, ["view", cap, "--poses", P, "--frame", "0", "--out", P], "--out", keep=[P])
    refused(capsys, ["hull", cap, "--frame", "0", "--resolution", "24",
                     "--out", cap / "silhouettes" / "v.npz"], "--out", keep=[cap])


def test_calib_import_never_overwrites_its_input(cap, tmp_path, capsys):
    g = tmp_path / "g.txt"
    g.write_text("500 0 60 0\n0 500 45 0\n0 0 1 2\n")
    refused(capsys, ["calib", "import", g, "--format", "pmatrix", "--size", "120x90",
                     "--out", g], "--out", keep=[g])
    out = tmp_path / "calibration.toml"
    refused(capsys, ["calib", "import", g, "--format", "pmatrix", "--size", "0x-5",
                     "--out", out], "--size", keep=[g])
    assert not out.exists() and sorted(os.listdir(tmp_path)) == ["g.txt"]
    assert main(["calib", "import", str(g), "--format", "pmatrix", "--size", "120x90",
                 "--out", str(out)]) == 0
    before = out.read_bytes()                      # an existing result kept on a refusal
    refused(capsys, ["calib", "import", g, "--format", "pmatrix", "--size", "nope",
                     "--out", out], "--size", keep=[out])
    assert out.read_bytes() == before


# ----------------------------------------------------------------------------- tracebacks
@pytest.mark.parametrize("frames", ["0:5:0", "infs:"])
def test_run_frames_slices(cap, poses, capsys, frames):
    refused(capsys, ["run", cap, "--resolution", "32", "--output", poses, "--frames", frames],
            "--frames", keep=[poses])


@pytest.mark.parametrize("coords", [["a", "b", "c"], [float("nan"), 0, 1], [1e308, 0, 1],
                                    "x", {"x": 1}, [True, 0, 1]])
def test_bad_coordinates_are_one_line_in_every_reader(cap, tmp_path, capsys, coords):
    P = poses_file(tmp_path / "bad.jsonl", coords)
    e = refused(capsys, ["detect", P, "above hand_1 head"], P, "line 2", "hand_1", keep=[P])
    assert refused(capsys, ["cluster", P], keep=[P]) == e
    assert refused(capsys, ["evaluate", cap, "--poses", P], keep=[P]) == e
    assert refused(capsys, ["view", cap, "--poses", P, "--frame", "1",
                            "--out", tmp_path / "v.png"], keep=[P]) == e
    assert not (tmp_path / "v.png").exists()


def test_detection_nesting_and_library_bounded(tmp_path, capsys):
    P = poses_file(tmp_path / "p.jsonl")
    for expr in ["not " * 5000 + "above head torso", "(" * 5000 + "above head torso" + ")" * 5000,
                 " and ".join(["above head torso"] * 3000)]:
        code, err, _ = cli(capsys, ["detect", P, expr])
        assert code == 2 and err[0].startswith("topopose: error: expression: nested deeper")
        assert len(err) == 3 and len(err[1]) < 100          # the caret's window, not 25 kB
    lib = tmp_path / "lib.toml"
    lib.write_bytes(bytes(range(256)) * 64)
    refused(capsys, ["detect", P, "--pose", "x", "--library", lib], lib, "pose library")
    lib.write_bytes(b"[[pose]]\nname = 1\nexpr = 5\n")
    refused(capsys, ["detect", P, "--pose", "x", "--library", lib], lib, "expr")


def test_view_and_segment_outputs_of_the_wrong_kind(cap, poses, tmp_path, capsys):
    refused(capsys, ["view", cap, "--poses", poses, "--frame", "0", "--out", tmp_path / "f.txt"],
            "--out", ".png")
    afile = tmp_path / "f.npz"
    afile.write_bytes(b"keep")
    refused(capsys, ["segment", cap, "--poses", poses, "--out", afile], "--out", "not a folder",
            keep=[afile])


def _server(reply: bytes | None):
    """A local TCP server answering ``reply`` to anything (None: accepts, never replies)."""
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    s.listen(8)
    held = []

    def serve():
        while True:
            try:
                c, _ = s.accept()
            except OSError:
                return
            held.append(c)
            if reply is not None:
                try:
                    c.recv(4096)
                    c.sendall(reply)
                except OSError:
                    pass

    threading.Thread(target=serve, daemon=True).start()
    return s, f"tcp://127.0.0.1:{s.getsockname()[1]}"


def test_scheduler_addresses_that_are_not_schedulers(cap, poses, capsys):
    from topopose.batch.run import probe_scheduler

    base = ["run", cap, "--resolution", "32", "--output", poses]
    refused(capsys, base + ["--scheduler", "garbage:::"], "--scheduler", "garbage:::", keep=[poses])
    srv, addr = _server(b"HTTP/1.1 400 Bad Request\r\nContent-Length: 0\r\n\r\n")
    try:
        refused(capsys, base + ["--scheduler", addr], "--scheduler", addr, keep=[poses])
    finally:
        srv.close()
    srv, addr = _server(None)                     # accepts and never replies: no hang
    try:
        t0 = time.perf_counter()
        with pytest.raises(InputError, match="--scheduler.*did not answer within 1 s"):
            probe_scheduler(addr, timeout=1.0)
        assert time.perf_counter() - t0 < 10
    finally:
        srv.close()


def test_detect_api_refuses_what_is_not_poses():
    for bad in ([1, 2, 3], [{"frame": "0", "parts": {"head": "up"}}], ["x"],
                [{"frame": "0", "parts": {"head": [float("nan"), 0, 0]}}]):
        with pytest.raises(InputError, match=r"poses\[0\]"):
            D.detect(bad, "above head torso")
    with pytest.raises(InputError):
        D.detect([], 5)


# ----------------------------------------------------------------------------- hangs, sizes
def test_synth_refuses_what_it_cannot_hold(tmp_path, capsys):
    out = tmp_path / "s"
    t0 = time.perf_counter()
    refused(capsys, ["synth", out, "--frames", "100000000000"], "--frames", "memory")
    assert time.perf_counter() - t0 < 30 and not out.exists()
    for args, opt in ((["--frames", "0"], "--frames"), (["--cameras", "0"], "--cameras"),
                      (["--fps", "nan"], "--fps"), (["--thickness", "-1"], "--thickness"),
                      (["--size", "0x10"], "--size"), (["--noise", "9"], "--noise")):
        refused(capsys, ["synth", out, *args], opt)
        assert not out.exists()


# ----------------------------------------------------------------------------- wrong answers
def test_numbers_checked_at_the_boundary(tmp_path, capsys):
    P = poses_file(tmp_path / "p.jsonl")
    for expr in ("near head torso -1", "far head torso -0.5", "near head torso 1e999"):
        code, err, _ = cli(capsys, ["detect", P, expr])
        assert code == 2 and "distance" in err[0], err
    with pytest.raises(InputError, match="distance"):
        D.parse("near head torso -1")
    assert D.parse("near head - torso - 1").value == 1.0          # '-' still separates
    for args, opt in ((["--clusters", "0"], "--clusters"), (["--clusters", "-2"], "--clusters"),
                      (["--threshold", "nan"], "--threshold"), (["--threshold", "-1"], "--threshold")):
        refused(capsys, ["cluster", P, *args], opt, keep=[P])
    refused(capsys, ["detect", P, "above head torso", "--margin", "nan"], "--margin")


@pytest.mark.parametrize("origin,voxel,field", [([np.nan, 0, 0], 0.1, "origin"),
                                                ([0, 0, 0], -1.0, "voxel_size"),
                                                ([0, 0, 0], np.inf, "voxel_size")])
def test_volume_fields_checked(tmp_path, capsys, origin, voxel, field):
    v = tmp_path / "v.npz"
    vol = np.zeros((8, 8, 8), bool)
    vol[2:6, 3:5, 3:5] = True
    np.savez_compressed(v, volume=vol, origin=np.array(origin, float), voxel_size=np.float64(voxel))
    refused(capsys, ["skeleton", v, "--out", tmp_path / "s.npz"], v, field, keep=[tmp_path])
    assert not (tmp_path / "s.npz").exists()


def test_no_folder_tree_made_and_the_option_named(cap, poses, tmp_path, capsys):
    deep = tmp_path / "a" / "b" / "p.jsonl"
    refused(capsys, ["run", cap, "--resolution", "32", "--output", deep], "--output", "does not exist")
    refused(capsys, ["detect", poses, "above hand_1 head", "--output", deep], "--output")
    refused(capsys, ["synth", tmp_path / "x" / "y"], "OUT", "does not exist")
    assert not (tmp_path / "a").exists() and not (tmp_path / "x").exists()
    out = tmp_path / "p.jsonl"                     # the partial file beside it cannot be made
    (tmp_path / "p.jsonl.partial").mkdir()
    e = refused(capsys, ["run", cap, "--resolution", "32", "--output", out], "--output", out)
    assert ".partial" not in e.split("(")[0]


def test_oversized_png_header_names_camera_and_file(copy, tmp_path, capsys):
    c = copy()
    bad = c / "silhouettes" / "cam_02" / "000001.png"
    write_png_header(bad, 60000, 60000)
    code, err, out = cli(capsys, ["run", c, "--resolution", "32", "--output", tmp_path / "p.jsonl"])
    assert code == 1 and "Traceback" not in "".join(err)
    line = [x for x in out.splitlines() if "failed 000001" in x]
    assert line and "cam_02" in line[0] and str(bad) in line[0] and "60000x60000" in line[0], out
    assert "OpenCV" not in out


def test_exports_carry_their_final_name_and_help_names_no_internals(cap, tmp_path, capsys):
    trc = tmp_path / "motion.trc"
    assert main(["run", str(cap), "--resolution", "32", "--output", str(tmp_path / "p.jsonl"),
                 "--trc", str(trc)]) == 0
    assert trc.read_text().splitlines()[0].split("\t")[-1] == "motion.trc"
    assert sorted(os.listdir(tmp_path)) == ["motion.trc", "p.jsonl"]
    from topopose.cli import build_parser

    text = [a for a in build_parser()._actions if a.dest == "command"][0].choices["run"].format_help()
    for internal in ("topopose.", ".py", "benchmarks/", "MAX_UNEXPLAINED", "CENTRE"):
        assert internal not in text, internal


def test_progress_bar_shows_the_whole_status(cap, tmp_path, capsys):
    assert main(["run", str(cap), "--resolution", "32", "--output", str(tmp_path / "p.jsonl")]) == 0
    shown = set(re.findall(r"status=(\w+)", capsys.readouterr().err))
    assert shown and shown <= {"matched", "rejected", "failed"}, shown


def test_third_party_warnings_silent_ours_one_line(cap, tmp_path, capsys):
    import warnings

    from topopose._quiet import one_line_warnings

    with one_line_warnings():
        warnings.warn("ours\nsecond line", UserWarning)               # this file: not ours
        import topopose.capture.calibration as calib

        exec(compile("import warnings\nwarnings.warn('mine', UserWarning)",
                     calib.__file__, "exec"), {})
        warnings.warn("numeric", RuntimeWarning)
    assert capsys.readouterr().err.splitlines() == ["topopose: warning: mine"]
    code, err, _ = cli(capsys, ["run", cap, "--resolution", "32", "--output", tmp_path / "p.jsonl"])
    assert code == 0 and not err, err


# ----------------------------------------------------------------------------- properties
JSON = st.recursive(st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=8),
                    lambda c: st.lists(c, max_size=4) | st.dictionaries(st.text(max_size=6), c,
                                                                        max_size=4),
                    max_leaves=12)
GOOD = {"frame": "000001", "status": "matched", "distance": 0.25,
        "parts": {"head": [0.0, 0.1, 1.7], "hand_1": [0.3, 0.1, 1.9], "torso": [0.0, 0.0, 1.2]},
        "joints": {"neck": [0.0, 0.0, 1.5]}, "timings_ms": {"total": 3.0}, "error": None}
FIELDS = [("frame",), ("status",), ("distance",), ("parts",), ("parts", "head"),
          ("parts", "hand_1"), ("joints", "neck"), ("timings_ms",), ("error",), ("diagnostics",)]
NUMBERS = st.floats() | st.integers(min_value=-(10 ** 400), max_value=10 ** 400) | st.sampled_from(
    [float("nan"), float("inf"), -float("inf"), 1e308, -1e308, 1e9, 1e10])


def mutated_line(field, value, coord):
    d = json.loads(json.dumps(GOOD))
    tgt = d
    for k in field[:-1]:
        tgt = tgt[k]
    if coord is not None and isinstance(tgt.get(field[-1]), list):
        tgt[field[-1]][coord[0]] = coord[1]
    else:
        tgt[field[-1]] = value
    return json.dumps(d)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(lines=st.lists(
    st.one_of(JSON.map(json.dumps),
              st.builds(mutated_line, st.sampled_from(FIELDS), JSON,
                        st.none() | st.tuples(st.integers(0, 2), NUMBERS | JSON)),
              st.text(max_size=40),
              st.just("[" * 3000 + "]" * 3000)), min_size=1, max_size=5),
       strict=st.booleans())
def test_poses_reader_never_raises_anything_else(tmp_path, lines, strict):
    f = tmp_path / "p.jsonl"
    f.write_bytes("\n".join(lines).encode("utf-8", "surrogatepass"))
    try:
        got = read_poses(f, strict=strict)
    except InputError as e:
        assert str(f) in str(e)
        return
    for p in got:
        assert isinstance(p, Pose)
        assert p.distance is None or math.isfinite(p.distance)
        for v in (*p.parts.values(), *p.joints.values()):
            assert v is None or (v.shape == (3,) and np.all(np.isfinite(v)))
        D.detect([p], "above hand_1 head or near head torso 0.5")     # and detection takes them


TOKENS = ["(", ")", "not", "and", "or", "xor", "above", "below", "x-greatest", "z-least", "order",
          "order-i", "near", "far", "head", "hand_1", "torso", "-", ",", "1", "0.5", "-1", "1e999",
          "nan", "inf", "true", "false", "1e5", "y", "-greatest", ".5", "NOT", "&", "é"]


def check_tree(node):
    assert D.depth(node) <= D.MAX_DEPTH
    todo = [node]
    while todo:
        n = todo.pop()
        if isinstance(n, D.Rel) and n.op in ("near", "far"):
            assert math.isfinite(n.value) and n.value >= 0
        todo += [n.arg] if isinstance(n, D.Not) else [n.left, n.right] if isinstance(n, D.BinOp) else []


def mutate(text, data):
    for _ in range(data.draw(st.integers(0, 4))):
        i = data.draw(st.integers(0, len(text)))
        op = data.draw(st.sampled_from(["insert", "delete", "repeat"]))
        if op == "insert":
            text = text[:i] + data.draw(st.sampled_from(TOKENS + [" ", "-", "("])) + text[i:]
        elif op == "delete":
            text = text[:i] + text[i + 3:]
        else:
            text = text[:i] * data.draw(st.integers(1, 60)) + text[i:]
    return text


@settings(max_examples=400, deadline=None)
@given(data=st.data(), how=st.sampled_from(["tokens", "text", "library"]))
def test_detection_grammar_never_raises_anything_else(data, how):
    if how == "tokens":
        text = " ".join(data.draw(st.lists(st.sampled_from(TOKENS), max_size=30)))
    elif how == "text":
        text = data.draw(st.text(max_size=60))
    else:
        lib = D.load_library()[0]
        text = mutate(lib[data.draw(st.sampled_from(sorted(lib)))].expr, data)
    try:
        node = D.parse(text)
    except InputError:
        return
    check_tree(node)
    pos = data.draw(st.fixed_dictionaries({p: st.one_of(st.none(), st.tuples(
        *[st.floats(-3, 3, allow_nan=False)] * 3)) for p in ("head", "hand_1", "torso")}))
    v = D.evaluate(node, pos, aliases={})
    assert v in (True, False, None)
    nan = {k: (float("nan"),) * 3 for k in pos}
    assert D.evaluate(node, nan, aliases={}) in (True, False, None)
