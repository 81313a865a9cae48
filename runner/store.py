"""Everything the runner writes: the lock, the journal of finished chunks, the results file.

Crash safety: each finished chunk goes to ``<out>.partial/chunk-NNNNN.npz``
through a temporary name, fsync and ``os.replace``, so a chunk file is
either complete or absent.  The results file is assembled from the journal
into a temporary name and renamed into place only when complete; then the
journal is removed.  ``OutputLock`` (``fcntl.flock`` on ``<out>.lock``)
refuses a second writer to the same output.

The results layout (dims, variables, units, attrs) is gyrolab/layout.py's.
"""
import fcntl
import json
import os
import shutil
from pathlib import Path

import numpy as np

from ..layout import (
    COORD_ATTRS,
    FIXED_COORDS,
    GRID_DIMS,
    INPUT_DIMS,
    INPUT_VARIABLES,
    RUN_VARIABLES,
    SAMPLE_VARIABLES,
    VARIABLE_ATTRS,
    WALL_TIME_NOTE,
    sample_dims,
    sample_variables,
)
from .config import ConfigError


def partial_dir(out):
    return Path(f"{out}.partial")


def lock_path(out):
    return Path(f"{out}.lock")


def fsync_dir(directory):
    fd = os.open(directory, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def atomic_replace(path, write_to):
    """Call ``write_to(tmp_path)``, fsync that file and rename it to ``path``; the
    temporary file is removed if anything fails, so ``path`` is old or whole."""
    path = Path(path)
    tmp = path.with_name(f".{path.name}.tmp{os.getpid()}")
    try:
        write_to(tmp)
        with open(tmp, "rb") as fh:
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()
    fsync_dir(path.parent)


def atomic_write(path, write):
    """Call ``write(fileobj)`` on a temporary file, then as :func:`atomic_replace`."""

    def write_to(tmp):
        with open(tmp, "wb") as fh:
            write(fh)

    atomic_replace(path, write_to)


class OutputLock:
    """Exclusive, non-blocking lock on ``<out>.lock``; ConfigError naming the holder's pid if taken.

    The lock file is removed on release; the inode check after locking makes
    that safe against a writer that opened the file just before the removal.
    """

    def __init__(self, out):
        self.out = Path(out)
        self.path = lock_path(out)
        self.fd = None

    def check_free(self):
        """ConfigError if another process holds the lock; creates nothing."""
        try:
            fd = os.open(self.path, os.O_RDONLY)
        except FileNotFoundError:
            return
        try:
            fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
        except BlockingIOError:
            self._refuse(fd)
        os.close(fd)

    def _refuse(self, fd):
        holder = os.read(fd, 64).decode(errors="replace").strip() or "?"
        os.close(fd)
        raise ConfigError(
            f"output.path={self.out}: another gyrolab (pid {holder}) is writing it right now; "
            "wait for it to finish or choose another output.path"
        )

    def acquire(self):
        while True:
            fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                self._refuse(fd)
            try:
                same = os.stat(self.path).st_ino == os.fstat(fd).st_ino
            except FileNotFoundError:
                same = False
            if same:
                break
            os.close(fd)  # the previous holder removed the file under us: lock the new one
        os.ftruncate(fd, 0)
        os.write(fd, f"{os.getpid()}\n".encode())
        self.fd = fd
        return self

    def release(self):
        if self.fd is not None:
            try:
                self.path.unlink()
            except FileNotFoundError:
                pass
            os.close(self.fd)
            self.fd = None

    def __enter__(self):
        return self.acquire()

    def __exit__(self, *exc):
        self.release()


class Journal:
    """Finished chunks of one sweep in ``<out>.partial/``; ``manifest.json`` names the config hash."""

    def __init__(self, out):
        self.dir = partial_dir(out)
        self.manifest_path = self.dir / "manifest.json"

    def exists(self):
        return self.manifest_path.exists()

    def manifest(self):
        with open(self.manifest_path) as fh:
            return json.load(fh)

    def create(self, manifest):
        """Start an empty journal (removing any old one)."""
        self.discard()
        self.dir.mkdir(parents=True)
        atomic_write(self.manifest_path, lambda fh: fh.write(json.dumps(manifest, indent=1).encode()))

    def discard(self):
        if self.dir.exists():
            shutil.rmtree(self.dir)

    def chunk_files(self):
        return sorted(self.dir.glob("chunk-*.npz"))

    def clean_temporaries(self):
        """Remove half-written chunk files a killed process left behind."""
        for tmp in self.dir.glob(".chunk-*.tmp*"):
            tmp.unlink()

    def write_chunk(self, number, runs, samples, status, n_steps, wall_time):
        """Store one finished chunk durably: runs (flat numbers), raw samples (n, time, RAW_PER_SAMPLE),
        per-run arrays."""

        def write(fh):
            np.savez(fh, runs=runs, samples=samples, status=status, n_steps=n_steps, wall_time=wall_time)

        atomic_write(self.dir / f"chunk-{number:05d}.npz", write)

    def chunks(self):
        """Yield each stored chunk as a dict of arrays."""
        for path in self.chunk_files():
            with np.load(path, allow_pickle=False) as data:
                yield {key: data[key] for key in data.files}

    def done_runs(self):
        """Flat numbers of the runs already stored and the next free chunk number."""
        files = self.chunk_files()
        runs = []
        for path in files:
            with np.load(path, allow_pickle=False) as data:
                runs.append(data["runs"])
        done = np.concatenate(runs) if runs else np.empty(0, dtype=np.int64)
        next_number = int(files[-1].stem.split("-")[1]) + 1 if files else 0
        return done, next_number


def assemble(out, grid, journal, attrs):
    """Write the results file from the journal into a temporary name, fsync it, rename it to ``out``."""
    atomic_replace(out, lambda tmp: write_results(tmp, grid, journal.chunks(), attrs))


def write_results(path, grid, chunks, attrs):
    """Write the results file at ``path`` (netCDF4/HDF5 via h5netcdf) from chunk dicts.

    One chunk is in memory at a time; each run is one HDF5 chunk per variable.
    """
    import h5netcdf
    import h5py

    shape = grid.shape
    ns = grid.n_samples
    with h5netcdf.File(path, "w") as nc:
        fixed = {d: np.array(v, dtype=object) for d, v in FIXED_COORDS.items()}
        nc.dimensions = dict(zip(GRID_DIMS, shape)) | {"time": ns} | {d: len(v) for d, v in fixed.items()}
        coords = {
            "method": np.array(grid.methods, dtype=object),
            "f": np.array(grid.f),
            "theta0": np.array(grid.theta0),
            "dt": np.array(grid.dt),
            "time": np.arange(ns) * grid.every,
            **fixed,
        }
        for name, values in coords.items():
            dtype = h5py.string_dtype() if values.dtype == object else values.dtype
            var = nc.create_variable(name, (name,), dtype, data=values)
            var.attrs.update(COORD_ATTRS[name])
        variables = {}
        for name in SAMPLE_VARIABLES:
            dims = GRID_DIMS + sample_dims(name)
            chunking = (1,) * len(GRID_DIMS) + (ns,) + ((3,) if len(dims) > len(GRID_DIMS) + 1 else ())
            variables[name] = nc.create_variable(name, dims, np.float64, chunks=chunking)
        for name, (dtype, _) in RUN_VARIABLES.items():
            variables[name] = nc.create_variable(name, GRID_DIMS, dtype)
        inputs = {"body": grid.bodies, "omega0": grid.omega0, "q0": grid.q0}
        for name, (own, _) in INPUT_VARIABLES.items():
            variables[name] = nc.create_variable(name, INPUT_DIMS + (own,), np.float64, data=inputs[name])
        for name, var in variables.items():
            var.attrs.update(VARIABLE_ATTRS[name])
        variables["wall_time"].attrs["description"] = WALL_TIME_NOTE
        per_run = {name: np.zeros(shape, dtype=variables[name].dtype) for name in RUN_VARIABLES}
        written = np.zeros(shape, dtype=bool)
        for chunk in chunks:
            index = grid.index(chunk["runs"])
            for name, values in sample_variables(chunk["samples"]).items():
                var = variables[name]
                for i, at in enumerate(zip(*index)):
                    var[at] = values[i]
            for name in per_run:
                per_run[name][index] = chunk[name]
            written[index] = True
        if not written.all():
            missing = int((~written).sum())
            raise RuntimeError(f"{missing} of {grid.n_runs} runs missing from the journal; cannot assemble {path}")
        for name, values in per_run.items():
            variables[name][...] = values
        nc.attrs.update(attrs)
