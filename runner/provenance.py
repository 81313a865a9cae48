"""Provenance attrs of a results file: what made it, with which code, when.

The commit is the one the package was built from (setup.py bakes it into
``gyrolab/_build_info.py``), never a ``git`` call on the installed directory
at run time, which would describe whatever checkout surrounds it.  Only when
the package runs straight from a git work tree (an editable install, or
``python -c "import gyrolab"`` in a checkout) is the commit that work tree's,
read when the file is written: that tree is then the code that runs.  The
kernel-source hash (kernels/__init__.py) names the kernel code exactly, in
either case.
"""

import datetime
import subprocess
import sys
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

from ..results.identity import LIBRARIES

PACKAGE_DIR = Path(__file__).resolve().parents[1]  # installed: .../gyrolab; work tree: the checkout


def _work_tree_state(directory):
    try:

        def git(*args):
            return subprocess.run(
                ["git", "-C", str(directory), *args], capture_output=True, text=True, timeout=10, check=True
            ).stdout.strip()

        if Path(git("rev-parse", "--show-toplevel")).resolve() != Path(directory).resolve():
            return "unknown", -1  # some other repository that merely contains the installation
        return git("rev-parse", "HEAD"), int(bool(git("status", "--porcelain", "--untracked-files=no")))
    except (OSError, subprocess.SubprocessError):
        return "unknown", -1


def code_state():
    """(commit, dirty, source): the code that runs; source is "build", "work tree" or "unknown"."""
    try:
        from .. import _build_info
    except ImportError:
        pass
    else:
        return _build_info.GIT_COMMIT, int(_build_info.GIT_DIRTY), "build"
    if (PACKAGE_DIR / "pyproject.toml").is_file() and (PACKAGE_DIR / "kernels").is_dir():
        commit, dirty = _work_tree_state(PACKAGE_DIR)
        return commit, dirty, "work tree" if commit != "unknown" else "unknown"
    return "unknown", -1, "unknown"


def library_versions():
    """{"<name>_version": version} of the libraries whose behaviour the results depend on."""
    out = {}
    for name in LIBRARIES:
        try:
            out[f"{name}_version"] = version(name)
        except PackageNotFoundError:
            out[f"{name}_version"] = "absent"
    return out


def engine_versions(config_yaml):
    """{"engine_versions": "mujoco 4.0.0, pybullet 3.2.7"} when the config's sweep.method names real engines
    (kernels/real/), else {} (so a file without them has the attrs it always had)."""
    import yaml

    from ..kernels.real import engine_versions as versions

    methods = ((yaml.safe_load(config_yaml) or {}).get("sweep") or {}).get("method") or []
    text = versions([str(m) for m in methods])
    return {"engine_versions": text} if text else {}


def provenance(config_yaml, threads):
    """File attrs: resolved config (YAML text), code and library versions (and the real engines' when the
    sweep runs any), numba threads, creation time (UTC ISO)."""
    from ..kernels import SOURCE_HASH
    from ..version import __version__

    commit, dirty, source = code_state()
    return {
        "config": config_yaml,
        "gyrolab_version": __version__,
        "git_commit": commit,
        "git_dirty": dirty,
        "git_source": source,
        "kernel_source_hash": SOURCE_HASH,
        "python_version": ".".join(map(str, sys.version_info[:3])),
        **library_versions(),
        **engine_versions(config_yaml),
        "threads": int(threads),
        "created": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
    }
