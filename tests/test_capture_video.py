"""Video input, camera-name mapping and size policies of capture folders.

Oracles: the same scene written as images/ and as videos/ (lossless FFV1: identical silhouettes
and hulls; lossy mp4v: nearly identical), brute-force frame selection by time, projections of
rescaled cameras against the original ones scaled by hand, masks padded by hand.
"""
from __future__ import annotations

import random
import shutil
import warnings

import cv2
import numpy as np
import pytest

from _capture_testutils import calibration_toml, capsule_masks, ring, write_capture
from topopose.capture import load_capture, prefetch, read_images
from topopose.errors import InputError
from topopose.hull import visual_hull
from topopose.batch.run import select_frames

N_FRAMES, FPS = 8, 25.0


@pytest.fixture(scope="module")
def cams():
    return ring(n=4, size=(160, 120), f=200)


def _scene(cams, n=N_FRAMES):
    """Colour frames (a bright moving capsule on a textured background) and the backgrounds."""
    rng = np.random.default_rng(1)
    bgs = []
    for c in cams:
        w, h = c.size
        yy, xx = np.mgrid[0:h, 0:w]
        bg = np.stack([40 + 30 * np.sin(xx / 9.0), 50 + 20 * np.cos(yy / 7.0), 60 + 0 * xx], -1)
        bgs.append(np.clip(bg + rng.normal(0, 1, bg.shape), 0, 255).astype(np.uint8))
    frames = {}
    for i in range(n):
        masks = capsule_masks(cams, (0.1 * np.sin(i / 2), 0, 0.6), (0.05 * i, 0.1, 1.3), 0.16)
        frames[f"{i:06d}"] = [np.where(m[:, :, None], np.uint8([200, 220, 240]), b)
                              for m, b in zip(masks, bgs)]
    return frames, bgs


@pytest.fixture(scope="module")
def scene(cams):
    return _scene(cams)


def write_video(path, images, fourcc="FFV1", fps=FPS):
    h, w = images[0].shape[:2]
    vw = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*fourcc), fps, (w, h))
    assert vw.isOpened(), f"OpenCV cannot write {fourcc} here"
    for im in images:
        vw.write(im)
    vw.release()


def video_capture(root, cams, scene, fourcc="FFV1", ext=".avi", names=None, capture_toml=None):
    frames, bgs = scene
    root.mkdir(parents=True, exist_ok=True)
    (root / "calibration.toml").write_text(calibration_toml(cams))
    if capture_toml is not None:
        (root / "capture.toml").write_text(capture_toml)
    (root / "videos").mkdir()
    (root / "backgrounds").mkdir()
    for k, c in enumerate(cams):
        name = names[k] if names else c.name
        write_video(root / "videos" / f"{name}{ext}", [frames[f][k] for f in sorted(frames)], fourcc)
        cv2.imwrite(str(root / "backgrounds" / f"{name}.png"), bgs[k])
    return root


def test_video_capture_equals_image_capture(tmp_path, cams, scene):
    frames, bgs = scene
    img = load_capture(write_capture(tmp_path / "img", cams, {}, images=frames, backgrounds=bgs))
    vid = load_capture(video_capture(tmp_path / "vid", cams, scene))
    assert vid.options["source"] == "videos" and vid.frames == img.frames
    assert vid.fps == pytest.approx(FPS) and not vid.options["incomplete_frames"]
    for f in ("000000", "000005"):
        for a, b in zip(read_images(img, f), read_images(vid, f)):
            assert np.array_equal(a, b)               # FFV1 is lossless
        for a, b in zip(img.silhouettes(f), vid.silhouettes(f)):
            assert np.array_equal(a, b) and a.sum() > 200
    ha, hb = visual_hull(img, "000003", resolution=40), visual_hull(vid, "000003", resolution=40)
    assert np.array_equal(ha.data, hb.data) and ha.data.sum() > 100


def test_videos_fuse_like_images(tmp_path, cams, scene):
    """A method without an empty scene fuses probabilities (soft hull) from videos exactly as
    from images: the same hull and the same fusion (videos once fell back to hard masks)."""
    frames, _ = scene
    toml = ("[capture.volume]\nmin = [-0.6, -0.6, 0.0]\nmax = [0.8, 0.8, 1.8]\n\n"
            "[silhouettes]\nmethod = \"sequence\"\nsamples = 8\n")
    root = write_capture(tmp_path / "img", cams, {}, images=frames)
    (root / "capture.toml").write_text(toml)
    img = load_capture(root)
    vroot = video_capture(tmp_path / "vid", cams, scene, capture_toml=toml)
    shutil.rmtree(vroot / "backgrounds")
    vid = load_capture(vroot)
    from topopose.capture.background import foreground_maps

    ha, hb = visual_hull(img, "000000", resolution=40), visual_hull(vid, "000000", resolution=40)
    assert ha.diagnostics["fusion"] == hb.diagnostics["fusion"] == "soft"
    assert np.array_equal(ha.data, hb.data)
    for a, b in zip(foreground_maps(img, "000000"), foreground_maps(vid, "000000")):
        assert np.array_equal(a, b)


def test_lossy_mp4_gives_nearly_the_same_hull(tmp_path, cams, scene):
    frames, bgs = scene
    img = load_capture(write_capture(tmp_path / "img", cams, {}, images=frames, backgrounds=bgs))
    vid = load_capture(video_capture(tmp_path / "vid", cams, scene, "mp4v", ".mp4"))
    assert len(vid.frames) == N_FRAMES
    ha, hb = visual_hull(img, "000004", resolution=40), visual_hull(vid, "000004", resolution=40)
    assert ha.data.shape == hb.data.shape
    inter, union = np.sum(ha.data & hb.data), np.sum(ha.data | hb.data)
    assert inter / union > 0.9, inter / union


def test_prefetch_and_random_access_agree(tmp_path, cams, scene, monkeypatch):
    import topopose.capture.sources as sources

    monkeypatch.setattr(sources, "SEEK_GAP", 2)           # seek on (almost) every jump
    cap = load_capture(video_capture(tmp_path / "vid", cams, _scene(cams, 30), "mp4v", ".mp4"))
    order = list(cap.frames)
    random.Random(3).shuffle(order)
    direct = {f: read_images(cap, f) for f in order}          # random access, seeks back and forth
    src = cap.options["frame_source"]
    for f, imgs in src.sequential(cap.frames):                # sequential decoding
        for k, c in enumerate(cap.cameras):
            assert np.array_equal(imgs[c.name], direct[f][k])
    with prefetch(cap, cap.frames[1:6]):
        assert "prefetch" in cap.cache
        for f in cap.frames[1:6]:
            masks = cap.silhouettes(f)
            from topopose.capture.io import _silhouettes_now
            for a, b in zip(masks, _silhouettes_now(cap, f)):
                assert np.array_equal(a, b)
        cap.silhouettes(cap.frames[0])                         # not prefetched: read directly
    assert "prefetch" not in cap.cache


def test_shorter_and_corrupt_videos_fail_only_their_frames(tmp_path, cams, scene):
    root = video_capture(tmp_path / "vid", cams, scene, "MJPG", ".avi")
    frames, _ = scene
    write_video(root / "videos" / "cam_02.avi", [frames[f][1] for f in sorted(frames)[:5]], "MJPG")
    data = (root / "videos" / "cam_03.avi").read_bytes()
    (root / "videos" / "cam_03.avi").write_bytes(data[: len(data) // 3])     # truncated
    cap = load_capture(root)
    assert len(cap.frames) == N_FRAMES                     # the longest video's count
    assert all(cap.options["incomplete_frames"][f] == ["cam_02"] for f in cap.frames[5:])
    with pytest.raises(InputError, match=r"cam_02\.avi.*frame 6 missing.*has 5 frames"):
        cap.silhouettes("000006")
    ok, bad = [], []
    for f in cap.frames:
        try:
            cap.silhouettes(f)
            ok.append(int(f))
        except InputError as exc:
            bad.append(int(f))
            assert ("cam_03.avi" in str(exc) and "cannot be decoded" in str(exc)) or int(f) >= 5
    assert ok and ok == list(range(len(ok))) and bad == list(range(len(ok), N_FRAMES))
    # a video that does not open at all: every frame fails with the reason, loading succeeds
    (root / "videos" / "cam_01.avi").write_bytes(b"not a video" * 50)
    cap = load_capture(root)
    with pytest.raises(InputError, match=r"cam_01\.avi: cannot open the video"):
        cap.silhouettes("000000")


def test_run_reports_the_missing_frames(tmp_path, cams, scene):
    from topopose.batch.run import run

    root = video_capture(tmp_path / "vid", cams, scene, "FFV1", ".avi")
    frames, _ = scene
    write_video(root / "videos" / "cam_04.avi", [frames[f][3] for f in sorted(frames)[:6]])
    res = run(root, model="human", resolution=24, output=tmp_path / "p.jsonl", progress=False,
              frames="4:8")
    st = {p.frame: p for p in res.poses}
    assert sorted(st) == ["000004", "000005", "000006", "000007"]
    for f in ("000006", "000007"):
        assert st[f].status == "failed" and "cam_04.avi" in st[f].error and "missing" in st[f].error
    for f in ("000004", "000005"):
        assert "missing" not in (st[f].error or "") and "video" not in (st[f].error or "")
    assert res.exit_status == 1


def test_frames_by_time(tmp_path, cams, scene):
    cap = load_capture(video_capture(tmp_path / "vid", cams, scene))
    for text, a, b in (("0.1s:0.2s", 0.1, 0.2), ("0.12s:", 0.12, 99), (":0.04s", 0, 0.04),
                       ("0s:0.2s", 0, 0.2)):
        want = [f for i, f in enumerate(cap.frames) if a <= i / FPS + 1e-12 and i / FPS < b - 1e-12]
        assert select_frames(cap, text) == want, text
    assert select_frames(cap, "0s:0.3s:2") == cap.frames[0:8:2]
    assert select_frames(cap, "2:5") == select_frames(cap, slice(2, 5)) == cap.frames[2:5]
    with pytest.raises(InputError, match="--frames"):
        select_frames(cap, slice(50, 60))
    cap.fps = None
    with pytest.raises(InputError, match="frame rate"):
        select_frames(cap, "0.1s:0.2s")
    with pytest.raises(InputError, match="--frames"):
        select_frames(cap, "a:b")


def test_camera_names_match_folders(tmp_path, cams, scene):
    names = ["cam01", "CAM_2", "Cam3", "cam-004"]
    cap = load_capture(video_capture(tmp_path / "a", cams, scene, names=names))
    assert cap.options["names"] == dict(zip([c.name for c in cams], names))
    cap.silhouettes(0)
    # explicit table: plain mapping and the per-camera table side by side
    names = ["left", "right", "top", "cam04"]
    toml = ('[cameras]\ncam_01 = "left"\ncam_02 = "right"\n'
            '[cameras.cam_03]\nfolder = "top"\nsize_policy = "error"\n')
    cap = load_capture(video_capture(tmp_path / "b", cams, scene, names=names, capture_toml=toml))
    assert cap.options["names"]["cam_02"] == "right" and cap.options["names"]["cam_04"] == "cam04"
    cap.silhouettes(1)
    # ambiguous: cam01 and cam_1 both match cam_01
    root = video_capture(tmp_path / "c", cams, scene, names=["cam01", "cam02", "cam03", "cam04"])
    shutil.copy(root / "videos" / "cam01.avi", root / "videos" / "cam_1.avi")
    with pytest.raises(InputError, match=r"cam_01.*(cam01.*cam_1|cam_1.*cam01)"):
        load_capture(root)
    # a table entry naming an absent folder, and an unknown calibration name
    (root / "videos" / "cam_1.avi").unlink()
    (root / "capture.toml").write_text('[cameras]\ncam_01 = "nope"\n')
    with pytest.raises(InputError, match=r"nope.*cam_01.*\[cameras\]"):
        load_capture(root)
    (root / "capture.toml").write_text('[cameras]\ncam_09 = "cam01"\n')
    with pytest.raises(InputError, match=r"capture.toml.*cam_09"):
        load_capture(root)
    (root / "capture.toml").write_text('[cameras.cam_01]\nsize_policy = "stretch"\n')
    with pytest.raises(InputError, match=r"\[cameras.cam_01\] field 'size_policy'"):
        load_capture(root)


def test_image_folders_are_matched_too(tmp_path, cams, scene):
    frames, bgs = scene
    root = write_capture(tmp_path / "img", cams, {}, images=frames, backgrounds=bgs)
    for k, c in enumerate(cams):
        (root / "images" / c.name).rename(root / "images" / f"Cam{k + 1}")
        (root / "backgrounds" / f"{c.name}.png").rename(root / "backgrounds" / f"cam{k + 1:02d}.png")
    cap = load_capture(root)
    assert cap.options["names"]["cam_03"] == "Cam3"
    assert cap.silhouettes("000002")[2].sum() > 200


def _resized_capture(tmp_path, cams, scene, size, policy_toml):
    """Image capture whose cam_02 frames and background are resized (resize) or cropped."""
    frames, bgs = scene
    w, h = size

    def fit(im):
        if w <= im.shape[1] and h <= im.shape[0]:
            return im[:h, :w].copy()                       # crop: what "pad" must undo
        return cv2.resize(im, (w, h), interpolation=cv2.INTER_NEAREST)
    frames = {f: [fit(im) if k == 1 else im for k, im in enumerate(ims)] for f, ims in frames.items()}
    bgs = [fit(b) if k == 1 else b for k, b in enumerate(bgs)]
    return write_capture(tmp_path / f"s{w}x{h}", cams, {}, policy_toml, images=frames,
                         backgrounds=bgs)


def test_size_policy_error_names_file_sizes_and_option(tmp_path, cams, scene):
    root = _resized_capture(tmp_path, cams, scene, (152, 120), None)
    with pytest.raises(InputError) as e:               # the first frame is checked at loading
        load_capture(root)
    msg = str(e.value)
    for word in ("cam_02/000000.png", "152x120", "[160, 120]", "size_policy", "pad", "scale"):
        assert word in msg, (word, msg)
    # a video of the wrong size stops the capture at loading
    vid = video_capture(tmp_path / "v", cams, scene)
    frames, _ = scene
    write_video(vid / "videos" / "cam_02.avi", [im[1][:, :150] for _, im in sorted(frames.items())])
    with pytest.raises(InputError, match=r"cam_02\.avi: image size 150x120.*size_policy"):
        load_capture(vid)


def test_size_policy_pad(tmp_path, cams, scene):
    root = _resized_capture(tmp_path, cams, scene, (152, 112), '[capture]\nsize_policy = "pad"\n')
    ref = load_capture(write_capture(tmp_path / "ref", cams, {}, images=scene[0], backgrounds=scene[1]))
    with pytest.warns(UserWarning, match=r"cam_02.*152x112.*padded"):
        cap = load_capture(root)
    with warnings.catch_warnings():
        warnings.simplefilter("error")                 # warned once per camera, not per frame
        m, m0 = cap.silhouettes("000003")[1], ref.silhouettes("000003")[1]
    assert m.shape == (120, 160)
    assert not m[112:].any() and not m[:, 152:].any()                  # padded: background
    inner = np.zeros_like(m0)
    inner[:112, :152] = True
    assert (m ^ m0)[:104, :144].sum() <= 2                            # same mask inside (the
    assert cap.cameras[1].size == (160, 120)                          # clean-up sees the edge)
    # per-camera syntax; masks (silhouettes/) are padded the same way
    masks = {f: [m0[:112, :152] if k == 1 else m for k, m in enumerate(ref.silhouettes(f))]
             for f in ref.frames[:2]}
    root = write_capture(tmp_path / "m", cams, masks,
                         '[cameras.cam_02]\nsize_policy = "pad"\n')
    with pytest.warns(UserWarning, match="cam_02"):
        cap = load_capture(root)
        got = cap.silhouettes(ref.frames[0])[1]
    want = np.zeros((120, 160), bool)
    want[:112, :152] = masks[ref.frames[0]][1]
    assert np.array_equal(got, want)


def test_size_policy_scale_rescales_intrinsics(tmp_path, cams, scene):
    root = _resized_capture(tmp_path, cams, scene, (200, 90), '[capture]\nsize_policy = "scale"\n')
    with pytest.warns(UserWarning, match=r"cam_02.*200x90.*rescaled"):
        cap = load_capture(root)
    c0, c1 = cams[1], cap.cameras[1]
    assert c1.size == (200, 90) and cap.cameras[0].size == (160, 120)
    pts = np.random.default_rng(0).uniform([-0.5, -0.5, 0.3], [0.5, 0.5, 1.5], (50, 3))
    assert np.allclose(c1.project(pts), c0.project(pts) * [200 / 160, 90 / 120], atol=1e-9)
    m = cap.silhouettes("000002")
    assert m[1].shape == (90, 200) and m[1].sum() > 100


def test_refocus_reaches_the_estimator(tmp_path, cams, scene):
    from topopose.frame.estimate import FrameEstimator
    from topopose.cli import build_parser

    cap = load_capture(video_capture(tmp_path / "vid", cams, scene))
    vol = FrameEstimator(cap, "human", 24, refocus=True).hull("000002")
    assert vol.diagnostics["grid"] == "refocus"
    assert build_parser().parse_args(["run", "X", "--refocus"]).refocus is True


def test_read_ahead_yields_in_order_raises_in_place_and_stops():
    """read_ahead: the same items in the same order as iterating directly, an exception of the
    iterable raised at its place, an early close stopping the thread and closing the iterable."""
    import threading

    from topopose.capture.sources import read_ahead

    for depth in (1, 2, 5):
        assert list(read_ahead(iter(range(50)), depth)) == list(range(50))
    assert list(read_ahead([], 2)) == []

    def failing():
        yield 1
        yield 2
        raise InputError("frame 3 broken")

    got = []
    with pytest.raises(InputError, match="frame 3 broken"):
        for x in read_ahead(failing(), 2):
            got.append(x)
    assert got == [1, 2]

    closed = threading.Event()

    def endless():
        try:
            i = 0
            while True:
                yield i
                i += 1
        finally:
            closed.set()

    gen = read_ahead(endless(), 3)
    assert [next(gen) for _ in range(4)] == [0, 1, 2, 3]
    n_before = threading.active_count()
    gen.close()
    assert closed.wait(2.0)
    assert threading.active_count() <= n_before


def test_decode_fields_same_frames_and_validated(tmp_path, cams, scene):
    """[silhouettes] decode_threads / decode_ahead: the prefetched silhouettes are the same with
    FFmpeg's own threads and no read-ahead as with the defaults (one thread, 2 ahead); wrong
    values name the file and the field."""
    base = '[silhouettes]\nmethod = "diff"\n'
    caps = {}
    for name, extra in (("new", ""), ("old", "decode_threads = 0\ndecode_ahead = 0\n")):
        caps[name] = load_capture(video_capture(tmp_path / name, cams, scene, "mp4v", ".mp4",
                                                capture_toml=base + extra))
    assert caps["new"].options["silhouettes"]["decode_threads"] == 1
    assert caps["new"].options["silhouettes"]["decode_ahead"] == 2
    assert caps["old"].options["frame_source"].threads == 0
    out = {}
    for name, cap in caps.items():
        with prefetch(cap, cap.frames):
            out[name] = [cap.silhouettes(f) for f in cap.frames]
    for a, b in zip(out["new"], out["old"]):
        assert all(np.array_equal(x, y) for x, y in zip(a, b))
    for k, (extra, field) in enumerate((
            ("decode_threads = -1", "decode_threads"), ("decode_ahead = 1.5", "decode_ahead"),
            ("decode_threads = 65", "decode_threads"), ("decode_ahead = true", "decode_ahead"))):
        root = tmp_path / f"bad{k}"
        root.mkdir()
        (root / "capture.toml").write_text(base + extra + "\n")
        from topopose.capture.calibration import read_capture_options
        with pytest.raises(InputError, match=rf"capture\.toml: \[silhouettes\] field '{field}'"):
            read_capture_options(root / "capture.toml")
