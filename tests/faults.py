"""Fault injection for tests/test_faults.py: damaged files and journals, signals, a full disk.

- ``BAD_FILES``: {name: make(path, good)} writes a bad results file at ``path``
  (``good``: a valid results file to damage or strip);
- ``CHUNK_FAULTS``: {name: damage(journal, chunk_path)} damages one journal
  chunk; those marked ``resealed`` rewrite the manifest's checksum, so the
  deeper content checks (not the checksum) must catch them;
- ``interrupt(...)``: start a sweep, wait for a point of integration or
  assembly, send a signal;
- ``small_disk(root)``: a tmpfs of a few MB when this process may mount one
  (root in a container), else None; ``fill(dir)`` fills its file system.
"""

import contextlib
import errno
import json
import os
import random
import shutil
import subprocess
import time
from pathlib import Path

import h5py
import numpy as np
import xarray as xr

from gyrolab.runner.store import Journal, sha256

from helpers import start

# --------------------------------------------------------------------------- bad results files


def _strip_variable(name):
    def make(path, good):
        with xr.open_dataset(good, engine="h5netcdf") as ds:
            ds.load().drop_vars(name).to_netcdf(path, engine="h5netcdf")

    return make


def _foreign_hdf5(path, good):
    with h5py.File(path, "w") as fh:
        fh["x"] = np.arange(10.0)
        fh.attrs["scene"] = "heavy_top"


def _foreign_netcdf(path, good):
    xr.Dataset({"x": ("time", np.arange(5.0))}, coords={"time": np.arange(5.0)}).to_netcdf(path, engine="h5netcdf")


def _no_layout_version(path, good):
    with xr.open_dataset(good, engine="h5netcdf") as ds:
        ds = ds.load()
    # no layout version and no provenance: not a layout-0 gyrolab file either (those are read)
    for key in ("layout_version", "gyrolab_version"):
        ds.attrs.pop(key, None)
    ds.to_netcdf(path, engine="h5netcdf")


def _truncated(path, good):
    data = Path(good).read_bytes()
    Path(path).write_bytes(data[: len(data) // 2])


def _damaged_metadata(path, good):
    """The superblock and root group header overwritten (bytes 8..2048 after the signature)."""
    data = bytearray(Path(good).read_bytes())
    rng = random.Random(1)
    for i in range(8, min(2048, len(data))):
        data[i] = rng.randrange(256)
    Path(path).write_bytes(bytes(data))


BAD_FILES = {
    "empty": lambda path, good: Path(path).write_bytes(b""),
    "garbage": lambda path, good: Path(path).write_bytes(os.urandom(4096)),
    "truncated": _truncated,
    "damaged_metadata": _damaged_metadata,
    "foreign_hdf5": _foreign_hdf5,
    "foreign_netcdf": _foreign_netcdf,
    "no_layout_version": _no_layout_version,
    "missing_energy": _strip_variable("energy"),
    "missing_status": _strip_variable("status"),
    "directory": lambda path, good: Path(path).mkdir(),
}


# --------------------------------------------------------------------------- damaged journal chunks


def _rewrite(journal, path, **changes):
    """Rewrite a chunk with some arrays changed and reseal its manifest checksum."""
    with np.load(path) as data:
        arrays = {k: data[k] for k in data.files}
    arrays.update(changes)
    with open(path, "wb") as fh:
        np.savez(fh, **arrays)
    reseal(journal, path)


def reseal(journal, path):
    manifest = json.loads(journal.manifest_path.read_text())
    entry = manifest["chunks"][path.name]
    entry["sha256"] = sha256(path)
    try:
        with np.load(path) as data:
            if "runs" in data.files:
                entry["runs"] = int(data["runs"].size)
    except Exception:  # a file damaged on purpose
        pass
    journal.manifest_path.write_text(json.dumps(manifest))


def _flip_byte(journal, path):
    data = bytearray(path.read_bytes())
    data[len(data) // 2] ^= 0xFF
    path.write_bytes(bytes(data))


def _unlisted(journal, path):
    manifest = json.loads(journal.manifest_path.read_text())
    del manifest["chunks"][path.name]
    journal.manifest_path.write_text(json.dumps(manifest))


def _nan_finished(journal, path):
    with np.load(path) as data:
        samples = data["samples"].copy()
    samples[0, 3:] = np.nan
    _rewrite(journal, path, samples=samples)


def _foreign(journal, path):
    with open(path, "wb") as fh:
        np.savez(fh, x=np.arange(3))
    reseal(journal, path)


CHUNK_FAULTS = {
    "empty": lambda j, p: p.write_bytes(b""),
    "truncated": lambda j, p: p.write_bytes(p.read_bytes()[: p.stat().st_size // 2]),
    "flipped_byte": _flip_byte,
    "garbage": lambda j, p: p.write_bytes(os.urandom(2048)),
    "unlisted_truncated": lambda j, p: (_unlisted(j, p), p.write_bytes(p.read_bytes()[: p.stat().st_size // 2])),
    "unlisted_nan_samples_status_0": lambda j, p: (_nan_finished(j, p), _unlisted(j, p)),
    # resealed: the checksum matches, the content must be checked
    "resealed_truncated": lambda j, p: (p.write_bytes(p.read_bytes()[: p.stat().st_size // 2]), reseal(j, p)),
    "resealed_foreign": _foreign,
    "resealed_runs_out_of_range": lambda j, p: _rewrite(j, p, runs=np.load(p)["runs"] + 10**6),
    "resealed_negative_runs": lambda j, p: _rewrite(j, p, runs=np.load(p)["runs"] - 10**6),
    "resealed_wrong_sample_shape": lambda j, p: _rewrite(j, p, samples=np.load(p)["samples"][:, :-1]),
    "resealed_wrong_status_shape": lambda j, p: _rewrite(j, p, status=np.load(p)["status"][:-1]),
    "resealed_nan_samples_status_0": _nan_finished,
    "resealed_duplicate_runs": None,  # made by the test: a copy of another chunk under a new name
}

MANIFEST_FAULTS = {
    "empty": b"",
    "garbage": b"\x00\xffnot json",
    "not_an_object": b"[1, 2, 3]",
    "no_config_hash": b'{"n_runs": 16}',
    "bad_chunks_table": b'{"config_hash": "x", "chunks": [1]}',
    "bad_n_runs": b'{"config_hash": "x", "n_runs": -3, "chunks": {}}',
}


def damage_chunk(run_dir, fault, index=0):
    """Apply CHUNK_FAULTS[fault] to the ``index``-th chunk of ``run_dir``'s journal; returns its name."""
    journal = Journal(Path(run_dir) / "results.h5")
    files = journal.chunk_files()
    path = files[index]
    if fault == "resealed_duplicate_runs":
        other = files[(index + 1) % len(files)]
        copy = journal.dir / "chunk-09999.npz"
        shutil.copy(other, copy)
        manifest = json.loads(journal.manifest_path.read_text())
        manifest["chunks"][copy.name] = dict(manifest["chunks"][other.name])
        journal.manifest_path.write_text(json.dumps(manifest))
        return copy.name
    CHUNK_FAULTS[fault](journal, path)
    return path.name


# --------------------------------------------------------------------------- signals


def stray_files(run_dir):
    """Everything in ``run_dir`` but the results file (journal, lock, temporaries)."""
    return sorted(p.name for p in Path(run_dir).iterdir() if p.name != "results.h5")


def interrupt(args, run_dir, cwd, sig, phase, rng, chunks=(1, 4)):
    """Start ``gyrolab args`` and send ``sig`` at a random point of ``phase``:
    "integration" (after a random number of stored chunks in ``chunks`` and a random
    fraction of a chunk delay) or "assembly" (while the results temporary is written).
    Returns (returncode, stderr)."""
    run_dir = Path(run_dir)
    delay = {"integration": {"GYROLAB_TEST_CHUNK_DELAY": 0.2}, "assembly": {"GYROLAB_TEST_ASSEMBLY_DELAY": 0.05}}[phase]
    proc = start(*args, f"hydra.run.dir={run_dir}", cwd=cwd, **delay)
    partial = run_dir / "results.h5.partial"
    if phase == "integration":
        want = rng.randint(*chunks)
        ready = lambda: len(list(partial.glob("chunk-*.npz"))) >= want  # noqa: E731
    else:
        ready = lambda: any(run_dir.glob(".results.h5.tmp*"))  # noqa: E731
    deadline = time.monotonic() + 120
    while not ready():
        if proc.poll() is not None:
            raise AssertionError(f"finished before the {phase} point: {proc.communicate()}")
        if time.monotonic() > deadline:
            proc.kill()
            raise AssertionError("timed out")
        time.sleep(0.01)
    time.sleep(rng.uniform(0, 0.15))
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=60)
    return proc.returncode, err


# --------------------------------------------------------------------------- a full disk


@contextlib.contextmanager
def small_disk(root, megabytes=8):
    """A tmpfs of ``megabytes`` at ``root/disk`` if we may mount one, else yields None."""
    mount = Path(root) / "disk"
    mount.mkdir()
    ok = (
        os.geteuid() == 0
        and shutil.which("mount")
        and subprocess.run(
            ["mount", "-t", "tmpfs", "-o", f"size={megabytes}m", "tmpfs", str(mount)], capture_output=True, timeout=10
        ).returncode
        == 0
    )
    try:
        yield mount if ok else None
    finally:
        if ok:
            subprocess.run(["umount", "-l", str(mount)], capture_output=True, timeout=10)


def fill(directory):
    """Fill the file system of ``directory`` with a ballast file; returns its path (remove it to free)."""
    ballast = Path(directory) / "ballast"
    fd = os.open(ballast, os.O_WRONLY | os.O_CREAT, 0o644)
    block = b"\0" * (1 << 16)
    try:
        while True:
            os.write(fd, block)
    except OSError as err:
        if err.errno != errno.ENOSPC:
            raise
    finally:
        os.close(fd)
    return ballast
