"""The first run: Numba compilation and the thinning look-up tables, said on screen and overlapped.

On a fresh machine (empty Numba and table caches) the first frame compiles every kernel and
builds the 2^26-entry look-up tables (thesis §5.1.2) before it can finish; both are cached on
disk, so it happens once. Two things keep that first frame short and honest:

* :func:`topopose._notices.notices` says what is happening ("compiling kernels…", "building the thinning look-up
  tables…") through a callback (the progress bar), from a Numba compile-event listener and
  from the table builders (:func:`topopose._notices.say`);
* :func:`start_warmup` starts, when the caches are cold, a helper process that builds the
  tables and compiles the tree and alignment kernels (filling the same disk caches) while this
  process compiles the hull and thinning kernels — the two cores work at once. The frame waits
  for the tables before thinning (:meth:`Warmup.wait_tables`) and for the helper before the
  tree stage (:meth:`Warmup.wait_all`), then loads those kernels from the cache.
"""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from topopose._notices import say


def tables_cold() -> bool:
    """True when the D6I1D look-up tables (bit planes, d6 byte table) are not on disk yet."""
    from topopose.topology.tables import cache_dir, table_key

    key = table_key()
    return not all((cache_dir() / f"luts-{key}{s}.npy").exists() for s in ("", "-d6"))


def kernels_cold() -> bool:
    """True when the alignment kernel has no entry in the Numba disk cache (a fresh install or
    an empty ``NUMBA_CACHE_DIR``)."""
    try:
        from topopose.match.align_kernels import align_data

        return not Path(align_data._cache._cache_file._index_path).exists()
    except Exception:       # noqa: BLE001  (a Numba without these internals: assume warm)
        return False


class Warmup:
    """The helper process of :func:`start_warmup` (``proc`` None: nothing to wait for)."""

    def __init__(self, proc):
        self.proc = proc
        self._tables = proc is None

    def wait_tables(self):
        """Block until the helper has written the look-up tables (or ended)."""
        while not self._tables:
            line = self.proc.stdout.readline()
            if not line or line.strip() == b"tables":
                self._tables = True

    def wait_all(self):
        """Block until the helper is done (its kernels are then in the disk cache)."""
        self.wait_tables()
        if self.proc is not None:
            try:
                self.proc.wait(timeout=600)
            except subprocess.TimeoutExpired:
                self.proc.kill()
            self.proc.stdout.close()
            self.proc = None

    def close(self):
        if self.proc is not None:
            self.proc.kill()
            self.proc.wait()
            self.proc.stdout.close()
            self.proc = None


_RUNNING: Warmup | None = None


def start_warmup(force: bool = False) -> Warmup:
    """Start the helper process when the caches are cold (see the module docstring); a helper
    already running (e.g. started by ``topopose demo`` before it synthesizes) is shared."""
    global _RUNNING
    if _RUNNING is not None and _RUNNING.proc is not None and _RUNNING.proc.poll() is None:
        return _RUNNING
    tcold, kcold = tables_cold(), kernels_cold()
    if not force and not (tcold or kcold):
        return Warmup(None)
    if os.environ.get("TOPOPOSE_NO_WARMUP"):
        return Warmup(None)
    say("first run: compiling kernels, building look-up tables (once, ~30 s)…" if tcold else
        "first run: compiling kernels (once, ~20 s)…")
    src = str(Path(__file__).resolve().parents[2])
    env = dict(os.environ)
    env["PYTHONPATH"] = src + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
    import signal

    old = signal.signal(signal.SIGINT, signal.SIG_IGN)   # Ctrl-C reaches this process only
    try:
        proc = subprocess.Popen([sys.executable, "-m", "topopose.batch.warmup"], env=env,
                                stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
                                stdin=subprocess.DEVNULL)
    except OSError:
        return Warmup(None)
    finally:
        signal.signal(signal.SIGINT, old)
    _RUNNING = Warmup(proc)
    return _RUNNING


def _stick_figure():
    """A one-voxel-thick stick figure (a curve skeleton with junctions and ends)."""
    import numpy as np

    s = np.zeros((30, 20, 50), dtype=bool)
    s[15, 10, 5:45] = True                 # spine
    for i in range(10):
        s[15 - i, 10, 5 - min(i, 4)] = True     # legs
        s[15 + i, 10, 5 - min(i, 4)] = True
        s[15 - i, 10, 35] = True           # arms
        s[15 + i, 10, 35] = True
    return s


def _warm_main() -> int:
    """The helper: tables first (then say so), then the tree and alignment kernels."""
    import numpy as np

    from topopose.topology.tables import load_byte_table, load_tables

    load_tables()
    load_byte_table("d6")
    print("tables", flush=True)
    from topopose.match import Matcher
    from topopose.pose import load_model
    from topopose.skeleton import data_tree

    data = data_tree(_stick_figure(), origin=np.zeros(3), voxel_size=0.02, border=None)
    data = data.normalized()
    model = load_model("human")
    Matcher(model.pattern(), method="aha", cut=False, up=np.array([0.0, 0.0, 1.0])).align(data)
    _warm_tracker()
    return 0


def _warm_tracker():
    """The kernels of what the frame loop keeps for the tracker and of the tracker's fit, on a
    two-bone body in a small hull."""
    import numpy as np

    from topopose.hull.volume import Volume
    from topopose.sequence.body import CapsuleBody
    from topopose.sequence.kept import scaled_crop
    from topopose.sequence.tracker import agreement, fit_frame, frame_data

    scaled_crop(np.ones((30, 40), bool), (7, 5))
    occ = np.zeros((12, 12, 20), bool)
    occ[4:8, 4:8, 2:18] = True
    body = CapsuleBody(("a", "b", "c"), np.array([-1, 0, 1]), np.array([np.nan, 0.1, 0.1]),
                       np.array([np.nan, 0.03, 0.03]), (0, 1, 2))
    P = np.array([[0.12, 0.12, 0.36], [0.12, 0.12, 0.26], [0.12, 0.12, 0.16]])
    for n in (50, 10 ** 6):      # points sampled, or all the surface voxels (another layout)
        data = frame_data(Volume(occ, np.zeros(3), 0.02), n)
        agreement(body, data, fit_frame(body, data, P))


if __name__ == "__main__":
    sys.exit(_warm_main())
