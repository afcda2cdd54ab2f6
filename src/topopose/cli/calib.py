"""`topopose calib import`: other calibration formats to calibration.toml."""
from __future__ import annotations

from pathlib import Path

import cv2

from topopose.capture.calib_import import import_calibration, write_calibration
from topopose.errors import InputError


def calib_import_cli(a) -> int:
    """``topopose calib import FILE... [--format F] [--size WxH | --image IMG] --out FILE``."""
    from topopose import _paths
    from topopose.capture.calibration import read_calibration

    out = _paths.writable_output(a.out, "--out", inputs=[*(("FILE", f) for f in a.files),
                                                         ("--image", getattr(a, "image", None))])
    size = a.size
    if getattr(a, "image", None):
        img = cv2.imread(str(a.image), cv2.IMREAD_UNCHANGED)
        if img is None:
            raise InputError(f"--image {a.image}: unreadable image")
        size = (img.shape[1], img.shape[0])
    cams = import_calibration(a.files, a.format, size)
    with _paths.atomic_output(out, "--out") as tmp:
        write_calibration(cams, tmp)
        try:
            read_calibration(tmp)             # what load_capture will read
        except InputError as exc:             # the message names the file the user asked for
            raise InputError(str(exc).replace(str(tmp), str(out))) from None
    print(f"wrote {out}: {len(cams)} cameras ({', '.join(c.name for c in cams)})")
    if len(a.files) == len(cams):             # one file per camera: where each one lies
        moved = [(c.name, Path(f).parent) for c, f in zip(cams, a.files)
                 if Path(f).parent.name not in ("", ".") and Path(f).parent.name != c.name
                 and Path(f).name.split(".")[0] != c.name]
        if moved:
            print("note: these cameras' files lie in folders of other names; their masks "
                  "belong under silhouettes/<camera>: "
                  + ", ".join(f"{n} ← {d}" for n, d in moved))
    return 0
