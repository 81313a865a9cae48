"""Which tests raise a pytest process's peak memory: a pytest plugin that records VmRSS and VmHWM (peak)
after every test, per process (xdist workers included), and a summary of the rises.

    PYTHONPATH=benchmarks GYROLAB_RSS_LOG=/tmp/rss pytest -p rss_per_test   # one JSON-lines file per process
    python benchmarks/rss_per_test.py /tmp/rss                              # per process: peak, top rises

The rise of a test is how much it raised its process's peak (VmHWM after it minus before it), so the
rises of one process add up to its peak less its collection.  Linux only (/proc/self/status).
"""

import json
import os
import sys
from pathlib import Path


def _status_kib():
    fields = {}
    with open("/proc/self/status") as f:
        for line in f:
            key, _, value = line.partition(":")
            if key in ("VmRSS", "VmHWM"):
                fields[key] = int(value.split()[0])
    return fields


_state = {}


def pytest_configure(config):
    directory = os.environ.get("GYROLAB_RSS_LOG")
    if not directory:
        return
    Path(directory).mkdir(parents=True, exist_ok=True)
    worker = os.environ.get("PYTEST_XDIST_WORKER", "main")
    path = Path(directory) / f"{worker}-{os.getpid()}.jsonl"  # never through a link planted at that name
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_APPEND | os.O_NOFOLLOW, 0o644)
    _state["file"] = os.fdopen(fd, "a")
    _state["worker"] = worker


def pytest_collection_finish(session):
    if "file" in _state:
        _write("<collection>")


def _write(nodeid):
    record = {"worker": _state["worker"], "test": nodeid, **_status_kib()}
    _state["file"].write(json.dumps(record) + "\n")
    _state["file"].flush()


def pytest_runtest_logfinish(nodeid, location):
    if "file" in _state:
        _write(nodeid)


def summarise(directory, top=12):
    """Per process: its peak (GiB), its collection's share and the tests that raised the peak most."""
    for path in sorted(Path(directory).glob("*.jsonl")):
        try:
            records = [json.loads(line) for line in path.read_text().splitlines() if line.strip()]
        except (OSError, UnicodeDecodeError, ValueError) as err:
            print(f"rss_per_test: {path}: not a record this plugin wrote ({err})", file=sys.stderr)
            sys.exit(2)
        if not records:
            continue
        rises, modules = [], {}
        for before, after in zip(records, records[1:]):
            rise = after["VmHWM"] - before["VmHWM"]
            if rise > 0:
                rises.append((rise, after["test"]))
                module = after["test"].split("::")[0]
                modules[module] = modules.get(module, 0) + rise
        first = records[0]
        print(
            f"{path.stem}: peak {records[-1]['VmHWM'] / 2**20:.2f} GiB over {len(records) - 1} tests; "
            f"after collection {first['VmHWM'] / 2**20:.2f} GiB"
        )
        for module, rise in sorted(modules.items(), key=lambda kv: -kv[1])[:top]:
            print(f"    +{rise / 1024:6.0f} MiB  {module}")
        for rise, test in sorted(rises, reverse=True)[:top]:
            print(f"        +{rise / 1024:6.0f} MiB  {test}")


if __name__ == "__main__":
    if len(sys.argv) != 2 or not Path(sys.argv[1]).is_dir():
        print("usage: python benchmarks/rss_per_test.py DIRECTORY (a pytest run's GYROLAB_RSS_LOG)", file=sys.stderr)
        sys.exit(2)
    summarise(sys.argv[1])
