"""The tests run on a bare clone: nothing reads outside the repository.

The committed HEAD is cloned into an empty temporary folder (no ``../shared`` beside it) and one
thinning test on the shipped body volumes runs there, with ``PYTHONPATH`` on the clone's
``src``; an audit hook records every file the process opens, and none may lie in the folder
that holds this checkout (where ``../shared`` lives on the developers' machine) outside the clone.
"""
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

DRIVER = r"""
import sys, os
opened = set()
def hook(event, args):
    if event == "open" and isinstance(args[0], (str, bytes, os.PathLike)):
        opened.add(os.path.abspath(os.fsdecode(args[0])))
sys.addaudithook(hook)
import pytest
code = pytest.main(["-q", "-p", "no:cacheprovider", "tests/test_topology_thinning.py",
                    "-k", "test_body_volumes and d6i1d"])
with open(sys.argv[1], "w") as fh:
    fh.write("\n".join(sorted(opened)))
sys.exit(int(code))
"""


@pytest.mark.slow
def test_thinning_test_passes_in_a_bare_clone(tmp_path):
    if shutil.which("git") is None or not (ROOT / ".git").exists():
        pytest.skip("not a git checkout (an sdist): nothing to clone")
    clone = tmp_path / "repo"
    subprocess.run(["git", "clone", "-q", "--no-hardlinks", str(ROOT), str(clone)], check=True,
                   capture_output=True)
    assert not (tmp_path / "shared").exists() and (clone / "tests" / "data").is_dir()
    env = dict(os.environ, PYTHONPATH=str(clone / "src"), NUMBA_CACHE_DIR=str(tmp_path / "numba"),
               PYTHONDONTWRITEBYTECODE="1")
    log = tmp_path / "opened.txt"
    r = subprocess.run([sys.executable, "-c", DRIVER, str(log)], cwd=clone, env=env,
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    assert "1 passed" in r.stdout, r.stdout[-2000:]
    from topopose.topology.tables import cache_dir

    cache = cache_dir().resolve()
    outside = (ROOT.parent, ROOT.parent.parent / "shared")    # ../ and ../../shared
    # the environment's package metadata (an editable install of this checkout has its
    # *.egg-info in ROOT/src, read by pytest's plugin discovery) is not data the tests read
    # allowed wherever they are: the look-up-table cache, the Python environment (a virtualenv
    # may sit beside the checkout) and temporary files (the checkout may sit in the system's
    # temporary folder) — but never ../shared
    import tempfile

    tmp = Path(tempfile.gettempdir()).resolve()
    allowed = (clone, cache, Path(sys.prefix).resolve(), Path(sys.base_prefix).resolve(), tmp)
    bad = [p for p in log.read_text().splitlines()
           if any(Path(p).is_relative_to(o) for o in outside)
           and (not any(Path(p).is_relative_to(a) for a in allowed)
                or any(Path(p).is_relative_to(o / "shared") for o in (ROOT.parent, ROOT.parents[1])))
           and not any(part.endswith((".egg-info", ".dist-info")) for part in Path(p).parts)]
    assert not bad, f"files read outside the clone: {bad[:5]}"
    opened_topopose = [p for p in log.read_text().splitlines() if "/topopose/" in p and p.endswith(".py")]
    assert opened_topopose and all(Path(p).is_relative_to(clone) for p in opened_topopose)
