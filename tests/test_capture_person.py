"""Silhouette method "person" (capture/segment.py) with a stand-in for MediaPipe's pose network.

The stand-in "network" returns the true capsule silhouette (the bright pixels of the synthetic
frames) as its segmentation mask, so the hull of the method must equal the hull of the true
silhouettes; no background model is learned; a camera where no one is found does not vote."""
from __future__ import annotations

import sys
import types

import cv2
import numpy as np
import pytest

from _capture_testutils import capsule_masks, ring, write_capture
from topopose.capture import load_capture
from topopose.capture.background import foreground_maps
from topopose.hull import visual_hull

TOML = ('[capture.volume]\nmin = [-0.5, -0.5, 0.2]\nmax = [0.5, 0.5, 1.7]\n\n'
        '[silhouettes]\nmethod = "person"\nscale = 1.0\nmedian = 0\n')


class _Result:
    def __init__(self, mask):
        self.segmentation_mask = mask


class _FakePose:
    """Stand-in for ``mediapipe.solutions.pose.Pose``: person = bright pixels; nobody in an
    image whose top-left pixel is pure red (a camera where the network finds no one)."""
    made = 0

    def __init__(self, **kwargs):
        assert kwargs["enable_segmentation"]
        # tracking mode (person_track) without the mask smoothing across frames
        assert kwargs["static_image_mode"] or kwargs["smooth_segmentation"] is False
        self.static = kwargs["static_image_mode"]
        type(self).made += 1
        self.number = type(self).made

    def process(self, rgb):
        if tuple(rgb[0, 0]) == (255, 0, 0):
            return _Result(None)
        return _Result((rgb.min(axis=2) > 150).astype(np.float32))


@pytest.fixture()
def fake_mediapipe(monkeypatch):
    from topopose.capture import segment

    mod = types.ModuleType("mediapipe.python.solutions.pose")
    mod.Pose = _FakePose
    for name in ("mediapipe", "mediapipe.python", "mediapipe.python.solutions"):
        monkeypatch.setitem(sys.modules, name, types.ModuleType(name))
    monkeypatch.setitem(sys.modules, "mediapipe.python.solutions.pose", mod)
    monkeypatch.setattr(segment, "_MODEL", {})
    monkeypatch.setattr(segment, "_LAST", {})
    _FakePose.made = 0


def _scene(tmp_path, blind_camera=None):
    cams = ring(n=4, size=(160, 120), f=200)
    masks = capsule_masks(cams, (0.0, 0.0, 0.6), (0.1, 0.1, 1.3), 0.16)
    rng = np.random.default_rng(3)
    images = []
    for k, (m, c) in enumerate(zip(masks, cams)):
        bg = rng.integers(0, 120, (c.size[1], c.size[0], 3)).astype(np.uint8)
        im = np.where(m[:, :, None], np.uint8([200, 220, 240]), bg)
        if k == blind_camera:
            im[0, 0] = (0, 0, 255)             # BGR pure red: the stand-in finds no one
        images.append(im)
    root = write_capture(tmp_path / "cap", cams, {}, images={"000000": images})
    (root / "capture.toml").write_text(TOML)
    truth = write_capture(tmp_path / "truth", cams, {"000000": masks})
    (truth / "capture.toml").write_text(TOML.split("\n\n")[0] + "\n")
    return load_capture(root), load_capture(truth), masks


def test_person_hull_equals_the_true_silhouettes_hull(tmp_path, fake_mediapipe):
    cap, truth, masks = _scene(tmp_path)
    maps = foreground_maps(cap, "000000")
    for q, m in zip(maps, masks):
        assert np.array_equal(q > 127, m)
    assert ("sequence_backgrounds",) not in cap.cache       # no background model learned
    h, t = visual_hull(cap, "000000", resolution=40), visual_hull(truth, "000000", resolution=40)
    assert h.diagnostics["fusion"] == "hard"                 # fusion "auto" for "person"
    assert np.array_equal(h.data, t.data) and t.data.sum() > 200
    assert _FakePose.made == 4                              # one network per camera


def test_a_camera_where_no_one_is_found_does_not_vote(tmp_path, fake_mediapipe):
    cap, _, _ = _scene(tmp_path, blind_camera=2)
    maps = foreground_maps(cap, "000000")
    assert (maps[2] == 128).all()
    assert not (maps[1] == 128).all()



# --- the grid of "person": follows the subject, one voxel size, independent of frame order ---

def _moving(tmp_path, name="cap"):
    """No [capture.volume]: a capsule that stands still for two frames, then steps 0.35 m
    aside and raises its top (frame 2)."""
    cams = ring(n=4, size=(160, 120), f=200)
    rng = np.random.default_rng(4)
    empty = [rng.integers(0, 120, (c.size[1], c.size[0], 3)).astype(np.uint8) for c in cams]
    ends = [((0.0, 0.0, 0.6), (0.05, 0.05, 1.2)), ((0.0, 0.0, 0.6), (0.05, 0.05, 1.2)),
            ((0.35, 0.1, 0.6), (0.4, 0.1, 1.4))]
    truth = {f"{i:06d}": capsule_masks(cams, a, b, 0.15) for i, (a, b) in enumerate(ends)}
    frames = {f: [np.where(m[:, :, None], np.uint8([200, 220, 240]), bg)
                  for m, bg in zip(ms, empty)] for f, ms in truth.items()}
    root = write_capture(tmp_path / name, cams, {}, images=frames)
    (root / "capture.toml").write_text(TOML.split("\n\n")[1])       # no volume
    return load_capture(root), cams, ends, truth


def _true_hull(cams, masks, vol):
    """The hull of the true silhouettes on ``vol``'s grid, largest component (the oracle)."""
    from topopose.hull import HullCarver, keep_largest_component

    occ = HullCarver(cams, vol.origin, vol.voxel_size, vol.data.shape).carve(masks, 0).astype(bool)
    keep_largest_component(occ)
    return occ


def test_person_grid_follows_the_subject_whatever_the_frame_order(tmp_path, fake_mediapipe):
    """Every frame's hull is the true silhouettes' hull on a grid around it (frame 2 stepped
    0.35 m aside and grew: not cut), with one voxel size set by the first frame's box and its
    margin, and no sampled frame read; the same frame gives the same grid and hull processed
    alone, in order, or after the others."""
    from topopose.capture import prefetch

    cap, cams, ends, truth = _moving(tmp_path)
    with prefetch(cap, cap.frames):
        hulls = {f: visual_hull(cap, f, resolution=40) for f in cap.frames}
    assert ("sequence_backgrounds",) not in cap.cache and ("fitted_boxes", 0) not in cap.cache
    a, b = (np.array(x) for x in ends[0])
    m = 0.1 - 0.02        # ⅔ of zone_margin (0.15 m), less a pixel (≈ 1.5 cm at 3 m: the
    #                       silhouettes sample pixel centres, so the hull may be that short)
    side = float(np.abs(b - a).max()) + 2 * 0.15
    vs = {h.voxel_size for h in hulls.values()}
    assert len(vs) == 1
    assert side + 2 * m <= vs.pop() * 38 < side + 2 * (m + 0.04) + 1.0      # cone phantoms
    for f, h in hulls.items():
        t = _true_hull(cams, truth[f], h)
        assert t.sum() > 200 and np.array_equal(h.data, t)
        assert h.diagnostics["grid"] == "zone" and not h.diagnostics["touches_border"]
        assert h.data.shape == tuple(np.array(h.diagnostics["bbox"][1]) + 2)     # cropped
    lo2 = hulls["000002"].origin
    assert lo2[0] > hulls["000000"].origin[0] + 0.2         # the grid moved with the subject
    for k, order in enumerate((["000002"], ["000002", "000000", "000001"])):
        # alone, or first (before the frame that sizes the grid)
        other, *_ = _moving(tmp_path, f"cap{k}")
        with prefetch(other, order):
            again = {f: visual_hull(other, f, resolution=40) for f in order}
        for f, h in again.items():
            assert np.allclose(h.origin, hulls[f].origin) and h.voxel_size == hulls[f].voxel_size
            assert np.array_equal(h.data, hulls[f].data)


def _world(h):
    return {tuple(np.round((h.origin + h.voxel_size * np.array(ijk)) / h.voxel_size).astype(int))
            for ijk in np.argwhere(h.data)}


def test_person_frame_leaving_the_zone_gets_a_refocused_grid(tmp_path, fake_mediapipe,
                                                              monkeypatch):
    """With a zone reaching 5 cm beyond the first frame's box, frame 2 (0.35 m aside) touches
    its border and is carved on a refocused grid of the same lattice: the true silhouettes'
    hull, the same voxels in the world as the zone's hull of a 1 m zone."""
    from topopose.hull import hull as H

    cap, cams, _ends, truth = _moving(tmp_path)
    wide = visual_hull(cap, "000002", resolution=40)
    monkeypatch.setattr(H, "PERSON_ZONE", 0.05)
    small, *_ = _moving(tmp_path, "small")
    h0, h2 = (visual_hull(small, f, resolution=40) for f in ("000000", "000002"))
    assert h0.diagnostics["grid"] == "zone" and h2.diagnostics["grid"] == "refocus"
    assert not h2.diagnostics["touches_border"] and h2.voxel_size == wide.voxel_size
    t = _true_hull(cams, truth["000002"], h2)
    assert t.sum() > 200 and np.array_equal(h2.data, t)
    assert _world(h2) == _world(wide) and wide.diagnostics["grid"] == "zone"


def test_cameras_run_in_threads_each_on_its_own_network(fake_mediapipe):
    """person_probabilities (one thread per camera) gives what the cameras one after the
    other give, and each camera's images go to its own network, in frame order."""
    from topopose.capture.segment import person_probabilities, person_probability

    rng = np.random.default_rng(0)
    frames = [[rng.integers(0, 256, (60, 80, 3)).astype(np.uint8) for _ in range(4)]
              for _ in range(3)]
    seen = {}
    orig = _FakePose.process

    def process(self, rgb):
        seen.setdefault(id(self), []).append(rgb.copy())
        return orig(self, rgb)

    _FakePose.process = process
    try:
        got = [person_probabilities(imgs, [("t", c) for c in range(4)]) for imgs in frames]
    finally:
        _FakePose.process = orig
    for imgs, maps in zip(frames, got):
        assert all(np.array_equal(q, person_probability(im, ("s", c)))
                   for c, (im, q) in enumerate(zip(imgs, maps)))
    assert len(seen) == 4
    for calls in seen.values():     # one camera per network, its frames in order
        c = next(c for c in range(4) if np.array_equal(calls[0], frames[0][c][:, :, ::-1]))
        assert all(np.array_equal(x, frames[i][c][:, :, ::-1]) for i, x in enumerate(calls))


def test_tracking_mode_keeps_a_graph_per_run_of_consecutive_frames(fake_mediapipe):
    """person_track: one tracking graph per camera while frames follow each other; a frame that
    does not follow the camera's previous one (asked again, skipped, out of order) gets a new
    graph, so its mask does not depend on frames outside its run."""
    from topopose.capture import segment

    graphs = {}
    orig = _FakePose.process

    def process(self, rgb):
        assert not self.static
        graphs.setdefault(self.number, []).append(int(rgb[0, 0, 0]))
        return orig(self, rgb)

    _FakePose.process = process
    try:
        for i in (0, 1, 2, 2, 5, 6, 3):
            img = np.full((20, 30, 3), i, np.uint8)
            q = segment.person_probabilities([img, img], [("a", 0), ("a", 1)], i)
            assert len(q) == 2 and q[0].shape == (20, 30)
    finally:
        _FakePose.process = orig
    runs = sorted(graphs.values())
    assert runs == [[0, 1, 2], [0, 1, 2], [2], [2], [3], [3], [5, 6], [5, 6]]
    assert _FakePose.made == 8


def test_cut_and_person_track_fields(tmp_path, fake_mediapipe):
    """``cut``: a pixel is subject when its probability exceeds it (hard fusion); it and
    ``person_track`` (a boolean) are validated with the file and field named."""
    from topopose import InputError
    from topopose.capture.background import masks_from_maps

    cap, _, _ = _scene(tmp_path)
    q = np.zeros((cap.cameras[0].size[1], cap.cameras[0].size[0]), np.uint8)
    q[0, :6] = [0, 76, 77, 127, 128, 255]
    for cut, want in ((0.3, [0, 0, 1, 1, 1, 1]), (0.5, [0, 0, 0, 0, 1, 1])):
        cap.options["silhouettes"]["cut"] = cut
        m = masks_from_maps(cap, [q] * len(cap.cameras))[0]
        assert m[0, :6].tolist() == [bool(x) for x in want] and m.sum() == sum(want)
    root = tmp_path / "cap"
    for extra, field in (("person_track = 1", "person_track"), ("cut = 1.5", "cut"),
                         ("cut = true", "cut")):
        (root / "capture.toml").write_text(TOML + extra + "\n")
        with pytest.raises(InputError, match=field):
            load_capture(root)
    (root / "capture.toml").write_text(TOML + "person_track = false\ncut = 0.4\n")
    opts = load_capture(root).options["silhouettes"]
    assert opts["person_track"] is False and opts["cut"] == 0.4


def test_downscaled_person_masks_carve_the_hull_of_their_upsampling(tmp_path, fake_mediapipe):
    """``scale = 0.25``: the silhouettes are UpsampledMasks carrying the network's 40 × 30
    masks, and the hull carved from those is the hull of the full-size (nearest-neighbour
    upsampled) masks, voxel for voxel."""
    from topopose.capture.background import UpsampledMask
    from topopose.hull import HullCarver

    cap, _, _ = _scene(tmp_path)
    (tmp_path / "cap" / "capture.toml").write_text(TOML.replace("scale = 1.0", "scale = 0.25"))
    cap = load_capture(tmp_path / "cap")
    masks = cap.silhouettes("000000")
    assert all(isinstance(m, UpsampledMask) and m.small.shape == (30, 40) for m in masks)
    for m in masks:
        assert np.array_equal(m, np.repeat(np.repeat(m.small, 4, 0), 4, 1).astype(bool))
    got = visual_hull(cap, "000000", resolution=40)
    cap.options["silhouettes"]["upsampled"] = False
    cap.cache.pop("foreground_last", None)
    plain = cap.silhouettes("000000")
    assert not any(isinstance(m, UpsampledMask) for m in plain)
    cap.cache.clear()
    want = visual_hull(cap, "000000", resolution=40)
    assert want.data.sum() > 100 and np.array_equal(got.data, want.data)
    carver = HullCarver(cap.cameras, got.origin, got.voxel_size, got.data.shape)
    a = carver.carve(masks, 0).copy()
    assert carver.fac.tolist() == [[4, 4]] * 4
    assert np.array_equal(a, carver.carve(plain, 0)) and carver.fac.max() == 1


def test_person_every_segments_each_camera_every_nth_frame_staggered(tmp_path, fake_mediapipe):
    """``person_every = n``: in a run of consecutive frames, frame i segments the cameras c with
    (i + c) % n == 0 and every other camera keeps the map of the frame it was segmented at last;
    the run's first frame and a frame that does not follow the previous one segment all
    cameras. With ``person_track`` each camera keeps one tracking graph over its run (its
    frames are n apart). Oracle: the stand-in network returns the image's value (10 i + c), so
    each map names the frame it came from."""
    from topopose import InputError

    cams = ring(n=4, size=(40, 30), f=60)
    frames = {f"{i:06d}": [np.full((30, 40, 3), 10 * i + c, np.uint8) for c in range(4)]
              for i in range(8)}
    root = write_capture(tmp_path / "cap", cams, {}, images=frames)
    orig = _FakePose.process
    _FakePose.process = lambda self, rgb: _Result(np.full(rgb.shape[:2], rgb[0, 0, 0] / 255,
                                                          np.float32))
    try:
        for n, track in ((2, False), (3, False), (2, True), (1, True)):
            (root / "capture.toml").write_text(
                TOML + f"person_every = {n}\nperson_track = {str(track).lower()}\n")
            cap = load_capture(root)
            made = _FakePose.made
            order = [0, 1, 2, 3, 4, 6, 7, 5]              # runs 0-4, 6-7, 5
            start = {0: 0, 1: 0, 2: 0, 3: 0, 4: 0, 6: 6, 7: 6, 5: 5}
            for i in order:
                got = [int(q[0, 0]) for q in foreground_maps(cap, f"{i:06d}")]
                want = [10 * max(j for j in range(start[i], i + 1)
                                 if j == start[i] or (j + c) % n == 0) + c for c in range(4)]
                assert got == want, (n, track, i)
            if track:     # one graph per camera and run
                assert _FakePose.made - made == 4 * 3
    finally:
        _FakePose.process = orig
    for bad in ("0", "1.5", "true", "65"):
        (root / "capture.toml").write_text(TOML + f"person_every = {bad}\n")
        with pytest.raises(InputError, match=r"capture\.toml.*person_every"):
            load_capture(root)


def test_person_every_from_videos_skips_the_conversion_not_the_maps(tmp_path, fake_mediapipe):
    """``person_every = n`` from videos: the reader decodes every camera but converts only the
    images the frame segments (``io._person_needed``, a speed-up); the maps must equal those of
    the same frames read one by one without the reader (every image converted), including
    after a jump in the frames; conversions were skipped; and an image skipped that the
    segmentation wants after all (here: every camera of a run's first frame) is read again."""
    from topopose.capture import prefetch
    from topopose.capture import sources
    from topopose.capture.images import image_list

    cams = ring(n=4, size=(160, 120), f=200)
    rng = np.random.default_rng(5)
    bgs = [rng.integers(0, 120, (c.size[1], c.size[0], 3)).astype(np.uint8) for c in cams]
    frames = []
    for i in range(9):
        ms = capsule_masks(cams, (0.1 * np.sin(i), 0.0, 0.6), (0.06 * i, 0.1, 1.3), 0.16)
        frames.append([np.where(m[:, :, None], np.uint8([200, 220, 240]), b)
                       for m, b in zip(ms, bgs)])
    root = write_capture(tmp_path / "cap", cams, {})
    (root / "videos").mkdir()
    for k, c in enumerate(cams):               # lossless: the images are the frames
        vw = cv2.VideoWriter(str(root / "videos" / f"{c.name}.avi"),
                             cv2.VideoWriter_fourcc(*"FFV1"), 25.0, c.size)
        assert vw.isOpened()
        for im in frames:
            vw.write(im[k])
        vw.release()
    order = ["000000", "000001", "000002", "000003", "000005", "000006", "000007", "000008"]
    calls = {True: 0, False: 0}
    get = sources._Decoder.get

    def counted(self, i, retrieve=True):
        calls[retrieve] += 1
        return get(self, i, retrieve)

    for n in (2, 3):
        (root / "capture.toml").write_text(TOML + f"person_every = {n}\nperson_track = true\n")
        direct = load_capture(root)
        want = {f: [q.copy() for q in foreground_maps(direct, f)] for f in order}
        assert any(not np.array_equal(want["000001"][c], want["000008"][c]) for c in range(4))
        cap = load_capture(root)
        calls[True] = calls[False] = 0
        sources._Decoder.get = counted
        try:
            with prefetch(cap, order):
                got = {f: foreground_maps(cap, f) for f in order}
        finally:
            sources._Decoder.get = get
        for f in order:
            assert all(np.array_equal(a, b) for a, b in zip(got[f], want[f])), (n, f)
        # frames 0 and 5 (after the jump) convert all 4 cameras, the 6 others 4 / n of them
        assert calls[True] == 8 + sum(sum((int(f) + c) % n == 0 for c in range(4))
                                      for f in order if f not in ("000000", "000005"))
        assert calls[False] == 4 * len(order) - calls[True] > 0
    fresh = load_capture(root)                  # a run's first frame: every camera wanted
    skipped = {c.name: sources.SKIPPED for c in fresh.cameras}
    maps = foreground_maps(fresh, "000003", image_list(fresh, "000003", skipped))
    ref = load_capture(root)
    assert all(np.array_equal(a, b) for a, b in zip(maps, foreground_maps(ref, "000003")))


def test_masks_of_a_kept_map_are_reused_and_equal(tmp_path, fake_mediapipe):
    """``masks_from_maps`` gives a camera whose map is the very array of the call before (a map
    ``person_every`` kept) the mask made then (a speed-up): equal to the mask made afresh,
    while a new array (even with the same values) is thresholded again."""
    from topopose.capture.background import masks_from_maps

    cap, _, _ = _scene(tmp_path)
    rng = np.random.default_rng(2)
    w, h = cap.cameras[0].size
    maps = [rng.integers(0, 256, (h // 4, w // 4)).astype(np.uint8) for _ in cap.cameras]
    first = masks_from_maps(cap, maps)
    second = [rng.integers(0, 256, (h // 4, w // 4)).astype(np.uint8) for _ in cap.cameras]
    second[1], second[3] = maps[1], maps[3].copy()           # kept (1) and equal but new (3)
    got = masks_from_maps(cap, second)
    assert got[1] is first[1] and got[3] is not first[3] and got[0] is not first[0]
    cap.cache.pop("masks_last")
    fresh = masks_from_maps(cap, second)
    for a, b in zip(got, fresh):
        assert np.array_equal(a, b) and np.array_equal(a.small, b.small)


def test_person_capture_without_a_subject_names_the_file_and_the_fix(tmp_path, fake_mediapipe):
    """No frame has a subject: the grid cannot be sized; the error names the capture and the
    field that fixes it, and no hull is returned."""
    from topopose.errors import InputError

    cams = ring(n=4, size=(160, 120), f=200)
    rng = np.random.default_rng(5)
    dark = {f"{i:06d}": [rng.integers(0, 120, (c.size[1], c.size[0], 3)).astype(np.uint8)
                         for c in cams] for i in range(2)}
    root = write_capture(tmp_path / "cap", cams, {}, images=dark)
    (root / "capture.toml").write_text(TOML.split("\n\n")[1])
    cap = load_capture(root)
    with pytest.raises(InputError, match=r"cap.*cannot size the voxel grid.*\[capture\.volume\]"):
        visual_hull(cap, "000001", resolution=40)
