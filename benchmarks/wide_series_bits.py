"""How far two gyrolab versions' lie_poisson4 trajectories differ, next to the method's truncation error.

    PYTHONPATH=OLD_INSTALL python benchmarks/wide_series_bits.py save old.npy   # e.g. pip install --target OLD_INSTALL
    python benchmarks/wide_series_bits.py save new.npy
    python benchmarks/wide_series_bits.py compare old.npy new.npy

``save``: the heavy top (50 Hz, 45°, released), 64 equal runs in blocks, 1 s, a sample every 0.01 s, at
dt = 1e-3 s (substeps up to ~0.5 rad: the doubled series since 2026-12-04, libm before) and 1e-4 s (below
0.2 rad: the series in both).  ``compare``: max |new − old| of the axis, ω and energy at each dt, and the
truncation error at 1e-3 s estimated as |x(dt = 1e-3) − x(dt = 1e-4)| of the first file.
"""

import sys

import numpy as np

FIELDS = {"axis": slice(0, 3), "omega": slice(3, 6), "energy": slice(6, 7)}


def save(path):
    from gyrolab.kernels.batch import integrate
    from gyrolab.kernels.scenes import build_scene

    sc = build_scene("heavy_top", 50.0, 45.0)
    runs = [np.tile(x, (64, 1)) for x in (sc.body, sc.omega0, sc.q0)]
    out = [
        integrate("lie_poisson4", *runs, dt, stride, 101, path="blocks")[0][0]
        for dt, stride in ((1e-3, 10), (1e-4, 100))
    ]
    np.save(path, np.stack(out))


def compare(old_path, new_path):
    old, new = np.load(old_path), np.load(new_path)
    for name, cols in FIELDS.items():
        coarse = np.abs(new[0][:, cols] - old[0][:, cols]).max()
        fine = np.abs(new[1][:, cols] - old[1][:, cols]).max()
        truncation = np.abs(old[0][:, cols] - old[1][:, cols]).max()
        where = f"{coarse:.2e} at dt 1e-3 s, {fine:.2e} at 1e-4 s"
        print(f"{name}: |new - old| {where}; truncation at 1e-3 s {truncation:.2e}")


if __name__ == "__main__":
    if len(sys.argv) == 3 and sys.argv[1] == "save":
        save(sys.argv[2])
    elif len(sys.argv) == 4 and sys.argv[1] == "compare":
        compare(sys.argv[2], sys.argv[3])
    else:
        sys.exit(__doc__.split("\n\n")[1])
