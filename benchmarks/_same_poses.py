"""Two poses files compared field by field, timings excluded: the frames whose every other field
(status, distance, parts, joints, error, diagnostics, header) is equal, and the fields that
differ where not.

    python benchmarks/same_poses.py OLD.jsonl NEW.jsonl

Used to show that a change of speed leaves the per-frame results identical (the old and the
new code run on the same capture). Exit 0 when the files agree, 1 when they differ.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path


def _records(path: Path) -> tuple:
    header, frames = None, {}
    for line in Path(path).read_text().splitlines():
        if not line.strip():
            continue
        d = json.loads(line)
        if "frame" not in d:
            header = d
            continue
        d.pop("timings_ms", None)
        frames[d["frame"]] = d
    return header, frames


def _diff(a, b, where="") -> list:
    """Paths where ``a`` and ``b`` differ (exact equality of the JSON values)."""
    if isinstance(a, dict) and isinstance(b, dict):
        out = []
        for k in sorted(set(a) | set(b)):
            if k not in a or k not in b:
                out.append(f"{where}/{k} (only in {'new' if k in b else 'old'})")
            else:
                out += _diff(a[k], b[k], f"{where}/{k}")
        return out
    if isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
        return [x for i, (u, v) in enumerate(zip(a, b)) for x in _diff(u, v, f"{where}[{i}]")]
    return [] if a == b else [where or "/"]


def compare(old: Path, new: Path) -> dict:
    """``{"frames", "identical", "differ": {frame: [paths]}, "missing", "header"}``."""
    ho, fo = _records(old)
    hn, fn = _records(new)
    for h in (ho, hn):
        if h is not None:
            h.pop("topopose", None)
    differ = {f: d for f in fo if f in fn for d in [_diff(fo[f], fn[f])] if d}
    return {"frames": len(fo), "identical": sum(f in fn for f in fo) - len(differ),
            "differ": differ, "missing": sorted(set(fo) ^ set(fn)),
            "header": _diff(ho or {}, hn or {})}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("old")
    ap.add_argument("new")
    a = ap.parse_args(argv)
    for p in (a.old, a.new):
        if not Path(p).is_file():
            print(f"{p}: poses file not found")
            return 2
    r = compare(Path(a.old), Path(a.new))
    print(f"{r['identical']} of {r['frames']} frames identical (timings excluded); "
          f"{len(r['differ'])} differ; {len(r['missing'])} in one file only; header "
          f"{'equal' if not r['header'] else 'differs: ' + ', '.join(r['header'])}")
    for f, paths in list(r["differ"].items())[:10]:
        print(f"  {f}: {', '.join(paths[:6])}{' …' if len(paths) > 6 else ''}")
    return 0 if not r["differ"] and not r["missing"] and not r["header"] else 1


if __name__ == "__main__":
    sys.exit(main())
