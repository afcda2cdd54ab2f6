"""Ctrl-C during `topopose run --workers 2` (no wall of Dask tracebacks): one line,
exit 130, no traceback, and the frames done so far are kept in the output."""
import pytest

from _sigint import interrupt

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
    partial = tmp_path / "p.jsonl.partial"
    code, err = interrupt(DRIVER, ["run", cap, "--workers", "2", "--resolution", "260",
                                   "--output", out], N, after=3, group=True)
    assert "faster in this process" not in err               # the Dask workers did run
    lines = [x for x in err.splitlines() if x.strip() and "frame/s" not in x and f"/{N} [" not in x]
    assert code == 130, err[-2000:]
    assert "Traceback" not in err and lines == ["topopose: interrupted"], err[-2000:]
    from topopose.pose import read_poses

    assert len(read_poses(out)) >= 1 and not partial.exists()      # nothing computed is lost


def test_ctrl_c_is_noted_when_library_code_swallows_it():
    """Dask's code can catch the KeyboardInterrupt of a Ctrl-C; the run's frame loop still sees
    it (``_ctrl_c_noted``) and the previous handler comes back."""
    import os
    import signal

    from topopose.batch.run import _ctrl_c_noted

    before = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        noted, old = _ctrl_c_noted()
        assert old is signal.default_int_handler and not noted.is_set()
        raised = False
        try:
            os.kill(os.getpid(), signal.SIGINT)
            for _ in range(1000):          # the handler runs between bytecodes
                pass
        except KeyboardInterrupt:          # swallowed, as library code may
            raised = True
        assert raised and noted.is_set()
        signal.signal(signal.SIGINT, old)
        assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
    finally:
        signal.signal(signal.SIGINT, before)
