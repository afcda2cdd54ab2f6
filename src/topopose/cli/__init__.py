"""The ``topopose`` command: argument handling only."""
from topopose.cli.main import build_parser, main

__all__ = ["build_parser", "main"]
