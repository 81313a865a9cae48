"""Run a grid's missing chunks in this process's numba threads (``runner.backend=local``).

The backend interface the sweep (runner/sweep.py) speaks, shared with
runner/dask_backend.py's ``DaskCluster``: ``threads``, ``remote``,
``describe()``, ``plan(grid, runs, chunk_seconds)``, ``estimate_seconds(grid,
chunks)``, ``segment_files_seconds(grid, chunks, chunk_seconds)``, ``start()``,
``warm_up(grid)``, ``run_missing(grid, journal, todo, chunk_seconds,
first_number, progress)``, and use as a context manager.
"""

from . import execute
from .grid import estimate_seconds, plan_chunks


class LocalBackend:
    """This process: ``threads`` numba threads integrate each chunk (runner/execute.py)."""

    remote = False  # the sweep says where it runs only for a cluster

    def __init__(self, threads):
        self.threads = int(threads)

    def describe(self):
        return f"{self.threads} threads"

    def plan(self, grid, runs, chunk_seconds):
        """Chunks (arrays of run indices) of ``runs`` sized to ~``chunk_seconds`` each (grid.plan_chunks)."""
        return plan_chunks(grid, runs, self.threads, chunk_seconds)

    def estimate_seconds(self, grid, chunks):
        """Estimated integration time (s) of ``chunks`` on these threads."""
        return estimate_seconds(grid, chunks, self.threads)

    def segment_files_seconds(self, grid, chunks, chunk_seconds):
        """Estimated wall time (s) of the segment files of the chunks cut in time (runner/segments.py)."""
        return execute.segment_files_seconds(grid, chunks, self.threads, chunk_seconds)

    def start(self):
        """Before the first chunk: numba runs the chunks on ``threads`` threads."""
        import numba

        numba.set_num_threads(self.threads)

    def warm_up(self, grid):
        execute.warm_up(grid)

    def run_missing(self, grid, journal, todo, chunk_seconds, first_number, progress=None):
        execute.run_missing(grid, journal, todo, self.threads, chunk_seconds, first_number, progress)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False
