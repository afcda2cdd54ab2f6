"""The benchmarks' own checks: their scoring code against hand-made oracles.

The library's tests (``tests/``) never import a benchmark; these do, and run apart from them:
``PYTHONPATH=$PWD/src pytest benchmarks/checks``.
"""
import sys
from pathlib import Path

BENCH = Path(__file__).resolve().parents[1]
if str(BENCH) not in sys.path:
    sys.path.insert(0, str(BENCH))
