"""Which keys of a sweep's resolved config identify the data of its results file.

The runner hashes the config without these keys to bind a journal to its sweep
(runner/config.py), and gyrolab-compare leaves them out when it compares two
files' configs: they change how a sweep is run, never what it computes.
"""

# Config keys that change how a sweep is run, not its data: left out of the data hash and of comparisons.
RUN_ONLY = {
    "output": ("path", "overwrite", "figures"),
    "runner": (
        "resume",
        "dry_run",
        "threads",
        "chunk_seconds",
        "backend",
        "address",
        "scheduler_file",
        "connect_timeout",
    ),
}

# Config keys whose default changes nothing a file written before the key existed holds: left out of
# the data hash and of comparisons while they have this value (output.variables=null: all stored).
NEUTRAL_DEFAULTS = {"output": {"variables": None}}


def drop_neutral_defaults(data):
    """``data`` (a resolved config as nested dicts) without the NEUTRAL_DEFAULTS keys at their default."""
    for group, keys in NEUTRAL_DEFAULTS.items():
        node = data.get(group)
        if isinstance(node, dict):
            for key, default in keys.items():
                if key in node and node[key] == default:
                    node.pop(key)
    return data


# The libraries whose versions a results file records (runner/provenance.py).
LIBRARIES = ("numpy", "numba", "scipy", "h5py", "h5netcdf", "xarray")
# Attrs that differ between two runs of the same config (tests compare files without them).
VOLATILE_ATTRS = (
    "config",
    "created",
    "threads",
    "git_commit",
    "git_dirty",
    "git_source",
    "gyrolab_version",
    "kernel_source_hash",
    "python_version",
    *(f"{name}_version" for name in LIBRARIES),
)
