"""Bounded work on any input: the checks a reader makes before it loads a file it was handed.

- ``check_file_sizes(path)``: the bytes a file's variables declare (shape x item size, read from
  the HDF5 metadata only, nothing loaded) must fit the memory budget and be backed by the file:
  a 37 kB file declaring 2.4 GB (chunks never written, or a compression bomb) is refused before
  xarray would try to hold it.  gyrolab's own files are uncompressed, so their variables declare
  about the file's size.
- ``safe_yaml(text)``: a YAML attr (the stored ``config``) parsed with limits on its length, its
  nesting and its node count after alias expansion (a "billion laughs" bomb or a recursive alias
  is refused in one line, not 3 GB of memory or a RecursionError).

Each refusal is a ``LimitError`` (a ValueError) with one line; the openers (analysis/io.py,
analysis/files/compare.py, analysis/files/combine.py) turn it into their own one-line error and exit 2.
"""

import os

MEMORY_FRACTION = 0.5  # of MemAvailable a reader may fill with one file's variables
DEFAULT_BUDGET = 4 * 2**30  # bytes, when MemAvailable is unknown
BUDGET_ENV = "GYROLAB_READ_BUDGET"  # bytes; overrides the memory budget (tests, small machines)
# Declared bytes a file may hold beyond its own size: its variables' metadata and attrs aside, a file
# written without compression stores every byte it declares.  Slack for HDF5's fill values of a few
# unwritten chunks and for files written by other tools with light compression.
MAX_EXPANSION = 64
MIN_SLACK = 64 * 2**20  # bytes: small files may declare this much whatever their size

MAX_YAML_BYTES = 1 << 20
MAX_YAML_DEPTH = 64
MAX_YAML_NODES = 200_000


class LimitError(ValueError):
    """Input beyond what a reader will take on; the message is one line."""


def memory_budget():
    """Bytes one file's variables may take in memory: GYROLAB_READ_BUDGET, else MEMORY_FRACTION of
    MemAvailable (/proc/meminfo), else DEFAULT_BUDGET."""
    if os.environ.get(BUDGET_ENV):
        return int(float(os.environ[BUDGET_ENV]))
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(int(line.split()[1]) * 1024 * MEMORY_FRACTION)
    except OSError:
        pass
    return DEFAULT_BUDGET


def _size(n):
    for unit in ("B", "kB", "MB", "GB", "TB", "PB"):
        if n < 1000 or unit == "PB":
            return f"{n:.3g} {unit}"
        n /= 1000


def declared_bytes(path):
    """Total bytes the datasets of the HDF5 file ``path`` declare (shape x item size), from its
    metadata alone; OSError/ValueError as h5py raises them for a file it cannot open."""
    import h5py

    total = 0

    def visit(_, obj):
        nonlocal total
        if isinstance(obj, h5py.Dataset):
            shape = obj.shape or ()
            n = 1
            for s in shape:
                n *= int(s)
            total += n * obj.dtype.itemsize

    with h5py.File(path, "r") as fh:
        fh.visititems(visit)
    return total


def check_file_sizes(path, budget=None):
    """LimitError unless the variables of the HDF5 file ``path`` declare at most the memory budget
    and at most MAX_EXPANSION x its size (+ MIN_SLACK).  A file h5py cannot open is left to the
    caller's own reader (its error says why)."""
    try:
        declared = declared_bytes(path)
        size = os.stat(path).st_size
    except Exception:  # not HDF5, damaged, absent: the opener reports it in its own words
        return
    budget = memory_budget() if budget is None else budget
    if declared > budget:
        raise LimitError(
            f"{path}: its variables declare {_size(declared)}, more than the {_size(budget)} a reader may load "
            f"(set {BUDGET_ENV} to allow more)"
        )
    if declared > MAX_EXPANSION * size + MIN_SLACK:
        raise LimitError(
            f"{path}: its variables declare {_size(declared)} but the file holds {_size(size)} "
            "(unwritten or compressed far beyond a results file: refused without loading)"
        )


def safe_yaml(text, max_bytes=MAX_YAML_BYTES, max_depth=MAX_YAML_DEPTH, max_nodes=MAX_YAML_NODES):
    """``yaml.safe_load(text)`` after checking its length, nesting depth and node count with every
    alias expanded (a bomb or a recursive alias); LimitError (one line) beyond them, yaml.YAMLError
    for bad syntax."""
    import yaml

    text = text.decode(errors="replace") if isinstance(text, bytes) else str(text)
    if len(text) > max_bytes:
        raise LimitError(f"YAML attr of {len(text)} characters, more than {max_bytes}")
    root = yaml.compose(text, Loader=yaml.SafeLoader)
    if root is None:
        return None
    count = 0
    stack = [(root, 1, ())]  # node, depth, ids of the nodes above it (a cycle: a recursive alias)
    while stack:
        node, depth, above = stack.pop()
        count += 1
        if count > max_nodes:
            raise LimitError(f"YAML attr expands to more than {max_nodes} nodes (an alias bomb?)")
        if depth > max_depth:
            raise LimitError(f"YAML attr nested deeper than {max_depth} levels (a recursive alias?)")
        if id(node) in above:
            raise LimitError("YAML attr refers to itself (a recursive alias)")
        if isinstance(node, yaml.SequenceNode):
            children = node.value
        elif isinstance(node, yaml.MappingNode):
            children = [n for pair in node.value for n in pair]
        else:
            continue
        inner = above + (id(node),)
        stack.extend((child, depth + 1, inner) for child in children)
    return yaml.safe_load(text)
