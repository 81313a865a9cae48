"""Provenance attrs of a results file: what made it, with which code, when."""
import datetime
import subprocess
from pathlib import Path

import numba
import numpy as np

# The git work tree of the installed source (editable install: the repo).
SOURCE_DIR = Path(__file__).resolve().parents[1]


def git_commit(directory=SOURCE_DIR):
    """(commit sha, dirty) of the source tree; ("unknown", -1) outside git."""
    try:
        sha = subprocess.run(["git", "-C", str(directory), "rev-parse", "HEAD"], capture_output=True,
                             text=True, timeout=10, check=True).stdout.strip()
        status = subprocess.run(["git", "-C", str(directory), "status", "--porcelain", "--untracked-files=no"],
                                capture_output=True, text=True, timeout=10, check=True).stdout
    except (OSError, subprocess.SubprocessError):
        return "unknown", -1
    return sha, int(bool(status.strip()))


def provenance(config_yaml, threads):
    """File attrs: resolved config (YAML text), versions, git commit, numba threads, creation time (UTC ISO)."""
    from .. import __version__

    sha, dirty = git_commit()
    return {
        "config": config_yaml,
        "gyrolab_version": __version__,
        "git_commit": sha,
        "git_dirty": dirty,
        "numba_version": numba.__version__,
        "numpy_version": np.__version__,
        "threads": int(threads),
        "created": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
    }


# Attrs that differ between two runs of the same config (tests compare files without them).
VOLATILE_ATTRS = ("config", "created", "threads", "git_commit", "git_dirty", "gyrolab_version", "numba_version",
                  "numpy_version")
