"""Assembly of the results file from finished chunks: HDF5 chunk shapes and whole-hyperslab writes.

The per-sample variables (gyrolab/results/layout.py) have dims (integrator, f, theta0,
dt, time[, xyz]).  ``chunk_layout`` picks one HDF5 chunk shape for all of
them: a *box* of runs taken from the trailing grid dims (dt first, then
theta0, f, integrator) times ``time_chunk`` samples, about CHUNK_ELEMENTS float64
values per vector component (256 KiB; 768 KiB for a vector, inside HDF5's
default 1 MiB chunk cache).  Box and time chunk are balanced so that reading
one run's time series and reading one time across all runs touch the same
number of bytes (runs_per_box * n_samples = n_runs * time_chunk), each about
sqrt(CHUNK_ELEMENTS * n_runs * n_samples) values of the variable, instead of
one chunk per run (one time across runs then reads the whole variable, and
many short runs make millions of tiny chunks).

The file is written box by box (``boxes``): the raw samples of a box's runs
are gathered from the chunks that hold them (``gather``), the variables are
derived once for the box and each is written as one hyperslab, so every HDF5
chunk is written exactly once and whole.  A box holds at most
ASSEMBLY_BLOCK_BYTES of raw and derived samples (``max_runs``), which bounds
the assembly's memory whatever the grid.

Sources of finished chunks: ``MemoryChunk`` (a dict as ``execute.run_chunk``
returns it) and ``JournalChunk`` (a journal file ``chunk-NNNNN.npz``, whose
samples are read run range by run range with ``os.preadv`` from the
uncompressed zip member, so a journal chunk is never loaded whole).
"""

import math
import os
import zipfile

import numpy as np

from ..results.layout import RUN_VARIABLES

CHUNK_ELEMENTS = 2**15  # float64 values per vector component in one HDF5 chunk (256 KiB)
ASSEMBLY_BLOCK_BYTES = 64 * 2**20  # bytes of raw + derived samples of one box held while assembling


def chunk_layout(shape, n_samples, max_runs):
    """(box, time_chunk): the runs per HDF5 chunk along the grid dims ``shape`` (integrator, f, theta0, dt)
    and the samples per chunk along time.  ``max_runs`` bounds the runs of a box (memory)."""
    n_runs = math.prod(shape)
    balanced = math.sqrt(CHUNK_ELEMENTS * n_runs / n_samples)
    k = int(min(max(round(balanced), 1), n_runs, max(int(max_runs), 1)))
    box, remaining = [1] * len(shape), k
    for d in reversed(range(len(shape))):
        box[d] = _even(shape[d], max(1, min(shape[d], remaining)))
        remaining = max(1, remaining // box[d])
    runs = math.prod(box)
    time_chunk = _even(n_samples, int(min(max(CHUNK_ELEMENTS // runs, 1), n_samples)))
    return tuple(box), time_chunk


def _even(n, size):
    """The chunk length in [size/2, size] that wastes least of the last chunk along an axis of ``n``
    (the longest of equals): HDF5 allocates edge chunks whole, so 1001 samples in chunks of 163
    would store 1141; in chunks of 143, 1001."""
    return min(range(max(1, size // 2), size + 1), key=lambda s: (-(-n // s) * s - n, -s))


def max_runs(bytes_per_run, budget=ASSEMBLY_BLOCK_BYTES):
    """Runs of one box within ``budget`` bytes, at ``bytes_per_run`` (raw + derived samples, bytes)."""
    return max(1, int(budget // max(int(bytes_per_run), 1)))


def boxes(shape, box):
    """Yield the tuples of slices of the boxes that tile the grid ``shape``, in C order."""
    starts = [range(0, n, b) for n, b in zip(shape, box)]
    for corner in np.ndindex(*[len(r) for r in starts]):
        yield tuple(slice(s[i], min(s[i] + b, n)) for s, i, b, n in zip(starts, corner, box, shape))


def box_runs(shape, where):
    """Flat run numbers (C order of ``shape``) of the box ``where`` (tuple of slices), in C order."""
    axes = [np.arange(s.start, s.stop) for s in where]
    return np.ravel_multi_index(np.meshgrid(*axes, indexing="ij"), shape).ravel()


class MemoryChunk:
    """A finished chunk held in memory: the dict of ``execute.run_chunk`` (runs, samples and each of
    RUN_VARIABLES)."""

    def __init__(self, chunk):
        self.chunk = chunk
        self.runs = np.asarray(chunk["runs"])

    def per_run(self, name):
        return np.asarray(self.chunk[name])

    def read_rows(self, rows):
        """Raw samples of the chunk's rows ``rows`` (array of row indices): (len(rows), time, fields)."""
        return np.asarray(self.chunk["samples"])[rows]


class JournalChunk:
    """A journal chunk file (np.savez, uncompressed); its samples stay on disk until read."""

    def __init__(self, path, n_samples, n_fields):
        self.path = str(path)
        with np.load(self.path, allow_pickle=False) as data:
            self.runs = data["runs"]
            self._per_run = {k: data[k] for k in RUN_VARIABLES}
        self.row_shape = (n_samples, n_fields)
        self._offset = _npy_member_offset(self.path, "samples.npy", (self.runs.size, *self.row_shape))
        self._loaded = None

    def per_run(self, name):
        return self._per_run[name]

    def read_rows(self, rows):
        """Raw samples of rows ``rows`` (sorted or not), read range by range of consecutive rows."""
        rows = np.asarray(rows, dtype=np.int64)
        if rows.size == 0:
            return np.empty((0, *self.row_shape))
        if self._offset is None:  # a compressed or unusual member: load it once
            if self._loaded is None:
                with np.load(self.path, allow_pickle=False) as data:
                    self._loaded = data["samples"]
            return self._loaded[rows]
        in_order = rows.size == 1 or bool(np.all(np.diff(rows) > 0))
        order = None if in_order else np.argsort(rows, kind="stable")
        ordered = rows if in_order else rows[order]
        out = np.empty((rows.size, *self.row_shape))
        row_bytes = out[0].nbytes
        breaks = np.flatnonzero(np.diff(ordered) != 1) + 1
        fd = os.open(self.path, os.O_RDONLY)
        try:
            for lo, hi in zip(np.r_[0, breaks], np.r_[breaks, ordered.size]):
                target = out[lo:hi]
                want = target.nbytes
                got = os.preadv(fd, [memoryview(target).cast("B")], self._offset + int(ordered[lo]) * row_bytes)
                if got != want:
                    raise OSError(f"{self.path}: short read ({got} of {want} bytes)")
        finally:
            os.close(fd)
        if in_order:
            return out
        result = np.empty_like(out)
        result[order] = out
        return result


def _npy_member_offset(path, member, shape):
    """Byte offset in ``path`` (a zip) of the data of the stored float64 C-order ``.npy`` member of
    ``shape``; None if the member is compressed or not such an array (then it is loaded instead)."""
    with zipfile.ZipFile(path) as zf:
        info = zf.getinfo(member)
        if info.compress_type != zipfile.ZIP_STORED:
            return None
    with open(path, "rb") as fh:
        fh.seek(info.header_offset)
        header = fh.read(30)
        if header[:4] != b"PK\x03\x04":
            return None
        name_len = int.from_bytes(header[26:28], "little")
        extra_len = int.from_bytes(header[28:30], "little")
        fh.seek(info.header_offset + 30 + name_len + extra_len)
        version = np.lib.format.read_magic(fh)
        read_header = np.lib.format.read_array_header_1_0 if version == (1, 0) else np.lib.format.read_array_header_2_0
        got_shape, fortran, dtype = read_header(fh)
        if tuple(got_shape) != tuple(shape) or fortran or dtype != np.float64:
            return None
        return fh.tell()


def gather(sources, owner, row, runs, row_shape, after_read=None):
    """Raw samples (len(runs), *row_shape) of the flat run numbers ``runs``: run r is row ``row[r]``
    of ``sources[owner[r]]``.  ``after_read()`` runs after each source's part (a test hook)."""
    out = np.empty((len(runs), *row_shape))
    which = owner[runs]
    for c in np.unique(which):
        at = np.flatnonzero(which == c)
        out[at] = sources[int(c)].read_rows(row[runs[at]])
        if after_read is not None:
            after_read()
    return out
