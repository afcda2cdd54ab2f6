"""Ctrl-C during `topopose run --workers 2` (no wall of Dask tracebacks): one line,
exit 130, no traceback, and the frames done so far are kept in the output."""
import os
import re
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

SRC = str(Path(__file__).resolve().parents[1] / "src")

DRIVER = r"""
import importlib, signal, sys
# a test started in the background by a non-interactive shell inherits SIGINT ignored (POSIX);
# a terminal's Ctrl-C reaches a foreground process whose Python turns it into KeyboardInterrupt
signal.signal(signal.SIGINT, signal.default_int_handler)
R = importlib.import_module("topopose.batch.run")
R.MIN_FRAMES_PER_WORKER = 0            # use the workers even for this small capture
from topopose.cli import main
sys.exit(main(sys.argv[1:]))
"""


@pytest.mark.slow
def test_ctrl_c_with_workers_is_one_line(tmp_path):
    from topopose.synth import synthesize

    N = 160      # long enough that the run is still going when Ctrl-C comes (7–20 frames/s)

    cap = synthesize(tmp_path / "cap", subject="human", frames=N, seed=2, cameras=6,
                     size=(240, 180), separated=True)
    out = tmp_path / "p.jsonl"
    env = dict(os.environ, PYTHONPATH=SRC)
    p = subprocess.Popen([sys.executable, "-c", DRIVER, "run", str(cap), "--workers", "2",
                          "--resolution", "260", "--output", str(out)], env=env,
                         stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, start_new_session=True)
    chunks = []                            # stderr as it comes (the progress bar: "k/N [")

    def pump():
        while b := os.read(p.stderr.fileno(), 4096):
            chunks.append(b)

    reader = threading.Thread(target=pump, daemon=True)
    reader.start()
    partial = tmp_path / "p.jsonl.partial"
    t0 = time.time()
    while time.time() - t0 < 120:          # wait for 3 frames done (cluster up and working)
        done = re.findall(rf"(\d+)/{N} \[", b"".join(chunks).decode(errors="replace"))
        if done and max(map(int, done)) >= 3:
            break
        if p.poll() is not None:
            break
        time.sleep(0.05)
    assert p.poll() is None, "the run ended before it could be interrupted"
    os.killpg(p.pid, signal.SIGINT)        # Ctrl-C reaches the whole process group
    p.wait(timeout=120)
    reader.join(timeout=30)
    err = b"".join(chunks)
    err = err.decode().replace("\r", "\n")
    assert "faster in this process" not in err               # the Dask workers did run
    lines = [x for x in err.splitlines() if x.strip() and "frame/s" not in x and f"/{N} [" not in x]
    assert p.returncode == 130, err[-2000:]
    assert "Traceback" not in err and lines == ["topopose: interrupted"], err[-2000:]
    from topopose.pose import read_poses

    assert len(read_poses(out)) >= 1 and not partial.exists()      # nothing computed is lost
