"""A followed frame is ``lost`` when its fit falls well below the same run's (the silhouette IoU
a right fit reaches is the set-up's). Oracles: the rule's definition on random fits, and a
synthetic walk one frame of which has silhouettes far wider than the subject."""
import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from topopose.capture import Capture
from topopose.sequence.follow import lost_frames

FITS = st.dictionaries(st.integers(0, 50), st.floats(0.01, 1.0), min_size=1, max_size=30)


@settings(max_examples=200, deadline=None)
@given(FITS, st.floats(0.0, 1.0), st.floats(0.05, 1.0))
def test_lost_frames_are_those_below_the_share_of_the_median_whatever_the_scale(fits, share,
                                                                               scale):
    """Exactly the frames below ``share`` × the median fit; the same frames when every fit is
    scaled (a set-up whose right fits all reach less)."""
    values = sorted(fits.values())
    n = len(values)
    median = values[n // 2] if n % 2 else 0.5 * (values[n // 2 - 1] + values[n // 2])
    assert lost_frames(fits, share) == {i for i, f in fits.items() if f < share * median}
    scaled = {i: f * scale for i, f in fits.items()}
    assert lost_frames(scaled, share) == {i for i, f in scaled.items()
                                          if f < share * median * scale}
    assert lost_frames({}, share) == set()


@pytest.fixture(scope="module")
def walk():
    from topopose.synth.capture import synthetic_capture

    return synthetic_capture("body", frames=10, seed=2, cameras=5, size=(320, 240),
                             motion="walk")


@pytest.mark.parametrize("share, silhouettes", [(None, True), (0.95, True), (None, False)])
def test_a_frame_whose_silhouettes_are_far_wider_than_the_subject_is_lost(walk, share,
                                                                         silhouettes):
    """Frame 5's masks dilated by 12 px in every camera (the capture volume reaching well below
    the floor, so that the wider hull stays inside it): the body fitted there covers a small
    share of them, so that frame is ``lost``; every followed frame's status is the rule's on
    the run's own fits, with the default share and with one close to 1 (an absolute bound
    that high would lose every frame), and without silhouettes (the fit is the voxel
    agreement)."""
    from dataclasses import replace

    from topopose.batch.run import run
    from topopose.sequence.follow import FollowOptions

    opts = FollowOptions(silhouette_fit=silhouettes)
    opts = opts if share is None else replace(opts, min_fit=share)
    bad = walk.frames[5]
    disk = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (25, 25))
    masks = dict(walk.masks)
    masks[bad] = [cv2.dilate(np.asarray(m, np.uint8), disk).astype(bool) for m in masks[bad]]
    cap = Capture(walk.cameras, walk.frames, None, walk.up, walk.units, walk.fps,
                  ((-1.25, -1.25, -0.6), (1.25, 1.25, 2.45)), {}, masks)
    res = run(cap, resolution=48, progress=False, follow=opts)
    by = {p.frame: p for p in res.poses}
    assert by[bad].status == "lost"
    followed = [p for p in res.poses if p.status in ("matched", "tracked", "lost")]
    assert len(followed) == len(walk.frames)
    fits = {p.frame: p.fit for p in followed}
    assert by[bad].fit < 0.5 * np.median(list(fits.values()))
    lost = {p.frame for p in followed if p.status == "lost"}
    assert lost == lost_frames(fits, opts.min_fit) and len(lost) < len(followed) // 2
