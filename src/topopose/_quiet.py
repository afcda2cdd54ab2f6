"""Quiet runs: third-party log noise silenced, topopose's own warnings one line each.

MediaPipe (its TensorFlow Lite and absl C++ logging) writes to the process's standard error
when a graph is built and first run, below Python, where no logging setting reaches it:
:func:`native_stderr_silenced` points file descriptor 2 at ``/dev/null`` for that moment.
:func:`one_line_warnings` prints topopose's own ``UserWarning``\\ s as one line
(``topopose: warning: ...``) and drops the warnings of other packages (deprecations,
``RuntimeWarning``\\ s of numerical libraries) for the duration of a command.
"""
from __future__ import annotations

import os
import sys
import threading
import warnings
from contextlib import contextmanager
from pathlib import Path

_LOCK = threading.Lock()
_STATE = {"depth": 0, "saved": None}
_PACKAGE = str(Path(__file__).resolve().parent)


@contextmanager
def native_stderr_silenced():
    """File descriptor 2 to ``/dev/null`` inside the block (thread-safe, nestable: restored
    when the last block ends). Python's ``sys.stderr`` writes go the same way meanwhile."""
    with _LOCK:
        if _STATE["depth"] == 0:
            try:
                sys.stderr.flush()
                saved = os.dup(2)
                null = os.open(os.devnull, os.O_WRONLY)
                os.dup2(null, 2)
                os.close(null)
            except OSError:                     # no descriptor 2 to silence
                saved = None
            _STATE["saved"] = saved
        _STATE["depth"] += 1
    try:
        yield
    finally:
        with _LOCK:
            _STATE["depth"] -= 1
            if _STATE["depth"] == 0 and _STATE["saved"] is not None:
                os.dup2(_STATE["saved"], 2)
                os.close(_STATE["saved"])
                _STATE["saved"] = None


def _ours(filename) -> bool:
    try:
        return str(Path(filename).resolve()).startswith(_PACKAGE)
    except (OSError, TypeError, ValueError):
        return False


@contextmanager
def one_line_warnings(prefix: str = "topopose: warning: "):
    """Inside the block: topopose's ``UserWarning``\\ s printed as one line on standard error,
    every other warning dropped."""
    def show(message, category, filename, lineno, file=None, line=None):
        if category is UserWarning and _ours(filename):
            print(prefix + str(message).replace("\n", " "), file=sys.stderr)

    with warnings.catch_warnings():
        warnings.showwarning = show
        yield
