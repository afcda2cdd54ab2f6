"""First run: what the screen says while kernels compile, and the helper process that
builds the tables and compiles the tree/alignment kernels beside the first frame."""
import subprocess
import sys
import time

from topopose import _notices
from topopose.batch import warmup


def test_notices_say_compiling_once():
    from numba import njit

    said = []
    with _notices.notices(said.append):
        @njit
        def f(x):
            return x + 1

        f(1)
        f(1.5)                              # a second compilation: no second message
    assert said == ["compiling kernels (first run only)…"]
    f(2j)                                   # outside: silent
    assert len(said) == 1
    _notices.say("x")                     # no-op outside
    assert len(said) == 1


def test_a_message_already_shown_is_kept():
    from numba import njit

    said = []
    with _notices.notices(said.append):
        _notices.say("building the thinning look-up tables")

        @njit
        def g(x):
            return x * 2

        g(3)
    assert said == ["building the thinning look-up tables"]


def test_warmup_waits_for_tables_then_for_the_end():
    p = subprocess.Popen([sys.executable, "-c",
                          "import time; time.sleep(0.3); print('tables', flush=True); time.sleep(0.7)"],
                         stdout=subprocess.PIPE)
    w = warmup.Warmup(p)
    t0 = time.perf_counter()
    w.wait_tables()
    assert p.poll() is None and time.perf_counter() - t0 >= 0.25       # tables done, still running
    w.wait_all()
    assert w.proc is None and p.returncode == 0
    w.wait_all()                                                        # idempotent
    warmup.Warmup(None).wait_all()


def test_cold_detection(tmp_path, monkeypatch):
    monkeypatch.setenv("TOPOPOSE_CACHE_DIR", str(tmp_path))
    assert warmup.tables_cold()
    monkeypatch.setenv("TOPOPOSE_NO_WARMUP", "1")
    assert warmup.start_warmup(force=True).proc is None


def test_helper_runs_the_pipeline_kernels(capsys):
    """The helper's own work (tables, tree, alignment) on warm caches: it reports the tables."""
    assert warmup._warm_main() == 0
    assert capsys.readouterr().out.strip() == "tables"
