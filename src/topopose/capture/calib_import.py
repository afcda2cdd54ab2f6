"""Calibrations as they come: importers to the capture's ``calibration.toml`` (Pose2Sim layout).

``topopose calib import FILE... [--format F] --out calibration.toml`` reads

- ``qualisys``: Qualisys Track Manager's XML export ``*.qca.txt`` (as Pose2Sim's demo ships
  it), read with Pose2Sim's conventions, checked numerically against the ``Calib.toml`` that
  Pose2Sim ships beside it: intrinsics in sub-pixel units of 1/64 px (``focalLengthU`` / 64 =
  fx, ``centerPointU`` / 64 − ``fov_video left`` = cx; the distortion coefficients are divided
  by 64 too, as Pose2Sim does), ``transform`` x, y, z = the camera centre in millimetres (→
  metres), and the rotation ``[r_ij]`` maps world to a camera frame with y up and z backwards:
  world → camera (OpenCV) ``R = diag(1, -1, -1) [r_ij]``, ``t = −R C``. Size from ``fov_video``.
- ``easymocap``: EasyMocap's ``intri.yml`` + ``extri.yml`` (OpenCV FileStorage YAML: ``names``,
  ``K_<name>``, ``dist_<name>``, optional ``H_<name>``/``W_<name>``; ``R_<name>`` (Rodrigues)
  or ``Rot_<name>`` (3×3), ``T_<name>``; world → camera).
- ``opencv``: one OpenCV FileStorage ``.yml``/``.yaml``/``.xml`` per camera (the file stem names
  the camera) with ``camera_matrix`` (or ``cameraMatrix``, ``K``), ``distortion_coefficients``
  (or ``dist_coeffs``, ``distCoeffs``, ``D``), ``rvec`` or ``R`` (Rodrigues or 3×3), ``tvec`` or
  ``T``, and ``image_width``/``image_height`` (or ``--size``).
- ``pmatrix``: one text file per camera holding a 3×4 projection matrix P (12 numbers; words
  such as ``CONTOUR`` are skipped), as Middlebury/DTU/Kinovis-style datasets ship them. The
  camera's name is the file's first token when it is a name (not a number nor such a word),
  else the file's stem, or its folder's name when several files share a stem
  (``cam00/cam_par.txt``, ``cam01/cam_par.txt`` …).
  ``P = s K [R | t]`` is split by an RQ decomposition (``scipy.linalg.rq``) with the signs
  fixed so that K has a positive diagonal and ``det R = +1``; K is scaled so that K[2,2] = 1;
  no lens distortion. The image size comes from ``--size`` or an image (``--image``).

Every problem raises :class:`InputError` naming the file and the field.
"""
from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from pathlib import Path

import cv2
import numpy as np

from topopose.errors import InputError
from topopose.geometry.camera import Camera

FORMATS = ("qualisys", "easymocap", "opencv", "pmatrix")


# --------------------------------------------------------------------------- writing
def calibration_text(cameras) -> str:
    """``calibration.toml`` text (Pose2Sim / aniposelib layout) for ``cameras``, full precision."""

    def vec(v):
        return "[" + ", ".join(repr(float(x)) for x in np.ravel(v)) + "]"

    lines = []
    for c in cameras:
        key = re.sub(r"[^A-Za-z0-9_-]", "_", c.name) or "camera"
        lines += [f"[{key}]", f"name = {_toml_str(c.name)}", f"size = [{c.size[0]}, {c.size[1]}]",
                  "matrix = [" + ", ".join(vec(row) for row in c.matrix) + "]",
                  f"distortions = {vec(c.distortions)}", f"rotation = {vec(c.rotation)}",
                  f"translation = {vec(c.translation)}",
                  f"fisheye = {'true' if c.fisheye else 'false'}", ""]
    return "\n".join(lines)


def _toml_str(s: str) -> str:
    return '"' + s.replace("\\", "\\\\").replace('"', '\\"') + '"'


def write_calibration(cameras, path) -> Path:
    path = Path(path)
    if path.parent and not path.parent.exists():
        path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(calibration_text(cameras))
    return path


def _camera(path, name, size, K, dist, R, t) -> Camera:
    """A checked :class:`Camera` from K, distortions, a world → camera rotation (3×3 or
    Rodrigues) and translation."""
    K = np.asarray(K, dtype=float)
    R = np.asarray(R, dtype=float)
    if R.size == 3:
        R = cv2.Rodrigues(R.reshape(3, 1))[0]
    if K.shape != (3, 3) or not np.all(np.isfinite(K)) or abs(np.linalg.det(K)) < 1e-12:
        raise InputError(f"{path}: camera {name!r}: the intrinsic matrix is not an invertible 3×3 "
                         f"matrix ({K.tolist()})")
    if R.shape != (3, 3) or not np.allclose(R @ R.T, np.eye(3), atol=1e-5) or np.linalg.det(R) < 0:
        raise InputError(f"{path}: camera {name!r}: the rotation is not a rotation matrix")
    d = np.asarray(dist, dtype=float).ravel()
    if d.size > 5 and np.any(d[5:] != 0):
        raise InputError(f"{path}: camera {name!r}: distortion coefficients beyond k3 "
                         f"({d.size} values) are not supported")
    if d.size < 4:
        d = np.r_[d, np.zeros(4 - d.size)]
    d = d[:5]
    if size is None:
        raise InputError(f"{path}: camera {name!r}: no image size in the file; give --size WxH "
                         f"or --image IMAGE")
    return Camera(str(name), (int(size[0]), int(size[1])), K, d,
                  cv2.Rodrigues(R)[0].ravel(), np.asarray(t, dtype=float).reshape(3))


# --------------------------------------------------------------------------- Qualisys
def _attr(path, cam, tag, key) -> float:
    if tag is None:
        raise InputError(f"{path}: camera {cam!r}: missing element <{key.split('.')[0]}>")
    v = tag.attrib.get(key.split(".")[-1])
    try:
        return float(v)
    except (TypeError, ValueError):
        raise InputError(f"{path}: camera {cam!r}: field '{key}' must be a number, "
                         f"got {v!r}") from None


def read_qualisys(path) -> list:
    """Cameras of a Qualisys ``.qca.txt`` XML calibration (conventions in the module docstring)."""
    path = Path(path)
    try:
        root = ET.fromstring(path.read_bytes())
    except OSError as exc:
        raise InputError(f"{path}: cannot read the file ({exc.strerror or exc})") from None
    except ET.ParseError as exc:
        raise InputError(f"{path}: not valid XML ({exc})") from None
    tags = root.findall("cameras/camera")
    if not tags:
        raise InputError(f"{path}: no <cameras><camera> element (not a Qualisys .qca.txt file)")
    cams = []
    for k, tag in enumerate(tags):
        name = tag.attrib.get("serial") or f"cam{k + 1:02d}"
        res = tag.attrib.get("video_resolution")
        zoom = 1.0
        if res not in (None, "", "N/A", "none"):
            try:
                zoom = int(str(res).rstrip("pP")) / 1080.0      # Pose2Sim: marker → video pixels
            except ValueError:
                raise InputError(f"{path}: camera {name!r}: field 'video_resolution' must be like "
                                 f"\"1080p\", got {res!r}") from None
        fov, tr, it = tag.find("fov_video"), tag.find("transform"), tag.find("intrinsic")
        left, top = _attr(path, name, fov, "fov_video.left"), _attr(path, name, fov, "fov_video.top")
        w = (_attr(path, name, fov, "fov_video.right") - left + 1) * zoom
        h = (_attr(path, name, fov, "fov_video.bottom") - top + 1) * zoom
        q = {a: _attr(path, name, it, f"intrinsic.{a}") for a in
             ("focalLengthU", "focalLengthV", "centerPointU", "centerPointV", "radialDistortion1",
              "radialDistortion2", "tangentalDistortion1", "tangentalDistortion2")}
        k3 = float(it.attrib.get("radialDistortion3", 0) or 0)
        K = [[q["focalLengthU"] / 64 * zoom, 0.0, (q["centerPointU"] / 64 - left) * zoom],
             [0.0, q["focalLengthV"] / 64 * zoom, (q["centerPointV"] / 64 - top) * zoom],
             [0.0, 0.0, 1.0]]
        dist = np.array([q["radialDistortion1"], q["radialDistortion2"], q["tangentalDistortion1"],
                         q["tangentalDistortion2"]] + ([k3] if k3 else [])) / 64
        Rq = np.array([[_attr(path, name, tr, f"transform.r{i}{j}") for j in (1, 2, 3)]
                       for i in (1, 2, 3)])
        C = np.array([_attr(path, name, tr, f"transform.{a}") for a in "xyz"]) / 1000.0
        R = np.diag([1.0, -1.0, -1.0]) @ Rq
        cams.append(_camera(path, name, (round(w), round(h)), K, dist, R, -R @ C))
    return cams


# --------------------------------------------------------------------------- FileStorage
def _storage(path: Path):
    if not path.is_file():
        raise InputError(f"{path}: calibration file not found")
    try:
        fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
        ok = fs.isOpened()
    except Exception:                         # cv2.error wrapped in SystemError
        ok = False
    if not ok:
        raise InputError(f"{path}: not a readable OpenCV FileStorage file (YAML or XML)")
    return fs


def _mat(fs, path, names, what, cam=None, required=True):
    for n in names:
        node = fs.getNode(n)
        if not node.empty():
            m = None
            if node.isMap():                   # !!opencv-matrix
                try:
                    m = node.mat()
                except cv2.error:
                    m = None
            elif node.isSeq():                 # a plain sequence of numbers
                items = [node.at(i) for i in range(node.size())]
                if all(it.isReal() or it.isInt() for it in items):
                    m = np.array([it.real() for it in items])
            elif node.isReal() or node.isInt():
                m = np.array([node.real()])
            if m is None:
                raise InputError(f"{path}: field '{n}' is not a matrix")
            m = np.asarray(m, dtype=float)
            if not np.all(np.isfinite(m)):
                raise InputError(f"{path}: field '{n}' has non-finite values")
            return m
    if required:
        who = f" of camera {cam!r}" if cam is not None else ""
        raise InputError(f"{path}: missing field '{names[0]}' ({what}{who})")
    return None


def _shape(path, field, m, sizes):
    if m.size not in sizes:
        raise InputError(f"{path}: field '{field}' must have {' or '.join(map(str, sizes))} "
                         f"values, got shape {m.shape}")
    return m


def _names(fs, path) -> list:
    node = fs.getNode("names")
    if node.empty() or not node.isSeq():
        raise InputError(f"{path}: missing field 'names' (the list of camera names)")
    return [node.at(i).string() or str(int(node.at(i).real())) for i in range(node.size())]


def read_easymocap(intri, extri, size=None) -> list:
    """Cameras of EasyMocap's ``intri.yml`` and ``extri.yml``."""
    intri, extri = Path(intri), Path(extri)
    fi, fe = _storage(intri), _storage(extri)
    names = _names(fi, intri)
    cams = []
    for n in names:
        K = _shape(intri, f"K_{n}", _mat(fi, intri, [f"K_{n}"], "intrinsic matrix", n), (9,))
        d = _mat(fi, intri, [f"dist_{n}", f"D_{n}"], "distortions", n, required=False)
        H = _mat(fi, intri, [f"H_{n}"], "height", n, required=False)
        W = _mat(fi, intri, [f"W_{n}"], "width", n, required=False)
        Rm = _mat(fe, extri, [f"Rot_{n}"], "rotation", n, required=False)
        if Rm is None:
            Rm = _shape(extri, f"R_{n}", _mat(fe, extri, [f"R_{n}"], "rotation", n), (3, 9))
        else:
            Rm = _shape(extri, f"Rot_{n}", Rm, (9,))
        T = _shape(extri, f"T_{n}", _mat(fe, extri, [f"T_{n}"], "translation", n), (3,))
        sz = (int(W.ravel()[0]), int(H.ravel()[0])) if W is not None and H is not None else size
        cams.append(_camera(intri, n, sz, K.reshape(3, 3), np.zeros(4) if d is None else d,
                            Rm.reshape(3, 3) if Rm.size == 9 else Rm, T))
    fi.release()
    fe.release()
    return cams


def read_opencv(path, size=None) -> Camera:
    """One camera from an OpenCV FileStorage file (the file stem names it)."""
    path = Path(path)
    fs = _storage(path)
    K = _shape(path, "camera_matrix", _mat(fs, path, ["camera_matrix", "cameraMatrix", "K",
                                                      "intrinsic_matrix"], "intrinsic matrix"), (9,))
    d = _mat(fs, path, ["distortion_coefficients", "dist_coeffs", "distCoeffs", "D",
                        "distortion"], "distortions", required=False)
    R = _shape(path, "rvec", _mat(fs, path, ["rvec", "R", "rotation", "rotation_matrix"],
                                  "rotation, world → camera"), (3, 9))
    t = _shape(path, "tvec", _mat(fs, path, ["tvec", "T", "translation"],
                                  "translation, world → camera"), (3,))
    w = _mat(fs, path, ["image_width"], "width", required=False)
    h = _mat(fs, path, ["image_height"], "height", required=False)
    s = _mat(fs, path, ["image_size", "imageSize"], "size", required=False)
    fs.release()
    sz = size
    if w is not None and h is not None:
        sz = (int(w.ravel()[0]), int(h.ravel()[0]))
    elif s is not None and s.size == 2:
        sz = (int(s.ravel()[0]), int(s.ravel()[1]))
    return _camera(path, path.name.split(".")[0], sz, K.reshape(3, 3),
                   np.zeros(4) if d is None else d, R.reshape(3, 3) if R.size == 9 else R, t)


# --------------------------------------------------------------------------- P matrices
def decompose_projection(P) -> tuple:
    """``P = s K [R | t]`` → (K with K[2,2] = 1 and a positive diagonal, R with det +1, t)."""
    from scipy.linalg import rq

    P = np.asarray(P, dtype=float).reshape(3, 4)
    if np.linalg.det(P[:, :3]) < 0:           # P is defined up to scale: make det(M) > 0
        P = -P
    K, R = rq(P[:, :3])
    D = np.diag(np.sign(np.diag(K)))
    K, R = K @ D, D @ R                       # D² = I: K R unchanged, diag(K) > 0
    t = np.linalg.solve(K, P[:, 3])
    return K / K[2, 2], R, t


#: words of P-matrix files that are no camera name (DTU / Middlebury headers)
_PMATRIX_WORDS = {"contour", "p", "p:", "projection", "matrix", "camera"}


def pmatrix_name(path) -> str | None:
    """The camera name a P-matrix file gives (its first token, when that is neither a number
    nor a format word such as ``CONTOUR``), or None."""
    try:
        toks = Path(path).read_text().replace(",", " ").split()
    except (OSError, UnicodeDecodeError):
        return None
    if not toks:
        return None
    try:
        float(toks[0])
        return None
    except ValueError:
        return None if toks[0].lower() in _PMATRIX_WORDS else toks[0]


def read_pmatrix(path, size=None, name=None) -> Camera:
    """One camera from a text file holding a 3×4 projection matrix, named ``name`` (default:
    the name the file gives, :func:`pmatrix_name`, else its stem)."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: calibration file not found")
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"{path}: cannot read the file as text ({exc})") from None
    nums = []
    for tok in text.replace(",", " ").split():
        try:
            nums.append(float(tok))
        except ValueError:
            continue                          # words such as CONTOUR
    if len(nums) != 12 or not np.all(np.isfinite(nums)):
        raise InputError(f"{path}: field 'P' must be a 3×4 projection matrix (12 numbers), "
                         f"found {len(nums)} numbers")
    P = np.array(nums).reshape(3, 4)
    if abs(np.linalg.det(P[:, :3])) < 1e-300 or np.linalg.matrix_rank(P[:, :3]) < 3:
        raise InputError(f"{path}: field 'P': the left 3×3 block of the projection matrix is singular")
    K, R, t = decompose_projection(P)
    if name is None:
        name = pmatrix_name(path) or path.name.split(".")[0]
    return _camera(path, name, size, K, np.zeros(4), R, t)


def pmatrix_names(files) -> list:
    """The camera name of each P-matrix file: the one it gives (:func:`pmatrix_name`), else its
    stem, else (several files of one stem) its folder's name."""
    given = [pmatrix_name(f) for f in files]
    stems = [f.name.split(".")[0] for f in files]
    return [g if g is not None else
            (f.parent.name if stems.count(st) > 1 and f.parent.name else st)
            for f, g, st in zip(files, given, stems)]


# --------------------------------------------------------------------------- detection, CLI
def detect_format(path) -> str:
    """Guess the format of a calibration file from its name and first bytes."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: calibration file not found")
    name = path.name.lower()
    head = path.read_bytes()[:4096].decode("utf-8", errors="replace")
    if name.endswith(".qca.txt") or ("<calibration" in head and "<cameras" in head):
        return "qualisys"
    if name.endswith((".yml", ".yaml", ".xml")) or head.lstrip().startswith(("%YAML", "<?xml")):
        if re.search(r"^\s*(names|K_\w+|Rot_\w+|R_\w+|T_\w+)\s*:", head, re.M) or "<names>" in head:
            return "easymocap"
        return "opencv"
    return "pmatrix"


def import_calibration(files, format: str | None = None, size=None) -> list:
    """Cameras from calibration files of one format (auto-detected when None).

    ``size`` (w, h) is used when the files give none (P matrices, OpenCV files without
    image_width/height).
    """
    files = [Path(f) for f in files]
    if not files:
        raise InputError("calib import: give at least one calibration file")
    if format is None:
        fmts = {detect_format(f) for f in files}
        if len(fmts) > 1:
            raise InputError(f"calib import: the files look like different formats "
                             f"({', '.join(sorted(fmts))}); give --format")
        format = fmts.pop()
    if format not in FORMATS:
        raise InputError(f"--format: must be one of {', '.join(FORMATS)}, got {format!r}")
    if format == "qualisys":
        cams = [c for f in files for c in read_qualisys(f)]
    elif format == "easymocap":
        if len(files) == 1 and files[0].is_dir():
            files = [files[0] / "intri.yml", files[0] / "extri.yml"]
        intri = [f for f in files if "intri" in f.name.lower()]
        extri = [f for f in files if "extri" in f.name.lower()]
        if len(files) != 2 or len(intri) != 1 or len(extri) != 1:
            raise InputError("calib import --format easymocap: give intri.yml and extri.yml "
                             f"(or their folder), got {', '.join(map(str, files))}")
        cams = read_easymocap(intri[0], extri[0], size)
    elif format == "opencv":
        cams = [read_opencv(f, size) for f in files]
    else:
        cams = [read_pmatrix(f, size, n) for f, n in zip(files, pmatrix_names(files))]
    names = [c.name for c in cams]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise InputError(f"calib import: camera name(s) {dup} appear twice (one file per camera, "
                         f"named after the camera, or in a folder named after it)")
    return cams
