"""Numba kernels: rotations, rigid-body dynamics, integration methods and scenes.

Importing this package first points numba's cache at directories keyed by
what each kernel file compiles.  numba itself only checks the file that
defines a cached function, so an edit of a helper (say the kick in
free_flow.py) would otherwise keep running the old machine code of every
method that inlines it.  Here every cached function is stored under a key
(``COMPILE_KEYS``, ``KeyedCacheLocator``):

- a core file (everything numba compiles outside methods/: rotations, the
  kicks and free flows, the drivers, the block path) is keyed by the bytes of
  every core file;
- a method file by the core's bytes, its own and those of the method files
  it imports (bullet_implicit_body imports bullet_explicit);
- files numba never compiles (``NOT_COMPILED``: the scenes, the closed forms,
  the scipy reference, the invariants' declarations, the registry's list of names) are in no key, so
  editing a scene or adding a method compiles nothing that already ran.

Any edit of what a kernel compiles selects a fresh directory: nothing stale
can run, and nothing needs clearing by hand.  The same source anywhere (a
second clone, another venv, a reinstall) finds the same directory.  ``SOURCE_HASH``, the hash of
every file under this folder, names the code that ran in a results file's
provenance.  ``NUMBA_CACHE_DIR``, when set, is the parent of the key
directories (default: ``$XDG_CACHE_HOME/gyrolab/numba`` or
``~/.cache/gyrolab/numba``).

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
import re
import secrets
import sys
import tempfile
from pathlib import Path

import numba
from numba.core import bytecode, caching

# 2^40 possible starts, ~1e4 functions per process: a collision between two processes' caches has a
# probability of order 1e-8.
bytecode.FunctionIdentity._unique_ids = itertools.count(secrets.randbits(40) + 1)


ROOT = Path(__file__).resolve().parent
# Pure-Python files and folders under kernels/ (relative paths): numba compiles nothing in them and no
# compiled function reads them (tests/test_provenance.py checks both), so they key no cache.
NOT_COMPILED = ("closed_form.py", "invariants.py", "parameters.py", "reference.py", "registry.py", "scenes", "real")
_METHOD_IMPORT = re.compile(r"^from \.(\w+) import", re.MULTILINE)


def _versions():
    return f"numba {numba.__version__} python {sys.version_info[:2]}".encode()


def _source_hash(root=ROOT):
    """Hash of every kernel source file under ``root`` and of the numba and Python versions."""
    digest = hashlib.sha256(_versions())
    for path in sorted(root.rglob("*.py")):
        digest.update(str(path.relative_to(root)).encode() + b"\0" + path.read_bytes() + b"\0")
    return digest.hexdigest()[:16]


def compiled_files(root=ROOT):
    """The .py files under ``root`` whose code numba may compile: all but ``NOT_COMPILED``."""
    out = []
    for path in sorted(root.rglob("*.py")):
        rel = path.relative_to(root)
        if str(rel) in NOT_COMPILED or rel.parts[0] in NOT_COMPILED:
            continue
        out.append(path)
    return out


def compile_keys(root=ROOT):
    """{resolved path: key} of every compiled kernel file under ``root`` (see the module docstring)."""
    files = compiled_files(root)
    methods = {p.stem: p for p in files if p.parent.name == "methods" and p.parent.parent == root}
    core = hashlib.sha256(_versions())
    for path in files:
        if path.stem not in methods or path.parent.name != "methods":
            core.update(str(path.relative_to(root)).encode() + b"\0" + path.read_bytes() + b"\0")
    core_key = core.hexdigest()[:16]
    keys = {}
    for path in files:
        if path.parent.name == "methods" and path.stem in methods:
            seen, todo = set(), [path.stem]
            while todo:  # the method file and the method files it imports, transitively
                name = todo.pop()
                if name in seen or name not in methods:
                    continue
                seen.add(name)
                todo.extend(_METHOD_IMPORT.findall(methods[name].read_text()))
            digest = hashlib.sha256(core_key.encode())
            for name in sorted(seen):
                digest.update(name.encode() + b"\0" + methods[name].read_bytes() + b"\0")
            keys[str(path.resolve())] = f"{path.stem}-{digest.hexdigest()[:16]}"
        else:
            keys[str(path.resolve())] = f"core-{core_key}"
    return keys


def _cache_root():
    base = os.environ.get("NUMBA_CACHE_DIR") or os.path.join(
        os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache"), "gyrolab", "numba"
    )
    for candidate in (base, os.path.join(tempfile.gettempdir(), f"gyrolab-numba-{os.getuid()}")):
        try:
            os.makedirs(candidate, exist_ok=True)
            if os.access(candidate, os.W_OK):
                return candidate
        except OSError:
            continue
    return None  # no writable place: numba's own locators decide (or it compiles every time)


SOURCE_HASH = _source_hash()
COMPILE_KEYS = compile_keys()
CACHE_ROOT = _cache_root()

# numba >= 0.60 names it UserProvidedCacheLocator, before that _UserProvidedCacheLocator.
_UserLocator = getattr(caching, "UserProvidedCacheLocator", None) or caching._UserProvidedCacheLocator


class KeyedCacheLocator(_UserLocator):
    """numba's user-directory locator, with the directory ``CACHE_ROOT/<key of the file>/kernels[/methods]``.

    numba's own subdirectory is named by a hash of the file's absolute folder, so every clone, venv or
    reinstall elsewhere compiled everything again; the key already names the source's content, and numba
    checks a hash of the file's bytes before it loads (its source stamp), so the folder relative to
    kernels/ is all the path needed: any copy of the same source at any place finds the same cache."""

    def __init__(self, py_func, py_file):
        super().__init__(py_func, py_file)
        path = Path(py_file).resolve()
        key = COMPILE_KEYS[str(path)]
        self._cache_path = os.path.join(CACHE_ROOT, key, "kernels", *path.parent.relative_to(ROOT).parts)

    @classmethod
    def from_function(cls, py_func, py_file):
        if CACHE_ROOT is None or str(Path(py_file).resolve()) not in COMPILE_KEYS:
            return None
        self = cls(py_func, py_file)
        try:
            self.ensure_cache_path()
        except OSError:
            return None
        return self


if CACHE_ROOT is not None:
    # numba >= 0.60 names it CacheImpl, before that _CacheImpl.
    (getattr(caching, "CacheImpl", None) or caching._CacheImpl)._locator_classes.insert(0, KeyedCacheLocator)
    # Cached functions outside kernels/ (none in the package; tests may define some) keep a directory
    # keyed by the whole source, as before.
    numba.config.CACHE_DIR = os.path.join(CACHE_ROOT, f"other-{SOURCE_HASH}")
