"""Batch runs over a capture (resume, workers, Dask), the demo and the evaluation against ground truth."""
from topopose.batch.run import RunResult, run

__all__ = ["RunResult", "run"]
