"""Ctrl-C in the tests: a command run in a child process, SIGINT sent once its progress bar
shows some frames done."""
import os
import re
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

SRC = str(Path(__file__).resolve().parents[1] / "src")


def interrupt(driver: str, argv, n: int, after: int = 2, group: bool = False,
              timeout: float = 120) -> tuple:
    """Run ``python -c driver argv...`` (``PYTHONPATH`` the worktree's ``src``); once its
    progress bar on standard error shows ``after`` of ``n`` frames done, send SIGINT (to its
    whole process group with ``group``, as a terminal's Ctrl-C reaches worker processes).

    Returns (exit status, standard error as text with carriage returns made line ends).
    """
    env = dict(os.environ, PYTHONPATH=SRC)
    p = subprocess.Popen([sys.executable, "-c", driver, *map(str, argv)], env=env,
                         stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                         start_new_session=group)
    chunks = []

    def pump():
        while b := os.read(p.stderr.fileno(), 4096):
            chunks.append(b)

    reader = threading.Thread(target=pump, daemon=True)
    reader.start()
    t0 = time.time()
    while time.time() - t0 < timeout and p.poll() is None:
        done = re.findall(rf"(\d+)/{n} \[", b"".join(chunks).decode(errors="replace"))
        if done and max(map(int, done)) >= after:
            break
        time.sleep(0.05)
    assert p.poll() is None, ("the run ended before it could be interrupted",
                              b"".join(chunks).decode(errors="replace")[-2000:])
    if group:
        os.killpg(p.pid, signal.SIGINT)
    else:
        p.send_signal(signal.SIGINT)
    p.wait(timeout=timeout)
    reader.join(timeout=30)
    return p.returncode, b"".join(chunks).decode(errors="replace").replace("\r", "\n")
