"""Calibration importers: each format → calibration.toml → read back → projections equal to
projections computed directly from the known cameras (cv2.projectPoints, or P·X for P matrices)
to 1e-6 px; the shipped Qualisys file against Pose2Sim's own conversion of it (Calib.toml)."""
from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from _capture_testutils import capsule_masks, ring, write_capture
from topopose.capture import load_capture, read_calibration
from topopose.capture.calib_import import (decompose_projection, detect_format,
                                           import_calibration, write_calibration)
from topopose.cli import main
from topopose.errors import InputError

DATA = Path(__file__).parent / "data"
PTS = np.random.default_rng(5).uniform([-1, -1, 0], [1, 1, 2], (300, 3))


@pytest.fixture(scope="module")
def known():
    """Cameras with distinct fx/fy, off-centre principal points and lens distortion."""
    cams = ring(n=3, size=(640, 480), f=700, dist=(-0.12, 0.05, 0.001, -0.002, 0.01))
    for k, c in enumerate(cams):
        c.matrix[0, 0] *= 1.0 + 0.03 * k
        c.matrix[1, 2] += 7 * k
    return cams


def direct(cam, pts=PTS):
    """Oracle: OpenCV's own projection of the original parameters."""
    return cv2.projectPoints(pts, cam.rotation, cam.translation, cam.matrix, cam.distortions)[0].reshape(-1, 2)


def round_trip(cams, tmp_path):
    out = write_calibration(cams, tmp_path / "calibration.toml")
    return read_calibration(out)


def assert_same_projections(got, want, tol=1e-6):
    assert [c.name for c in got] == [c.name for c in want]
    for a, b in zip(got, want):
        assert a.size == b.size
        pa, pb = a.project(PTS), direct(b)
        assert np.nanmax(np.abs(pa - pb)) < tol, (a.name, np.nanmax(np.abs(pa - pb)))


def test_easymocap(tmp_path, known):
    fi = cv2.FileStorage(str(tmp_path / "intri.yml"), cv2.FILE_STORAGE_WRITE)
    fe = cv2.FileStorage(str(tmp_path / "extri.yml"), cv2.FILE_STORAGE_WRITE)
    fi.write("names", [c.name for c in known])
    fe.write("names", [c.name for c in known])
    for k, c in enumerate(known):
        fi.write(f"K_{c.name}", c.matrix)
        fi.write(f"dist_{c.name}", c.distortions.reshape(1, 5))
        fi.write(f"H_{c.name}", c.size[1])
        fi.write(f"W_{c.name}", c.size[0])
        fe.write(f"R_{c.name}", c.rotation.reshape(3, 1))
        if k == 1:                               # EasyMocap also writes Rot_ (3×3): preferred
            fe.write(f"Rot_{c.name}", c.R)
        fe.write(f"T_{c.name}", c.translation.reshape(3, 1))
    fi.release()
    fe.release()
    assert detect_format(tmp_path / "intri.yml") == "easymocap"
    cams = import_calibration([tmp_path / "extri.yml", tmp_path / "intri.yml"])
    assert_same_projections(round_trip(cams, tmp_path), known)
    cams = import_calibration([tmp_path], "easymocap")          # the folder
    assert_same_projections(cams, known)


@pytest.mark.parametrize("ext", [".yml", ".xml"])
def test_opencv_filestorage(tmp_path, known, ext):
    files = []
    for k, c in enumerate(known):
        p = tmp_path / f"{c.name}{ext}"
        fs = cv2.FileStorage(str(p), cv2.FILE_STORAGE_WRITE)
        fs.write("camera_matrix", c.matrix)
        fs.write("distortion_coefficients", c.distortions.reshape(5, 1))
        if k == 0:
            fs.write("R", c.R)
        else:
            fs.write("rvec", c.rotation.reshape(3, 1))
        fs.write("tvec", c.translation.reshape(3, 1))
        if k < 2:
            fs.write("image_width", c.size[0])
            fs.write("image_height", c.size[1])
        fs.release()
        files.append(p)
    assert {detect_format(f) for f in files} == {"opencv"}
    with pytest.raises(InputError, match=r"cam_03.*no image size.*--size"):
        import_calibration(files)
    cams = import_calibration(files, size=(640, 480))
    assert_same_projections(round_trip(cams, tmp_path), known)


def test_pmatrix(tmp_path, known):
    cams0 = [c for c in known]
    files = []
    for k, c in enumerate(cams0):
        c = type(c)(c.name, c.size, c.matrix.copy(), np.zeros(4), c.rotation, c.translation)
        c.matrix[0, 1] = 0.5 * k                     # a skew survives the decomposition
        cams0[k] = c
        P = c.matrix @ np.c_[c.R, c.translation]
        P *= (-1) ** k * (0.01 + 3 * k)              # any scale, negative too
        p = tmp_path / f"{c.name}.txt"
        p.write_text(("CONTOUR\n" if k == 2 else "") +
                     "\n".join(" ".join(repr(float(x)) for x in row) for row in P) + "\n")
        files.append(p)
        K, R, t = decompose_projection(P)
        assert np.allclose(K, c.matrix, atol=1e-9) and np.allclose(R, c.R, atol=1e-12)
        assert np.allclose(t, c.translation, atol=1e-12)
    assert detect_format(files[0]) == "pmatrix"
    cams = round_trip(import_calibration(files, size=(640, 480)), tmp_path)
    for a, c, f in zip(cams, cams0, files):
        P = np.loadtxt(f, comments="C")
        h = np.c_[PTS, np.ones(len(PTS))] @ P.T
        want = h[:, :2] / h[:, 2:]                  # oracle: P X, no lens
        assert np.max(np.abs(a.project(PTS) - want)) < 1e-6
        if c.matrix[0, 1] == 0:                     # cv2.projectPoints ignores a skew
            assert np.max(np.abs(a.project(PTS) - direct(c))) < 1e-6


def test_qualisys_reproduces_pose2sim(tmp_path):
    """The shipped Calib.qca.txt against Calib.toml (Pose2Sim's conversion of the same file)."""
    cams = round_trip(import_calibration([DATA / "Calib.qca.txt"]), tmp_path)
    ref = read_calibration(DATA / "Calib.toml")
    assert [c.name for c in cams] == ["cam01", "cam02", "cam03", "cam04"]
    for a, b in zip(cams, ref):
        assert a.size == b.size == (1088, 1920)
        err = np.nanmax(np.abs(a.project(PTS) - direct(b)))
        assert err < 1e-6, err


def _qca(cams, path):
    """Write ``cams`` as a .qca.txt (the inverse of the importer's conventions)."""
    rows = []
    for c in cams:
        Rq = (np.diag([1.0, -1.0, -1.0]) @ c.R).tolist()
        C = (c.center * 1000).tolist()
        K, d = (c.matrix * 64).tolist(), (c.distortions * 64).tolist()
        tr = " ".join(f'r{i + 1}{j + 1}="{Rq[i][j]!r}"' for i in range(3) for j in range(3))
        rows.append(f'''<camera serial="{c.name}" active="1">
 <fov_video left="0" top="0" right="{c.size[0] - 1}" bottom="{c.size[1] - 1}"/>
 <transform {tr} x="{C[0]!r}" y="{C[1]!r}" z="{C[2]!r}"/>
 <intrinsic focalLengthU="{K[0][0]!r}" focalLengthV="{K[1][1]!r}" centerPointU="{K[0][2]!r}"
  centerPointV="{K[1][2]!r}" radialDistortion1="{d[0]!r}" radialDistortion2="{d[1]!r}"
  radialDistortion3="{d[4]!r}" tangentalDistortion1="{d[2]!r}" tangentalDistortion2="{d[3]!r}"/>
</camera>''')
    path.write_text("<?xml version='1.0'?>\n<calibration><cameras>\n" + "\n".join(rows) +
                    "\n</cameras></calibration>\n")
    return path


def test_qualisys_exact_round_trip(tmp_path, known):
    p = _qca(known, tmp_path / "mine.qca.txt")
    assert detect_format(p) == "qualisys"
    assert_same_projections(round_trip(import_calibration([p]), tmp_path), known)


def test_cli_writes_a_calibration_load_capture_accepts(tmp_path, capsys):
    out = tmp_path / "cap" / "calibration.toml"
    out.parent.mkdir()                               # no folder is made silently
    assert main(["calib", "import", str(DATA / "Calib.qca.txt"), "--out", str(out)]) == 0
    assert "4 cameras" in capsys.readouterr().out
    cams = read_calibration(out)
    masks = capsule_masks(cams, (0, 0, 0.6), (0, 0, 1.4), 0.2)
    root = write_capture(tmp_path / "cap2", cams, {"000000": masks})
    out.replace(root / "calibration.toml")          # the imported file itself, not a rewrite
    cap = load_capture(root)
    assert [c.name for c in cap.cameras] == ["cam01", "cam02", "cam03", "cam04"]
    assert all(m.any() for m in cap.silhouettes(0))


@pytest.mark.parametrize("fmt, text, words", [
    ("qualisys", "<calibration><cameras><camera serial='c1'><fov_video left='0' top='0' "
     "right='9' bottom='9'/><transform r11='x'/></camera></cameras></calibration>",
     ["bad.txt", "c1", "intrinsic"]),
    ("qualisys", "<calibration><cameras>", ["bad.txt", "XML"]),
    ("pmatrix", "1 2 3\n4 5 6\n", ["bad.txt", "'P'", "12 numbers"]),
    ("easymocap", None, ["intri.yml"]),
    ("opencv", "%YAML:1.0\n---\ncamera_matrix: [1, 0]\n", ["bad.txt", "camera_matrix"]),
])
def test_bad_calibration_files_exit_2(tmp_path, capsys, fmt, text, words):
    p = tmp_path / "bad.txt"
    if text is not None:
        p.write_text(text)
    files = [str(p)] if fmt != "easymocap" else [str(p), str(tmp_path / "intri.yml")]
    if fmt == "easymocap":
        (tmp_path / "intri.yml").write_text("%YAML:1.0\n---\nnames: [a]\n")
        p.write_text("%YAML:1.0\n---\nnames: [a]\n")
        files = [str(tmp_path / "intri.yml"), str(tmp_path / "extri.yml")]
        (tmp_path / "extri.yml").write_text("%YAML:1.0\n---\nnames: [a]\n")
    assert main(["calib", "import", *files, "--format", fmt, "--out", str(tmp_path / "o.toml")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and err.startswith("topopose: error:")
    for w in words:
        assert w in err, (w, err)
    if fmt == "easymocap":
        assert "K_a" in err


def _pmatrix_text(cam, name=None) -> str:
    P = cam.matrix @ np.c_[cam.R, cam.translation]
    return (f"{name} " if name else "") + " ".join(repr(float(x)) for x in P.ravel()) + "\n"


@pytest.mark.parametrize("named", [True, False])
def test_pmatrix_files_of_one_name_in_camera_folders(tmp_path, capsys, named):
    """Ten ``camXX/cam_par.txt`` files (one name for all, beside the masks): one call imports
    them, each camera named by its file's first token, or else by its folder; the capture
    loads, and its cameras project as the P matrices do."""
    cams = [type(c)(c.name, c.size, c.matrix, np.zeros(4), c.rotation, c.translation)
            for c in ring(n=4, size=(320, 240), f=400)]
    folders = [f"view{k}" for k in range(len(cams))]
    files = []
    for c, d in zip(cams, folders):
        (tmp_path / d).mkdir()
        f = tmp_path / d / "cam_par.txt"
        f.write_text(_pmatrix_text(c, c.name if named else None))
        files.append(f)
    out = tmp_path / "cap" / "calibration.toml"
    out.parent.mkdir()
    assert main(["calib", "import", *map(str, files), "--size", "320x240", "--out", str(out)]) == 0
    want = [c.name for c in cams] if named else folders
    said = capsys.readouterr().out
    assert f"{len(cams)} cameras ({', '.join(want)})" in said
    # a camera whose file lies in a folder of another name: said, with the folder
    assert (f"{cams[0].name} ← {tmp_path / folders[0]}" in said) == named
    got = read_calibration(out)
    assert [c.name for c in got] == want
    for a, c in zip(got, cams):
        assert np.max(np.abs(a.project(PTS) - c.project(PTS))) < 1e-6


def test_pmatrix_same_stem_same_folder_name_is_refused(tmp_path):
    """Two files whose stems and folders cannot tell their cameras apart: one line, exit 2."""
    c = ring(n=1, size=(320, 240), f=400, dist=(0, 0, 0, 0))[0]
    files = []
    for d in ("a/x", "b/x"):
        (tmp_path / d).mkdir(parents=True)
        f = tmp_path / d / "P.txt"
        f.write_text(_pmatrix_text(c))
        files.append(f)
    with pytest.raises(InputError, match="appear twice"):
        import_calibration(files, size=(320, 240))
