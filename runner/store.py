"""Everything the runner writes: the lock, the journal of finished chunks, the results file.

Crash safety: each finished chunk goes to ``<out>.partial/chunk-NNNNN.npz``
through a temporary name, fsync and ``os.replace``, so a chunk file is
either complete or absent; then its HMAC (below, ``chunk_mac``) and number of runs are
added to ``manifest.json`` (written the same way).  A resume verifies every chunk
(``Journal.verify``: listed, proof, keys, shapes, run numbers, finite
samples of finished runs) and moves a bad one aside into
``<out>.partial/rejected/`` so that its runs are computed again.  A chunk cut in
time keeps its samples so far and its runs' state in ``segment-NNNNN.npz`` (the
same proof and checks) until the whole chunk is stored (``Journal.open_segments``).  The results
file is assembled from the journal into a temporary name and renamed into
place only when complete; then the journal is removed.  Temporaries a killed
process left (``.<out>.tmp<pid>``) are removed by the next writer
(``remove_stale_temporaries``).  ``OutputLock`` (``fcntl.flock`` on
``<out>.lock``) refuses a second writer to the same output.

The results layout (dims, variables, units, attrs) is gyrolab/results/layout.py's.
"""

import errno
import hashlib
import hmac
import json
import os
import re
import shutil
import stat
import sys
import time
from pathlib import Path

import numpy as np

from ..results.layout import (
    COORD_ATTRS,
    FIXED_COORDS,
    GRID_DIMS,
    INPUT_DIMS,
    INPUT_VARIABLES,
    RAW_PER_SAMPLE,
    RUN_VARIABLES,
    VARIABLE_ATTRS,
    VARIABLES_ATTR,
    WALL_TIME_NOTE,
    sample_dims,
    sample_variables,
    variables_attr,
)
from ..safe_files import atomic_replace, atomic_write, open_regular, remove_entry
from .assembly import JournalChunk, MemoryChunk, box_runs, boxes, chunk_layout, gather, max_runs
from .config import ConfigError


def partial_dir(out):
    return Path(f"{out}.partial")


class JournalError(ConfigError):
    """A journal whose manifest cannot be trusted (one-line message)."""


START_OVER = "start over with output.overwrite=true"  # the advice of a JournalError's message, last


# A chunk's arrays: its runs (flat numbers), their raw samples and each per-run variable of the layout.
CHUNK_KEYS = ("runs", "samples", *RUN_VARIABLES)
# Each chunk proves it belongs to its sweep: ``binding`` (the config hash and the kernel-source hash
# the journal was started with) and ``mac``, an HMAC-SHA256 under the journal's secret key (a 0600
# file in the 0700 journal directory) of the chunk's file name, its binding and every array's bytes.
# A chunk of another sweep, one made up, or one copied under another name fails it, whatever its
# manifest entry says.
PROOF_KEYS = ("binding", "mac")
KEY_FILE = "key"
JOURNAL_NAME = re.compile(r"chunk-(\d{5,9})\.npz")
# A chunk integrated in time segments (runner/segments.py) keeps its samples so far in
# ``segment-NNNNN.npz`` (NNNNN: the chunk's number): a chunk's arrays with samples 0..k only, plus
# ``state`` (n, 7), each run's (ω, q) at sample k, from which a resume goes on bit for bit.
SEGMENT_NAME = re.compile(r"segment-(\d{5,9})\.npz")
SEGMENT_KEYS = (*CHUNK_KEYS, "state")


def chunk_mac(key, name, binding, arrays, keys=CHUNK_KEYS):
    """HMAC-SHA256 (hex) under ``key`` of a chunk's file name, binding and ``keys`` arrays."""
    mac = hmac.new(key, digestmod=hashlib.sha256)
    mac.update(f"{name}\0{binding}\0".encode())
    for k in keys:
        value = np.ascontiguousarray(arrays[k])
        mac.update(f"{k}:{value.dtype.str}:{value.shape}\0".encode())
        mac.update(_bytes_view(value))  # the array's bytes in place: no copy of ~0.7 GB a big sweep
    return mac.hexdigest()


def _bytes_view(array):
    """The bytes of a C-contiguous array as a flat memoryview (the bytes ``tobytes`` would copy)."""
    return memoryview(array.reshape(-1)).cast("B") if array.size else b""


def save_npz(fh, arrays):
    """Write ``arrays`` (name -> array) to the open binary file ``fh`` as ``np.savez`` does (an
    uncompressed zip of .npy members that ``np.load`` reads), without its copy: np.savez passes each
    array to the zip member through 16 MiB ``tobytes`` copies; here each member is the .npy header and
    the array's own bytes (one CRC-32 pass in zipfile, one write)."""
    import zipfile

    with zipfile.ZipFile(fh, mode="w", compression=zipfile.ZIP_STORED, allowZip64=True) as zf:
        for name, value in arrays.items():
            value = np.asarray(value, order="C")  # (not ascontiguousarray, which makes a 0-d array 1-d)
            with zf.open(f"{name}.npy", mode="w", force_zip64=True) as member:
                np.lib.format.write_array_header_1_0(member, np.lib.format.header_data_from_array_1_0(value))
                member.write(_bytes_view(value))


def sha256(path):
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


class Journal:
    """Finished chunks of one sweep in ``<out>.partial/``; ``manifest.json`` names the config
    hash, the grid (n_runs, shape, n_samples) and each chunk's HMAC and number of runs."""

    def __init__(self, out):
        self.dir = partial_dir(out)
        self.manifest_path = self.dir / "manifest.json"
        self.rejected_dir = self.dir / "rejected"
        self._manifest = None
        self.write_seconds = 0.0  # wall time (s) spent in write_chunk by this object

    def exists(self):
        return self.manifest_path.exists()

    def manifest(self):
        """The manifest as a dict; JournalError (one line) if it is unreadable or malformed."""
        try:
            with open(self.manifest_path, "rb") as fh:
                manifest = json.loads(fh.read().decode())
        except (OSError, UnicodeDecodeError, ValueError) as err:
            raise JournalError(
                f"{self.manifest_path}: damaged journal manifest ({_reason(err)}); {START_OVER}"
            ) from None
        problem = _manifest_problem(manifest)
        if problem:
            raise JournalError(f"{self.manifest_path}: damaged journal manifest ({problem}); {START_OVER}")
        return manifest

    def create(self, manifest):
        """Start an empty journal (removing any old one): a directory only we may enter, a fresh
        secret key, the manifest (``kernel_source_hash``: this code's, unless given)."""
        from ..kernels import SOURCE_HASH

        self.discard()
        self.dir.parent.mkdir(parents=True, exist_ok=True)
        self.dir.mkdir(mode=0o700)
        key = os.urandom(32).hex().encode()
        atomic_write(self.dir / KEY_FILE, lambda fh: fh.write(key), mode=0o600)
        self._manifest = {"kernel_source_hash": SOURCE_HASH, **manifest, "chunks": {}}
        self._write_manifest()

    def key(self):
        """The journal's secret key; JournalError (one line) if it is missing or not our file."""
        if getattr(self, "_key", None) is None:
            try:
                fd = open_regular(self.dir / KEY_FILE, os.O_RDONLY)
                with os.fdopen(fd, "rb") as fh:
                    self._key = fh.read(200)
            except (OSError, ValueError) as err:
                raise JournalError(
                    f"{self.dir}: no usable journal key ({_reason(err)}; a journal of an older gyrolab?); "
                    "start over with output.overwrite=true"
                ) from None
        return self._key

    def binding(self):
        """What every chunk of this journal records: ``<config hash> <kernel-source hash>``."""
        if self._manifest is None:
            self._manifest = self.manifest()
        return f"{self._manifest['config_hash']} {self._manifest.get('kernel_source_hash', '')}"

    def _write_manifest(self):
        text = json.dumps(self._manifest, indent=1).encode()
        atomic_write(self.manifest_path, lambda fh: fh.write(text))

    def discard(self):
        remove_entry(self.dir)  # a link there is removed, not followed

    def chunk_files(self):
        """The regular files named ``chunk-NNNNN.npz`` (never a link, a directory or a FIFO)."""
        return sorted(p for p in self.dir.glob("chunk-*.npz") if JOURNAL_NAME.fullmatch(p.name) and _is_regular(p))

    def odd_entries(self):
        """Entries of the journal directory that are none of its own files: each (name, what)."""
        odd = []
        for p in sorted(self.dir.iterdir()):
            if p.name in ("manifest.json", KEY_FILE) and _is_regular(p):
                continue
            if p.name == "rejected" and p.is_dir() and not p.is_symlink():
                continue
            if p.name.startswith((".chunk-", ".segment-", ".manifest.json.", f".{KEY_FILE}.")):
                continue  # a killed writer's temporary: clean_temporaries
            if (JOURNAL_NAME.fullmatch(p.name) or SEGMENT_NAME.fullmatch(p.name)) and _is_regular(p):
                continue
            odd.append((p.name, _what(p)))
        return odd

    def set_aside_odd_entries(self):
        """Move every odd entry (a link, directory, FIFO, misnamed file) into ``rejected/`` without
        opening or following it; returns [(name, reason)]."""
        moved = []
        if self.rejected_dir.is_symlink() or (self.rejected_dir.exists() and not self.rejected_dir.is_dir()):
            what = _what(self.rejected_dir)
            moved.append(("rejected", f"{what} where the rejected chunks go; removed, never followed"))
            self.rejected_dir.unlink()
        for name, what in self.odd_entries():
            self._reject(self.dir / name)
            moved.append((name, f"{what}, not a journal chunk; never read"))
        return moved

    def clean_temporaries(self):
        """Remove half-written chunk and manifest files a killed process left behind."""
        temporaries = (".chunk-*.tmp*", ".segment-*.tmp*", ".manifest.json.tmp*")
        for tmp in [p for pattern in temporaries for p in self.dir.glob(pattern)]:
            remove_entry(tmp)  # a file, a private directory of safe_files.atomic_replace, or a link

    def write_chunk(self, number, runs, samples, **per_run):
        """Store one finished chunk durably: runs (flat numbers), raw samples (n, time, RAW_PER_SAMPLE),
        ``per_run`` arrays (n,), one for each of RUN_VARIABLES; then record its HMAC in the manifest."""

        start = time.perf_counter()
        path = self.dir / f"chunk-{number:05d}.npz"
        arrays = _chunk_arrays(runs, samples, per_run)
        binding = self.binding()
        mac = chunk_mac(self.key(), path.name, binding, arrays)

        atomic_write(path, lambda fh: save_npz(fh, {**arrays, "binding": np.array(binding), "mac": np.array(mac)}))
        self.record_chunk(path, len(runs), mac)
        self.write_seconds += time.perf_counter() - start

    def write_segment(self, number, runs, samples, state, **per_run):
        """Store durably the samples so far of chunk ``number``, which is integrated in time segments
        (runner/segments.py): ``write_chunk``'s arrays with samples (n, k + 1, RAW_PER_SAMPLE) of
        samples 0..k, and ``state`` (n, 7).  Each segment replaces the last; ``write_chunk`` of the
        whole chunk, then ``remove_segment``, end it."""
        start = time.perf_counter()
        path = self.dir / f"segment-{number:05d}.npz"
        arrays = _chunk_arrays(runs, samples, per_run, state=state)
        binding = self.binding()
        mac = chunk_mac(self.key(), path.name, binding, arrays, SEGMENT_KEYS)
        atomic_write(path, lambda fh: save_npz(fh, {**arrays, "binding": np.array(binding), "mac": np.array(mac)}))
        self.write_seconds += time.perf_counter() - start

    def remove_segment(self, number):
        remove_entry(self.dir / f"segment-{number:05d}.npz")

    def segment_files(self):
        """The regular files named ``segment-NNNNN.npz``."""
        return sorted(p for p in self.dir.glob("segment-*.npz") if SEGMENT_NAME.fullmatch(p.name) and _is_regular(p))

    def open_segments(self, todo, n_runs, n_samples):
        """The chunks a killed sweep left part-way in time, to go on with: [(number, arrays)] of each
        segment file that passes a chunk's checks (its proof, shapes, finite samples and state of the
        runs still going) and whose runs are all in ``todo``; and [(file name, reason)] of the ones
        moved aside into ``rejected/`` (their runs are computed again).  A segment file whose runs are
        all done (its chunk was stored just before a kill) is removed."""
        todo, open_, rejected, seen = np.asarray(todo, dtype=np.int64), [], [], set()
        for path in self.segment_files():
            try:
                with np.load(path, allow_pickle=False) as data:
                    runs = np.asarray(data["runs"]).ravel()
                going = np.isin(runs, todo)
            except Exception:  # unreadable: _chunk_problem says why
                runs = going = np.zeros(0, dtype=bool)
            if runs.size and not going.any():
                remove_entry(path)
                continue
            problem = _chunk_problem(path, None, n_runs, n_samples, seen, self.key(), self.binding(), segment=True)
            if problem is None and not going.all():
                problem = "some of its runs are stored in chunks already"
            if problem:
                rejected.append((path.name, problem))
                self._reject(path)
                continue
            with np.load(path, allow_pickle=False) as data:
                open_.append((int(SEGMENT_NAME.fullmatch(path.name).group(1)), {k: data[k] for k in SEGMENT_KEYS}))
        return open_, rejected

    def report_set_aside(self, rejected):
        """One line on stderr for each (file name, reason) that ``verify`` or ``open_segments`` moved
        aside into ``rejected/``."""
        for name, reason in rejected:
            print(
                f"gyrolab: journal: {name} moved aside to {self.rejected_dir}: {reason}; its runs are computed again",
                file=sys.stderr,
            )

    def record_chunk(self, path, n_runs, mac):
        """Add a chunk file written by this or another process to the manifest, with its HMAC ``mac``
        (hex; the one the file carries)."""
        if self._manifest is None:
            self._manifest = self.manifest()
        self._manifest.setdefault("chunks", {})[Path(path).name] = {"mac": str(mac), "runs": int(n_runs)}
        self._write_manifest()

    def chunks(self):
        """Yield each stored chunk as a dict of arrays."""
        for path in self.chunk_files():
            with np.load(path, allow_pickle=False) as data:
                yield {key: data[key] for key in data.files}

    def verify(self, n_runs, n_samples):
        """Check every chunk file against the manifest and the grid; move each bad one into
        ``rejected/``.  Returns [(chunk file name, reason)] of the chunks set aside."""
        manifest = self._manifest = self.manifest()
        listed = manifest.get("chunks")
        rejected, seen, changed = self.set_aside_odd_entries(), set(), listed is None
        listed = manifest["chunks"] = listed if listed is not None else {}
        for path in self.chunk_files():
            problem = _chunk_problem(path, listed, n_runs, n_samples, seen, self.key(), self.binding())
            if problem:
                rejected.append((path.name, problem))
                self._reject(path)
                changed |= listed.pop(path.name, None) is not None
            elif path.name not in listed:  # killed before its manifest entry, or a journal without checksums
                with np.load(path, allow_pickle=False) as data:
                    listed[path.name] = {"mac": str(data["mac"]), "runs": int(data["runs"].size)}
                changed = True
        have = {p.name for p in self.chunk_files()}
        for name in [n for n in listed if n not in have]:
            listed.pop(name)  # listed but gone: its runs are simply not done
            changed = True
        if changed:
            self._write_manifest()
        return rejected

    def _reject(self, path):
        self.rejected_dir.mkdir(exist_ok=True)
        target = self.rejected_dir / path.name
        k = 1
        while target.exists() or target.is_symlink():
            target, k = self.rejected_dir / f"{path.stem}.{k}{path.suffix}", k + 1
        os.replace(path, target)

    def done_runs(self):
        """Flat numbers of the runs already stored and the next free chunk number."""
        files = self.chunk_files()
        runs = []
        for path in files:
            with np.load(path, allow_pickle=False) as data:
                runs.append(data["runs"])
        done = np.concatenate(runs) if runs else np.empty(0, dtype=np.int64)
        numbers = [int(JOURNAL_NAME.fullmatch(p.name).group(1)) for p in files]
        numbers += [int(SEGMENT_NAME.fullmatch(p.name).group(1)) for p in self.segment_files()]
        numbers += [
            int(p.stem.split("-")[1].split(".")[0])
            for p in self.rejected_dir.glob("chunk-*.npz")
            if p.stem.split("-")[1].split(".")[0].isdigit()
        ]
        return done, max(numbers) + 1 if numbers else 0


def _chunk_arrays(runs, samples, per_run, **more):
    """A chunk's arrays in CHUNK_KEYS order (then ``more``); TypeError when ``per_run`` is not one
    array for each of RUN_VARIABLES (a writer that misses one would store a chunk no resume accepts)."""
    missing = [k for k in RUN_VARIABLES if k not in per_run]
    unknown = sorted(set(per_run) - set(RUN_VARIABLES))
    if missing or unknown:
        what = f"missing {', '.join(missing)}" if missing else f"unknown {', '.join(unknown)}"
        raise TypeError(f"a chunk needs the per-run arrays {', '.join(RUN_VARIABLES)}: {what}")
    arrays = dict(runs=runs, samples=samples, **{k: per_run[k] for k in RUN_VARIABLES}, **more)
    return {k: np.asarray(v) for k, v in arrays.items()}


def _reason(err):
    text = " ".join(str(err).split())
    return f"{type(err).__name__}: {text[:100]}" if text else type(err).__name__


def _manifest_problem(manifest):
    """What is wrong with a parsed manifest, or None."""
    if not isinstance(manifest, dict):
        return "not a JSON object"
    if not isinstance(manifest.get("config_hash"), str):
        return "no config_hash"
    if "n_runs" in manifest and not (isinstance(manifest["n_runs"], int) and manifest["n_runs"] > 0):
        return f"n_runs={manifest['n_runs']!r}"
    chunks = manifest.get("chunks")
    if chunks is not None:
        if not isinstance(chunks, dict):
            return "chunks is not a JSON object"
        for name, entry in chunks.items():
            # "mac" (the chunk's HMAC), or "sha256" (the file's, as gyrolab wrote before 2026-12-05)
            proof = entry.get("mac", entry.get("sha256")) if isinstance(entry, dict) else None
            if not (isinstance(proof, str) and isinstance(entry.get("runs"), int)):
                return f"bad entry for {name}"
    return None


def _is_regular(path):
    try:
        return stat.S_ISREG(os.lstat(path).st_mode)
    except OSError:
        return False


def _what(path):
    try:
        mode = os.lstat(path).st_mode
    except OSError:
        return "gone"
    if stat.S_ISLNK(mode):
        return "a symbolic link"
    if stat.S_ISDIR(mode):
        return "a directory"
    if stat.S_ISREG(mode):
        return "a file of another name"
    return "a special file"


def _chunk_problem(path, listed, n_runs, n_samples, seen, key, binding, segment=False):
    """Why the chunk file ``path`` cannot be used, or None (then its runs are added to ``seen``).
    ``segment``: a segment file (SEGMENT_KEYS, samples 0..k of n_samples)."""
    keys = SEGMENT_KEYS if segment else CHUNK_KEYS
    # A chunk missing from the manifest was renamed into place just before a kill, ahead of its
    # manifest entry: whole (atomic rename, fsync), so it is judged by its content alone.
    listed = listed if listed is not None and path.name in listed else None
    # The manifest entry names the chunk by its HMAC ("mac"), which the file carries and which is
    # checked against the arrays below: one hash of the samples, not a second one of the file.  (zip's
    # CRC-32 of each member, which np.load checks as it reads one whole, covers the .npy headers.)  An
    # entry of an older gyrolab names the file's sha256 instead.
    entry = listed[path.name] if listed is not None else None
    if entry is not None and "mac" not in entry and sha256(path) != entry["sha256"]:
        return "checksum differs from the manifest's (damaged file)"
    try:
        with np.load(path, allow_pickle=False) as data:
            missing = [k for k in keys if k not in data.files]
            if missing:
                return f"not a gyrolab chunk (no array {missing[0]!r})"
            if any(k not in data.files for k in PROOF_KEYS):
                return "no proof of its sweep (a chunk of an older gyrolab or not one of this journal's)"
            arrays = {k: data[k] for k in (*keys, *PROOF_KEYS)}
    except Exception as err:  # zipfile, numpy and zlib raise many kinds on damaged input
        return f"unreadable ({_reason(err)})"
    if entry is not None and "mac" in entry and not hmac.compare_digest(str(arrays["mac"]), entry["mac"]):
        return "not the chunk the manifest lists (its HMAC differs from the manifest's: replaced or damaged)"
    if str(arrays["binding"]) != binding:
        return "made by another sweep or other kernel code (its config or kernel-source hash differs)"
    if not hmac.compare_digest(str(arrays["mac"]), chunk_mac(key, path.name, binding, arrays, keys)):
        return "does not prove it belongs to this journal (its HMAC does not match: foreign, made up or altered)"
    runs = arrays["runs"]
    if runs.ndim != 1 or runs.size == 0 or runs.dtype.kind not in "iu":
        return f"runs has shape {runs.shape} and dtype {runs.dtype}"
    n = runs.size
    if listed is not None and listed[path.name]["runs"] != n:
        return f"{n} runs where the manifest says {listed[path.name]['runs']}"
    if runs.min() < 0 or runs.max() >= n_runs:
        return f"run numbers outside 0..{n_runs - 1}"
    if len(set(runs.tolist())) != n or seen.intersection(runs.tolist()):
        return "runs stored twice"
    shape = arrays["samples"].shape
    expected = (n, n_samples, RAW_PER_SAMPLE)
    if segment and len(shape) == 3 and 1 <= shape[1] <= n_samples:
        expected = (n, shape[1], RAW_PER_SAMPLE)
    if shape != expected or arrays["samples"].dtype != np.float64:
        return f"samples have shape {shape}, expected {expected}"
    for key in RUN_VARIABLES:
        if arrays[key].shape != (n,):
            return f"{key} has shape {arrays[key].shape}, expected ({n},)"
    finished = arrays["status"] == 0
    if not np.isfinite(arrays["samples"][finished]).all():
        return "non-finite samples in runs marked finished (status 0)"
    if segment and (arrays["state"].shape != (n, 7) or not np.isfinite(arrays["state"][finished]).all()):
        return f"state has shape {arrays['state'].shape} or is not finite where its run goes on"
    seen.update(runs.tolist())
    return None


# Test hook: seconds to sleep after each journal chunk's part of a box copied into the results file
# being assembled.
ASSEMBLY_DELAY_ENV = "GYROLAB_TEST_ASSEMBLY_DELAY"


def assemble(out, grid, journal, attrs, before_replace=None):
    """Write the results file from the journal into a temporary name, fsync it, rename it to ``out``
    (``before_replace`` as in atomic_replace)."""
    need = grid.file_bytes() * 1.05 + 2**20  # all the file holds (runner/grid.py), and a margin
    free = shutil.disk_usage(Path(out).parent).free
    if free < need:  # HDF5 can crash (not raise) when the disk fills while it closes a file
        raise OSError(
            errno.ENOSPC,
            f"No space left on device: the results need ~{need / 1e6:.3g} MB, {free / 1e6:.3g} MB free",
            str(out),
        )
    delay = float(os.environ.get(ASSEMBLY_DELAY_ENV, "0") or 0)
    after_read = None
    if delay:
        after_read = lambda: time.sleep(delay)  # noqa: E731
    sources = [JournalChunk(path, grid.n_samples, RAW_PER_SAMPLE) for path in journal.chunk_files()]
    atomic_replace(
        out, lambda tmp: in_child(lambda: write_results(tmp, grid, sources, attrs, after_read), out), before_replace
    )


CHILD_ERROR = "gyrolab-child-error: "  # marks the child's own one-line reason among libhdf5's output


def in_child(work, where):
    """Run ``work()`` (writing the file ``where``) in a forked child process and wait for it.

    libhdf5 can crash (SIGSEGV) or print hundreds of lines of error stack when the disk fills or
    fails while it writes or closes a file; in a child, that stays there: its stderr goes to a
    private temporary, and any failure comes back here as one OSError (ENOSPC when the device of
    ``where`` is full, else EIO; filename ``where``) with the child's last line as the reason.  A signal here (the
    child ignores the terminal's) kills the child and is raised as usual."""
    import signal
    import tempfile

    sys.stdout.flush()
    sys.stderr.flush()
    with tempfile.TemporaryFile() as log:
        pid = os.fork()
        if pid == 0:  # the child: no Python clean-up of the parent's objects, only os._exit
            status = 1
            try:
                for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
                    signal.signal(sig, signal.SIG_IGN)
                os.dup2(log.fileno(), 2)
                work()
                status = 0
            except BaseException as err:  # noqa: BLE001 - reported to the parent as one line
                os.write(2, f"\n{CHILD_ERROR}{_reason(err)}\n".encode(errors="replace"))
            finally:
                os._exit(status)
        try:
            _, status = os.waitpid(pid, 0)
        except BaseException:  # an interrupt: the child must not outlive its parent
            os.kill(pid, signal.SIGKILL)
            os.waitpid(pid, 0)
            raise
        if os.waitstatus_to_exitcode(status) == 0:
            return
        log.seek(0)
        noise = log.read()[-20000:].decode(errors="replace")
    code = os.waitstatus_to_exitcode(status)
    said = [line.split(CHILD_ERROR, 1)[1] for line in noise.splitlines() if CHILD_ERROR in line]
    reason = said[-1] if said else (f"killed by {signal.Signals(-code).name}" if code < 0 else f"status {code}")
    text = " ".join(reason.split())[:200]
    full = "No space left" in noise or "errno = 28" in noise or _nearly_full(where)
    raise OSError(errno.ENOSPC if full else errno.EIO, f"writing the results failed ({text})", str(where))


def _nearly_full(where):
    """True when the device of ``where`` has less than 1 MiB free (a crash there is a full disk)."""
    try:
        return shutil.disk_usage(Path(where).parent).free < 2**20
    except OSError:
        return False


def write_results(path, grid, chunks, attrs, after_read=None):
    """Write the results file at ``path`` (netCDF4/HDF5 via h5netcdf) from finished chunks: dicts as
    ``execute.run_chunk`` returns them, or runner/assembly.py sources (``JournalChunk``).

    The per-sample variables are written box by box, each variable's box as one hyperslab
    (runner/assembly.py: chunk shapes, bounded memory); ``after_read()`` runs after each chunk's
    part of a box is read (a test hook)."""
    import h5netcdf
    import h5py

    sources = [c if hasattr(c, "read_rows") else MemoryChunk(c) for c in chunks]
    shape = grid.shape
    ns = grid.n_samples
    owner = np.full(grid.n_runs, -1, dtype=np.int64)
    row = np.zeros(grid.n_runs, dtype=np.int64)
    per_run = {name: np.zeros(grid.n_runs, dtype=dtype) for name, (dtype, _) in RUN_VARIABLES.items()}
    for c, source in enumerate(sources):
        runs = np.asarray(source.runs, dtype=np.int64)
        if (owner[runs] >= 0).any() or np.unique(runs).size != runs.size:
            raise RuntimeError(f"runs stored twice in the journal; cannot assemble {path}")
        owner[runs], row[runs] = c, np.arange(runs.size)
        for name in per_run:
            per_run[name][runs] = source.per_run(name)
    missing = int((owner < 0).sum())
    if missing:
        raise RuntimeError(f"{missing} of {grid.n_runs} runs missing from the journal; cannot assemble {path}")
    box, time_chunk = chunk_layout(shape, ns, max_runs(grid.bytes_per_run()))
    with h5netcdf.File(path, "w") as nc:
        fixed = {d: np.array(v, dtype=object) for d, v in FIXED_COORDS.items()}
        nc.dimensions = dict(zip(GRID_DIMS, shape)) | {"time": ns} | {d: len(v) for d, v in fixed.items()}
        coords = {
            "integrator": np.array(grid.methods, dtype=object),
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
        for name in grid.variables:
            dims = GRID_DIMS + sample_dims(name)
            chunking = box + (time_chunk,) + ((3,) if len(dims) > len(GRID_DIMS) + 1 else ())
            variables[name] = nc.create_variable(name, dims, np.float64, chunks=chunking)
        for name, (dtype, _) in RUN_VARIABLES.items():
            variables[name] = nc.create_variable(name, GRID_DIMS, dtype)
        inputs = {"body": grid.bodies, "omega0": grid.omega0, "q0": grid.q0}
        for name, (own, _) in INPUT_VARIABLES.items():
            variables[name] = nc.create_variable(name, INPUT_DIMS + (own,), np.float64, data=inputs[name])
        for name, var in variables.items():
            var.attrs.update(VARIABLE_ATTRS[name])
        variables["wall_time"].attrs["description"] = WALL_TIME_NOTE
        for name, values in per_run.items():
            variables[name][...] = values.reshape(shape)
        nc.attrs.update(attrs)
        if variables_attr(grid.variables) is not None:  # a file names its variables unless they are UNNAMED_HOLD
            nc.attrs[VARIABLES_ATTR] = variables_attr(grid.variables)
    # The samples go into the datasets h5netcdf made, through h5py: h5netcdf looks each dataset up
    # by path three or four times per write (~0.3 s of the 8000-run sweep's ~400 box writes), and
    # the data add no netCDF metadata.
    with h5py.File(path, "r+") as h5:
        datasets = {name: h5[name] for name in grid.variables}
        for where in boxes(shape, box):
            runs = box_runs(shape, where)
            raw = gather(sources, owner, row, runs, (ns, RAW_PER_SAMPLE), after_read)
            lengths = tuple(s.stop - s.start for s in where)
            for name, values in sample_variables(raw, grid.variables).items():
                datasets[name][where] = values.reshape(lengths + values.shape[1:])
            del raw
