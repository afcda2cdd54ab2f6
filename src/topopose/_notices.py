"""What the first run is doing, said on screen: a callback for messages and a Numba compile listener.

:func:`say` is called by the stages that do one-time work (the thinning look-up tables);
:func:`notices` routes those messages, and the first kernel compilation, to the progress bar.
"""
from __future__ import annotations

import contextlib

_SAY = None          # callback(str) while a run shows progress; None: silent


def say(message: str) -> None:
    """Tell the user what the first run is doing (no-op outside :func:`notices`)."""
    if _SAY is not None:
        _SAY(message)


@contextlib.contextmanager
def notices(callback):
    """While active, first-run work is reported through ``callback(message)``: the tables being
    built (:func:`say`) and the first kernel compilation (a Numba ``numba:compile`` listener)."""
    global _SAY
    from numba.core import event

    class _Compiling(event.Listener):
        said = False

        def on_start(self, ev):
            if not self.said:
                self.said = True
                callback("compiling kernels (first run only)…")

        def on_end(self, ev):
            pass

    listener = _Compiling()
    old = _SAY

    def said(message):              # a first-run message already on screen: keep it
        listener.said = True
        callback(message)

    _SAY = said
    event.register("numba:compile", listener)
    try:
        yield
    finally:
        event.unregister("numba:compile", listener)
        _SAY = old
