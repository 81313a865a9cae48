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

It also starts numba's counter of function ids at a random value in each
process.  numba names every compiled function ``<module>.<qualname>$<id>``
with ODR linkage, the id counted from 1 in each process; cached code keeps
those names.  Two methods compiled in different processes can therefore
bring different code under one name (driver.make_advance's ``advance_run``
closure is the same qualname for every method), and a process that loads
both caches links one method's kernel to the other's code: a sweep of two
methods silently ran the first one's step for both.  With random starting
ids, names from different processes differ (tests/test_provenance.py
reproduces the collision with the counter reset).
"""

import hashlib
import itertools
import os
import secrets
import sys
import tempfile
from pathlib import Path

import numba
from numba.core import bytecode

# 2^40 possible starts, ~1e4 functions per process: a collision between two processes' caches has a
# probability of order 1e-8.
bytecode.FunctionIdentity._unique_ids = itertools.count(secrets.randbits(40) + 1)


def _source_hash():
    digest = hashlib.sha256(f"numba {numba.__version__} python {sys.version_info[:2]}".encode())
    root = Path(__file__).resolve().parent
    for path in sorted(root.rglob("*.py")):
        digest.update(str(path.relative_to(root)).encode() + b"\0" + path.read_bytes() + b"\0")
    return digest.hexdigest()[:16]


def _cache_root():
    base = os.environ.get("NUMBA_CACHE_DIR") or os.path.join(
        os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache"), "gyrolab", "numba"
    )
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
