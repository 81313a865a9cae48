"""Peak resident memory of every process a command starts (Linux): which process is the big one.

``/usr/bin/time -v`` reports one number, the largest maximum RSS among the command's descendants,
without saying which process it was.  This runs the command and, every ``--every`` seconds, reads
``VmHWM`` (the kernel's own record of a process's peak RSS) from /proc for each of its descendants,
so a process's peak is missed only by what it grows in its last interval.  At the end it prints the
``--top`` processes by peak, each with its command line, and the largest sum of RSS over the
processes alive at one moment (what the machine had to hold).

    python benchmarks/peak_rss.py -- pytest -q tests/test_methods.py
    python benchmarks/peak_rss.py --json peaks.json -- bash .ci/run

The command's exit status is passed on.  Reads /proc only: no third-party package.
"""

import argparse
import json
import os
import subprocess
import sys
import time


def _children_map():
    """{ppid: [pid, ...]} of every process readable in /proc."""
    kids = {}
    for name in os.listdir("/proc"):
        if not name.isdigit():
            continue
        try:
            with open(f"/proc/{name}/stat", "rb") as f:
                stat = f.read().decode(errors="replace")
        except OSError:
            continue
        # the command name (field 2) may hold spaces and parentheses: split after its last ")"
        ppid = int(stat[stat.rindex(")") + 2 :].split()[1])
        kids.setdefault(ppid, []).append(int(name))
    return kids


def _descendants(root):
    kids, out, todo = _children_map(), [], [root]
    while todo:
        pid = todo.pop()
        out.append(pid)
        todo.extend(kids.get(pid, ()))
    return out


def _memory_kib(pid):
    """(VmHWM, VmRSS) of pid in KiB, or None when it is gone or is a kernel thread."""
    try:
        with open(f"/proc/{pid}/status") as f:
            fields = dict(line.split(":", 1) for line in f if ":" in line)
    except OSError:
        return None
    if "VmHWM" not in fields:
        return None
    return int(fields["VmHWM"].split()[0]), int(fields["VmRSS"].split()[0])


def _cmdline(pid):
    try:
        with open(f"/proc/{pid}/cmdline", "rb") as f:
            return f.read().replace(b"\0", b" ").decode(errors="replace").strip()
    except OSError:
        return ""


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--every", type=float, default=0.2, help="seconds between samples (default 0.2)")
    parser.add_argument("--top", type=int, default=10, help="processes to list (default 10)")
    parser.add_argument("--json", help="also write every process's peak to this JSON file")
    parser.add_argument("command", nargs=argparse.REMAINDER, help="the command, after --")
    args = parser.parse_args(argv)
    command = args.command[1:] if args.command[:1] == ["--"] else args.command
    if not command:
        parser.error("no command given (put it after --)")
    if args.every <= 0:
        parser.error("--every must be > 0")

    start = time.monotonic()
    child = subprocess.Popen(command)
    peaks = {}  # pid -> [peak KiB, command line]
    held = 0  # largest sum of VmRSS over the processes alive at one sample
    while True:
        alive = 0
        for pid in _descendants(child.pid):
            mem = _memory_kib(pid)
            if mem is None:
                continue
            hwm, rss = mem
            alive += rss
            if pid not in peaks:
                peaks[pid] = [hwm, _cmdline(pid)]
            peaks[pid][0] = max(peaks[pid][0], hwm)
        held = max(held, alive)
        if child.poll() is not None:
            break
        time.sleep(args.every)
    wall = time.monotonic() - start

    ranked = sorted(peaks.items(), key=lambda item: -item[1][0])
    print(f"peak_rss: {len(peaks)} processes over {wall:.0f} s; largest held at once {held / 2**20:.2f} GiB")
    for pid, (kib, cmd) in ranked[: args.top]:
        print(f"  {kib / 2**20:6.2f} GiB  pid {pid:<7d} {cmd[:150]}")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(
                {
                    "command": command,
                    "wall_s": wall,
                    "held_kib": held,
                    "processes": [{"pid": p, "peak_kib": k, "cmdline": c} for p, (k, c) in ranked],
                },
                f,
                indent=1,
            )
    return child.returncode


if __name__ == "__main__":
    sys.exit(main())
