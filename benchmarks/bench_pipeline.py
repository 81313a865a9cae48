"""The whole pipeline, end to end: wall time of ``gyrolab`` split into its phases, and peak RSS.

    python benchmarks/bench_pipeline.py                       # every case, 3 repetitions each
    python benchmarks/bench_pipeline.py --case big --repeat 3 --gyrolab /other/venv/bin/gyrolab
    python benchmarks/bench_pipeline.py --disk                # only the disk's write bandwidth (dd, fsync)

Each case runs ``gyrolab <overrides> output.figures=false hydra.run.dir=<scratch>`` in a subprocess
(after one untimed run that loads the numba cache), reads the runner's closing line ``results: ...
in T s (I s integrating, J s journal, A s assembly)`` (a gyrolab from before that split prints only
``(I s integrating)``, journal writes included) and the process's peak RSS (``os.wait4``), and
prints the median of each over the repetitions (seconds, MB).  ``--gyrolab`` runs another
installed version for an A/B comparison.  Cases:

- ``big``: the issue's 8000-run sweep (4 methods x 100 f x 5 theta0 x 4 dt, 10 s, 1001 samples);
- ``short``: 10^5 short runs (4 methods x 100 f x 25 theta0 x 10 dt, 0.01 s, 11 samples);
- ``mixed``: a mixed-dt grid (dt = 1e-3 and 1e-5 s), where the dry run used to be 120x low.

Every case also prints the dry run's estimate (its first number, ``estimated time: T s``) and its
ratio to the measured time to the results file.

``--disk`` writes 1 GiB with ``dd ... conv=fsync`` into the scratch directory (MB/s).
Timings move with the machine's load: the script prints ``uptime`` before each case.
"""

import argparse
import math
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

METHODS4 = "sweep.method=[seed_next,rk4,lie_poisson,lie_poisson4]"


def _list(values):
    return "[" + ",".join(f"{v:g}" for v in values) + "]"


CASES = {
    "big": [
        f"sweep.f={_list(range(1, 101))}",
        "sweep.theta0=[15,30,45,60,75]",
        "sweep.dt=[1e-4,2e-4,5e-4,1e-3]",
        METHODS4,
        "sweep.t_end=10",
        "output.every=1e-2",
    ],
    "short": [
        f"sweep.f={_list(range(1, 101))}",
        f"sweep.theta0={_list(range(5, 130, 5))}",
        "sweep.dt=[1e-4,2e-4,2.5e-4,5e-4,1e-3,1.25e-4,5e-5,4e-5,2e-5,1e-5]",
        METHODS4,
        "sweep.t_end=0.01",
        "output.every=1e-3",
    ],
    "mixed": [
        "sweep.f=[1,10,50]",
        "sweep.theta0=[30,45,60]",
        "sweep.dt=[1e-3,1e-5]",
        "sweep.method=[seed_next,lie_poisson4]",
        "sweep.t_end=10",
        "output.every=1e-2",
    ],
}
CLOSING = re.compile(
    r"results: .* in ([\d.]+) s \(([\d.]+) s integrating(?:, ([\d.]+) s journal, ([\d.]+) s assembly)?\)"
)
ESTIMATE = re.compile(r"estimated time: ([\d.e+-]+) s")


def measure(exe, overrides, scratch, repeat):
    """Median over ``repeat`` runs of: the process's wall time, the runner's time to the results file
    and its phases (s; ``rest`` = JIT load, checks and what the phases leave out), peak RSS and file
    size (MB)."""
    rows = []
    for i in range(repeat):
        run_dir = Path(scratch) / f"run{i}"
        start = time.perf_counter()
        proc = subprocess.Popen(
            [exe, *overrides, "output.figures=false", f"hydra.run.dir={run_dir}"],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            env={**os.environ, "TQDM_DISABLE": "1"},
        )
        out = proc.stdout.read().decode()
        err = proc.stderr.read().decode()
        _, status, usage = os.wait4(proc.pid, 0)
        proc.returncode = os.waitstatus_to_exitcode(status)
        wall = time.perf_counter() - start
        if proc.returncode != 0:
            raise SystemExit(f"bench_pipeline: gyrolab failed ({proc.returncode}): {err.strip()[-400:]}")
        match = CLOSING.search(out)
        if not match:
            raise SystemExit(f"bench_pipeline: no closing line in: {out[-400:]}")
        total, integ, journal, assembly = (float(g) if g is not None else float("nan") for g in match.groups())
        size = sum(p.stat().st_size for p in run_dir.glob("*.h5"))
        rows.append(
            {
                "process": wall,
                "to_file": total,
                "integrating": integ,
                "journal": journal,
                "assembly": assembly,
                "rest": total - integ - sum(x for x in (journal, assembly) if not math.isnan(x)),
                "rss_mb": usage.ru_maxrss / 1024,
                "file_mb": size / 1e6,
            }
        )
        print("  run", i, " ".join(f"{k}={v:.3g}" for k, v in rows[-1].items()), flush=True)
        shutil.rmtree(run_dir, ignore_errors=True)
    return {k: statistics.median(r[k] for r in rows) for k in rows[0]}


def dry_estimate(exe, overrides, scratch):
    out = subprocess.run(
        [exe, *overrides, "runner.dry_run=true", f"hydra.run.dir={Path(scratch) / 'dry'}"],
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    match = ESTIMATE.search(out)
    return float(match.group(1)) if match else float("nan"), out


def disk_bandwidth(scratch, megabytes=1024):
    """MB/s of writing ``megabytes`` MiB with dd and a final fsync (conv=fsync)."""
    target = Path(scratch) / "dd.bin"
    start = time.perf_counter()
    subprocess.run(
        ["dd", "if=/dev/zero", f"of={target}", "bs=1M", f"count={megabytes}", "conv=fsync"],
        check=True,
        capture_output=True,
    )
    seconds = time.perf_counter() - start
    target.unlink()
    return megabytes * 2**20 / 1e6 / seconds


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--case", choices=[*CASES, "all"], default="all")
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--gyrolab", default=str(Path(sys.executable).parent / "gyrolab"))
    parser.add_argument("--scratch", default=None, help="directory for the runs (default: a temporary one)")
    parser.add_argument("--disk", action="store_true", help="only measure the disk's write bandwidth")
    args = parser.parse_args(argv)
    scratch = Path(tempfile.mkdtemp(prefix="bench-pipeline-", dir=args.scratch))
    try:
        if args.disk:
            rates = [disk_bandwidth(scratch) for _ in range(args.repeat)]
            print(f"disk: dd bs=1M count=1024 conv=fsync: median {statistics.median(rates):.0f} MB/s of {rates}")
            return
        cases = list(CASES) if args.case == "all" else [args.case]
        subprocess.run(
            [args.gyrolab, *CASES["mixed"][:1], "sweep.theta0=[45]", "sweep.dt=[1e-3]", METHODS4]
            + ["sweep.t_end=0.1", "output.figures=false", f"hydra.run.dir={scratch / 'warm'}"],
            check=True,
            capture_output=True,
        )  # load (or compile) the numba cache before timing
        shutil.rmtree(scratch / "warm", ignore_errors=True)
        for case in cases:
            overrides = CASES[case]
            print(f"case {case}: {args.gyrolab} {' '.join(overrides)} output.figures=false")
            print("  uptime:", subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip())
            med = measure(args.gyrolab, overrides, scratch, args.repeat)
            print(f"  median of {args.repeat}: " + ", ".join(f"{k} {v:.3g}" for k, v in med.items()))
            estimate, _ = dry_estimate(args.gyrolab, overrides, scratch)  # the dry run against the measurement
            print(
                f"  dry-run estimate {estimate:.3g} s; measured to the file {med['to_file']:.3g} s; "
                f"ratio {estimate / med['to_file']:.2f}"
            )
            print("  uptime:", subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip(), flush=True)
    finally:
        shutil.rmtree(scratch, ignore_errors=True)


if __name__ == "__main__":
    main()
