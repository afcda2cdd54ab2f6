"""The machine a benchmark ran on, recorded beside its figures."""
import datetime
import gzip
import json
import os
import platform
import subprocess
from pathlib import Path


def results_dir() -> Path:
    """Where the benchmarks write: ``$TOPOPOSE_BENCH_RESULTS`` (``topopose bench`` points it
    to the untracked ``benchmarks/results/quick/`` unless ``--save``), else ``benchmarks/results``."""
    env = os.environ.get("TOPOPOSE_BENCH_RESULTS")
    return Path(env) if env else Path(__file__).resolve().parent / "results"


def machine(**extra) -> dict:
    """CPU model, cores, load, library versions and date; ``extra`` items are added as given."""
    import numba
    import numpy as np

    model = platform.processor() or ""
    try:
        out = subprocess.run(["lscpu"], capture_output=True, text=True).stdout
        for line in out.splitlines():
            if line.startswith("Model name"):
                model = line.split(":", 1)[1].strip()
    except OSError:
        pass
    try:
        load = round(os.getloadavg()[0], 2)
    except OSError:
        load = None
    info = {"cpu": model, "cores": os.cpu_count(), "load_average": load,
            "python": platform.python_version(), "numpy": np.__version__, "numba": numba.__version__,
            "date": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
            "threads": "NUMBA_NUM_THREADS=" + os.environ.get("NUMBA_NUM_THREADS", "unset")}
    info.update(extra)
    return info


def machine_line(m: dict) -> str:
    """``Machine: CPU, n cores, load x, date`` for a report, from :func:`machine`'s dict."""
    return f"Machine: {m['cpu']}, {m['cores']} cores, load {m['load_average']}, {m['date']}"


def read_rows(path) -> dict:
    """A benchmark's saved JSON, gzip-compressed when its name ends in ``.gz``."""
    p = Path(path)
    return json.loads(gzip.decompress(p.read_bytes()) if p.suffix == ".gz" else p.read_text())


def write_results(out, doc: dict, report) -> None:
    """Write ``doc`` to ``out``.json and ``report(doc)`` to ``out``.md (the folder made)."""
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.with_suffix(".json").write_text(json.dumps(doc, indent=1, default=str))
    out.with_suffix(".md").write_text(report(doc))
    print(f"wrote {out}.md / .json")


def sequence_settings(pairs) -> dict:
    """``{name: value}`` from ``name=value`` strings (a Python literal each, e.g.
    ``despike=None``, ``from_start=set()``): options of the sequence stage
    (:class:`topopose.sequence.options.SequenceOptions` fields), a development study's peer of
    a default, passed to the fits as options. An unknown name or a value that is no literal is
    an error that names it."""
    import ast

    from topopose.sequence.options import SequenceOptions

    out = {}
    for pair in pairs or ():
        name, sep, value = pair.partition("=")
        try:
            v = ast.literal_eval(value.strip())
        except (ValueError, SyntaxError):
            raise SystemExit(f"--set {pair!r}: {value.strip()!r} is not a Python literal") from None
        out[name.strip()] = v
        try:
            SequenceOptions.of(**{name.strip(): v})
        except TypeError:
            raise SystemExit(f"--set {pair!r}: no sequence option {name.strip()!r} "
                             "(topopose.sequence.options)") from None
        if not sep:
            raise SystemExit(f"--set {pair!r}: expected name=value")
    return out
