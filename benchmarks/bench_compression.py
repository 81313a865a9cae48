"""Does an HDF5 compressor pay for results files?  Rewrite a file's per-sample variables with each filter.

    python benchmarks/bench_compression.py outputs/<date>/<time>/results.h5

For each filter (none; lzf; shuffle + lzf; gzip level 1; shuffle + gzip 1: the ones h5py ships, no
plugin) every per-sample variable of the file is written into a scratch file next to it with the
file's own HDF5 chunk shape, then fsync'd; prints the wall time of writing (s), the bytes and the
write rate of the uncompressed data (MB/s), and the time to read everything back (s).  A compressor
pays only if its write rate beats the disk's (``bench_pipeline.py --disk``) by enough to make up
for the CPU it costs, and the ratio is worth it.
"""

import argparse
import os
import time
from pathlib import Path

import h5py
import numpy as np

from gyrolab.results.layout import SAMPLE_VARIABLES

FILTERS = {
    "none": {},
    "lzf": {"compression": "lzf"},
    "shuffle+lzf": {"compression": "lzf", "shuffle": True},
    "gzip1": {"compression": "gzip", "compression_opts": 1},
    "shuffle+gzip1": {"compression": "gzip", "compression_opts": 1, "shuffle": True},
}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("file")
    args = parser.parse_args(argv)
    source = Path(args.file)
    with h5py.File(source, "r") as fh:
        data = {n: (fh[n][...], fh[n].chunks) for n in SAMPLE_VARIABLES if n in fh}
    raw = sum(a.nbytes for a, _ in data.values())
    print(f"{source}: {raw / 1e6:.0f} MB of per-sample data")
    print("filter | write s | stored MB | ratio | MB/s of data | read s")
    for name, opts in FILTERS.items():
        scratch = source.with_name(f".bench-compression-{name}.h5")
        start = time.perf_counter()
        with h5py.File(scratch, "w") as fh:
            for var, (values, chunks) in data.items():
                fh.create_dataset(var, data=values, chunks=chunks, **opts)
        with open(scratch, "rb") as f:
            os.fsync(f.fileno())
        write = time.perf_counter() - start
        stored = scratch.stat().st_size
        start = time.perf_counter()
        with h5py.File(scratch, "r") as fh:
            for var in data:
                np.asarray(fh[var][...])
        read = time.perf_counter() - start
        scratch.unlink()
        print(f"{name} | {write:.2f} | {stored / 1e6:.0f} | {raw / stored:.2f} | {raw / 1e6 / write:.0f} | {read:.2f}")


if __name__ == "__main__":
    main()
