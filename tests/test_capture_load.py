"""load_capture: a good capture folder round-trips; every bad input raises InputError naming
the file and the field (small broken capture folders written in tmp_path)."""
from __future__ import annotations

import re
import warnings

import cv2
import numpy as np
import pytest

from _capture_testutils import calibration_toml, capsule_masks, ring, write_capture
from topopose.capture import load_capture
from topopose.cli import main
from topopose.errors import InputError


@pytest.fixture(scope="module")
def cams():
    return ring(n=3, size=(160, 120), f=200)


@pytest.fixture(scope="module")
def masks(cams):
    return [capsule_masks(cams, (0, 0, 0.7 + 0.1 * i), (0.1, 0, 1.2), 0.15) for i in range(3)]


@pytest.fixture
def good(tmp_path, cams, masks):
    frames = {"frame_2": masks[0], "frame_10": masks[1], "frame_1": masks[2]}
    return write_capture(tmp_path / "cap", cams, frames,
                         capture_toml='[capture]\nup = "+z"\nunits = "m"\nfps = 30\n')


def test_good_capture_round_trip(good, cams, masks):
    cap = load_capture(good)
    assert cap.frames == ["frame_1", "frame_2", "frame_10"]            # natural order
    assert [c.name for c in cap.cameras] == [c.name for c in cams]
    assert cap.fps == 30 and cap.units == "m" and cap.volume is None
    assert cap.options["incomplete_frames"] == {} and cap.options["source"] == "silhouettes"
    for c, c0 in zip(cap.cameras, cams):
        assert np.allclose(c.matrix, c0.matrix) and np.allclose(c.rotation, c0.rotation)
        assert np.allclose(c.translation, c0.translation) and c.size == c0.size
    sil = cap.silhouettes("frame_10")
    assert all(np.array_equal(a, b) for a, b in zip(sil, masks[1]))
    assert all(np.array_equal(a, b) for a, b in zip(cap.silhouettes(0), masks[2]))


def _expect(path, *words, call=load_capture):
    with pytest.raises(InputError) as ei:
        call(path)
    msg = str(ei.value)
    for w in words:
        assert w in msg, f"{w!r} not in {msg!r}"
    return msg


def _edit_calibration(root, pattern, repl, count=1):
    p = root / "calibration.toml"
    text, n = re.subn(pattern, repl, p.read_text(), count=count, flags=re.M)
    assert n, pattern
    p.write_text(text)


def test_missing_calibration(good):
    (good / "calibration.toml").unlink()
    _expect(good, "calibration.toml", "not found")


def test_not_toml(good):
    (good / "calibration.toml").write_text("[cam_01\nname = ")
    _expect(good, "calibration.toml", "TOML")


@pytest.mark.parametrize("pattern,repl,words", [
    (r"^matrix = .*$", "", ["[cam_02]", "'matrix'"]),
    (r"^size = .*$", "size = [160]", ["[cam_02]", "'size'"]),
    (r"^size = .*$", "size = [160.5, 120]", ["[cam_02]", "'size'"]),
    (r"^matrix = .*$", "matrix = [[1.0, 0.0], [0.0, 1.0]]", ["[cam_02]", "'matrix'", "3×3"]),
    (r"^matrix = .*$", "matrix = [[0.0, 0.0, 80.0], [0.0, 0.0, 60.0], [0.0, 0.0, 1.0]]",
     ["[cam_02]", "'matrix'", "singular"]),
    (r"^translation = .*$", "translation = [nan, 0.0, 1.0]", ["[cam_02]", "'translation'", "non-finite"]),
    (r"^rotation = .*$", "rotation = [0.1, inf, 0.0]", ["[cam_02]", "'rotation'", "non-finite"]),
    (r"^rotation = .*$", 'rotation = "none"', ["[cam_02]", "'rotation'"]),
    (r"^rotation = .*$", "rotation = [[1.0, 0, 0], [0, 2.0, 0], [0, 0, 1.0]]", ["[cam_02]", "'rotation'"]),
    (r"^distortions = .*$", "distortions = [0.1, 0.2, 0.3]", ["[cam_02]", "'distortions'"]),
    (r"^fisheye = .*$", 'fisheye = "no"', ["[cam_02]", "'fisheye'"]),
])
def test_malformed_camera_field(good, pattern, repl, words):
    # edit the second camera table only
    p = good / "calibration.toml"
    head, sep, tail = p.read_text().partition("[cam_02]")
    tail = re.sub(pattern, repl, tail, count=1, flags=re.M)
    p.write_text(head + sep + tail)
    _expect(good, "calibration.toml", *words)


def test_no_camera_and_duplicates(good, cams):
    (good / "calibration.toml").write_text("[metadata]\nerror = 0.1\n")
    _expect(good, "calibration.toml", "no camera table")
    text = calibration_toml(cams).replace('name = "cam_02"', 'name = "cam_01"')
    (good / "calibration.toml").write_text(text)
    _expect(good, "calibration.toml", "cam_01", "'name'")


def test_camera_folder_absent(good):
    import shutil

    shutil.rmtree(good / "silhouettes" / "cam_03")
    _expect(good, "cam_03", "not found")


def test_no_frames_at_all(tmp_path, cams):
    root = write_capture(tmp_path / "c", cams, {})
    for c in cams:
        (root / "silhouettes" / c.name).mkdir(parents=True)
    _expect(root, "silhouettes", "no frame")
    (tmp_path / "d").mkdir()
    (tmp_path / "d" / "calibration.toml").write_text(calibration_toml(cams))
    _expect(tmp_path / "d", "silhouettes/", "images/")


def test_frame_missing_for_one_camera(good):
    (good / "silhouettes" / "cam_02" / "frame_2.png").unlink()
    cap = load_capture(good)                           # a per-frame problem: loading succeeds
    assert cap.frames == ["frame_1", "frame_2", "frame_10"]
    assert cap.options["incomplete_frames"] == {"frame_2": ["cam_02"]}
    _expect("frame_2", "cam_02", "frame_2", "missing", call=cap.silhouettes)
    cap.silhouettes("frame_10")                        # the others still load


def test_wrong_image_size_and_corrupt_image(good):
    p = good / "silhouettes" / "cam_01" / "frame_10.png"
    cv2.imwrite(str(p), np.zeros((100, 150), np.uint8))
    (good / "silhouettes" / "cam_03" / "frame_1.png").write_bytes(b"\x89PNG\r\n\x1a\n garbage")
    cap = load_capture(good)
    _expect("frame_10", "frame_10.png", "150x100", "'size'", "[160, 120]", call=cap.silhouettes)
    _expect("frame_1", "cam_03", "frame_1.png", "corrupt", call=cap.silhouettes)
    cap.silhouettes("frame_2")


@pytest.mark.parametrize("text,words", [
    ("[capture]\n[capture.volume]\nmin = [0, 0, 1]\nmax = [1, 1, 1]\n", ["capture.volume", "'min'", "'max'"]),
    ("[capture]\n[capture.volume]\nmin = [0, 0]\nmax = [1, 1, 1]\n", ["capture.volume", "'min'"]),
    ("[capture.volume]\nmax = [1, 1, 1]\n", ["capture.volume", "'min'"]),
    ('[capture]\nup = "up"\n', ["capture", "'up'"]),
    ("[capture]\nfps = -3\n", ["[capture]", "'fps'"]),
    ('[capture]\nunits = "furlong"\n', ["[capture]", "'units'"]),
    ('[silhouettes]\nmethod = "magic"\n', ["[silhouettes]", "'method'"]),
    ("[silhouettes]\nthreshhold = 3\n", ["[silhouettes]", "'threshhold'"]),
    ("[capture\n", ["capture.toml", "TOML"]),
])
def test_bad_capture_toml(good, text, words):
    (good / "capture.toml").write_text(text)
    _expect(good, "capture.toml", *words)


def test_volume_and_options_read(good):
    (good / "capture.toml").write_text('[capture]\nup = "-y"\nunits = "mm"\n[capture.volume]\n'
                                       'min = [-1, -1, 0]\nmax = [1, 1, 2]\n'
                                       "[silhouettes]\nthreshold = 12\nclose = 0\n")
    cap = load_capture(good)
    assert cap.up == "-y" and np.allclose(cap.up_vector, [0, -1, 0]) and cap.units == "mm"
    assert np.allclose(cap.volume[0], [-1, -1, 0]) and np.allclose(cap.volume[1], [1, 1, 2])
    assert cap.options["silhouettes"]["threshold"] == 12 and cap.options["silhouettes"]["close"] == 0


def test_millimetre_translations_with_metre_units_warn(good, cams):
    p = good / "calibration.toml"
    text = p.read_text()
    for c in cams:
        old = "translation = [" + ", ".join(repr(float(x)) for x in c.translation) + "]"
        new = "translation = [" + ", ".join(repr(float(x) * 1000) for x in c.translation) + "]"
        text = text.replace(old, new)
    p.write_text(text)
    with pytest.warns(UserWarning, match="millimetres"):
        load_capture(good)
    (good / "capture.toml").write_text('[capture]\nunits = "mm"\n')
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        load_capture(good)


def test_images_need_backgrounds(tmp_path, cams, masks):
    ims = {"000000": [np.full((120, 160, 3), 80, np.uint8)] * 3}
    root = write_capture(tmp_path / "i", cams, {}, images=ims)
    _expect(root, "backgrounds", "cam_01")
    write_capture(root, cams, {}, backgrounds=[np.zeros((120, 150, 3), np.uint8)] * 3)
    _expect(root, "cam_01.png", "'size'")


def test_cli_hull_bad_input_exit_2(good, tmp_path, capsys):
    (good / "calibration.toml").unlink()
    assert main(["hull", str(good), "--frame", "0", "--out", str(tmp_path / "v.npz")]) == 2
    err = capsys.readouterr().err
    assert "calibration.toml" in err and "\n" not in err.strip()
