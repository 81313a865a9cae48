"""Numba kernels: rotations, rigid-body dynamics, integration methods and scenes.

Importing this package first points numba's cache at a directory keyed by
``SOURCE_HASH``, a hash of every kernel source file under this folder and of
the numba and Python versions.  numba itself only compares the time stamp of
the file that defines a cached function, so an edit of a helper (say the kick
in free_flow.py) would otherwise keep running the old machine code of every
method that inlines it.  With the key, any edit of any kernel file selects a
fresh cache directory: nothing stale can run, and nothing needs clearing by
hand.  ``NUMBA_CACHE_DIR``, when set, is the parent of those directories
(default: ``$XDG_CACHE_HOME/gyrolab/numba`` or ``~/.cache/gyrolab/numba``).
"""
import hashlib
import os
import sys
import tempfile
from pathlib import Path

import numba


def _source_hash():
    digest = hashlib.sha256(f"numba {numba.__version__} python {sys.version_info[:2]}".encode())
    root = Path(__file__).resolve().parent
    for path in sorted(root.rglob("*.py")):
        digest.update(str(path.relative_to(root)).encode() + b"\0" + path.read_bytes() + b"\0")
    return digest.hexdigest()[:16]


def _cache_root():
    base = os.environ.get("NUMBA_CACHE_DIR") or os.path.join(
        os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache"), "gyrolab", "numba")
    for candidate in (base, os.path.join(tempfile.gettempdir(), f"gyrolab-numba-{os.getuid()}")):
        path = os.path.join(candidate, SOURCE_HASH)
        try:
            os.makedirs(path, exist_ok=True)
            if os.access(path, os.W_OK):
                return path
        except OSError:
            continue
    return None  # no writable place: numba's own locators decide (or it compiles every time)


SOURCE_HASH = _source_hash()
CACHE_DIR = _cache_root()
if CACHE_DIR is not None:
    numba.config.CACHE_DIR = CACHE_DIR
