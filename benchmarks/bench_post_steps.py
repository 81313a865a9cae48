"""The post-steps the dry run counts after the results file: the figure step and the verdict study's.

    python benchmarks/bench_post_steps.py figures [--kinds nutation,tip]  # each figure kind on files of a few sizes
    python benchmarks/bench_post_steps.py verdict                         # the verdict callback's parts
    python benchmarks/bench_post_steps.py estimate -- OVERRIDES...        # the figure step's estimate of a sweep

Times are CPU seconds of this one process (``time.process_time``): the figures are single-threaded and
the machine these were fitted on was loaded by other work, so the CPU time stands for the wall time on
a quiet machine (the bisection's kernels run on numba's threads: its CPU time over the threads it used).
Each line prints the measurement next to the model's estimate (analysis/figures/cost.py,
analysis/verdicts/cost.py); the coefficients there were fitted to these lines.

``figures``: results files written by the runner's own grid, chunks and store (methods whose kernels
the numba cache holds are quick: point NUMBA_CACHE_DIR at a warm cache), then each figure kind drawn
on each (``Figure.write``, as the figure step does: the file opened lazily).  ``import`` is the CPU of
importing the figure modules and matplotlib, paid once by the first figure of a sweep.

``verdict``: a verdict-like multirun directory (per scene a dt ladder of 1 s and a long run at dt = 1e-3
s), then ``verdict`` without the bisection (reading, orders, drift classes), the bisection of each
method (``method_stability_threshold``, 10 s), and ``write_outputs`` (markdown, json, one figure per
scene), each timed.
"""

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

# the default study's methods; chunks of fewer than MIN_BLOCK_RUNS runs: only their run kernels are needed
METHODS = ["seed_next", "seed_prev", "rk4", "lie_poisson", "lie_poisson4"]
# (methods, f values, theta0 values, dt values, t_end s, every s): the figure step's files
SIZES = [
    (2, 1, 1, 1, 1.0, 1e-3),
    (5, 3, 1, 3, 1.0, 1e-3),
    (5, 3, 1, 3, 10.0, 1e-3),
    (5, 25, 2, 2, 1.0, 1e-3),
]


def compose(*overrides):
    from hydra import compose, initialize_config_module

    from gyrolab.runner.config import register_configs

    register_configs()
    with initialize_config_module(config_module="gyrolab.conf", version_base=None):
        return compose("config", overrides=list(overrides))


def write_file(path, *overrides):
    """The results file of ``overrides`` through the runner's grid, chunks (one per method) and store."""
    from gyrolab.runner.config import config_hash
    from gyrolab.runner.execute import run_chunk
    from gyrolab.runner.grid import build_grid
    from gyrolab.runner.store import write_results
    from gyrolab.runner.sweep import file_attrs

    cfg = compose(*overrides)
    grid = build_grid(cfg)
    from gyrolab.kernels.batch import MIN_BLOCK_RUNS

    per_method = grid.n_runs // len(grid.methods)
    chunks = [
        run_chunk(grid, np.arange(start, min(start + MIN_BLOCK_RUNS - 1, stop)), 2)
        for k in range(len(grid.methods))
        for stop in [(k + 1) * per_method]
        for start in range(k * per_method, stop, MIN_BLOCK_RUNS - 1)
    ]
    write_results(path, grid, chunks, file_attrs(cfg, grid, 2, config_hash(cfg)))
    return grid


def _list(values):
    return "[" + ",".join(f"{v:g}" if not isinstance(v, str) else v for v in values) + "]"


def bench_figures(kinds, scratch):
    t = time.process_time()
    import matplotlib.pyplot  # noqa: F401

    from gyrolab.analysis.figures.registry import FIGURES

    print(f"import: {time.process_time() - t:.2f} s CPU")
    from gyrolab.analysis.figures.cost import figure_seconds
    from gyrolab.results import open_results

    kinds = kinds or list(FIGURES)
    print("kind | methods x f x theta0 x dt | samples | measured CPU s | model s")
    for k, (nm, nf, nt, nd, t_end, every) in enumerate(SIZES):
        path = Path(scratch) / f"size{k}.h5"
        grid = write_file(
            path,
            f"sweep.method={_list(METHODS[:nm])}",
            f"sweep.f={_list(np.linspace(1, 50, nf))}",
            f"sweep.theta0={_list(np.linspace(30, 60, nt))}",
            f"sweep.dt={_list([1e-3, 5e-4, 2.5e-4][:nd])}",
            f"sweep.t_end={t_end:g}",
            f"output.every={every:g}",
        )
        for kind in kinds:
            ds = open_results(str(path), lazy=True)
            try:
                t = time.process_time()
                try:
                    FIGURES[kind].write(ds, Path(scratch) / f"{kind}{k}.png", notes=[])
                    took = f"{time.process_time() - t:.2f}"
                except Exception as err:  # a kind this grid cannot draw (e.g. sciml on the heavy top)
                    took = f"failed ({type(err).__name__}: {str(err)[:60]})"
            finally:
                ds.close()
            model = figure_seconds(kind, grid.shape, grid.n_samples)
            print(f"{kind} | {' x '.join(map(str, grid.shape))} | {grid.n_samples} | {took} | {model:.2f}", flush=True)


def bench_verdict(scratch, scenes=("heavy_top", "free_asymmetric"), methods=METHODS, stability=10.0):
    from gyrolab.analysis.io import build_run_scene
    from gyrolab.analysis.verdicts.classify import method_stability_threshold
    from gyrolab.analysis.verdicts.cost import bisection_seconds, bisection_trials, verdict_seconds
    from gyrolab.analysis.verdicts.verdict import load, verdict, write_outputs
    from gyrolab.runner.grid import step_rate

    root = Path(scratch) / "verdict"
    grids = []
    for k, scene in enumerate(scenes):
        for j, part in enumerate(("verdict_ladder", "verdict_long")):
            d = root / str(2 * k + j)
            d.mkdir(parents=True, exist_ok=True)
            over = [f"scene={scene}", f"+experiment@_global_={part}", f"sweep.method={_list(methods)}"]
            grids.append(write_file(d / f"{part.split('_')[1]}.h5", *over))
    model = verdict_seconds(grids, stability, step_rate)
    for j, part in enumerate(("ladders", "long runs")):  # what the reading costs: the ladders' references, the series
        dirs = [root / str(2 * k + j) for k in range(len(scenes))]
        t = time.process_time()
        verdict(dirs)
        print(f"reading and classifying the {part} alone: {time.process_time() - t:.2f} s CPU")
    t = time.process_time()
    records = verdict([root])
    datasets = load([root])
    print(f"reading and classifying: {time.process_time() - t:.2f} s CPU, model {model['reading']:.2f} s")
    total = 0.0
    for _, ds in datasets[::2]:  # one bisection per scene and method, at the first (f, theta0)
        f, th = float(ds.f.values[0]), float(ds.theta0.values[0])
        scene = build_run_scene(ds, f, th)
        omega = float(np.linalg.norm(scene.omega0))
        for m in methods:
            t = time.process_time()
            method_stability_threshold(m, scene, stability)
            took = time.process_time() - t  # numba's threads: CPU of all of them
            total += took
            steps = sum(float(c.sum()) for c in bisection_trials(omega, stability))
            cpu = steps / step_rate(m, 4, False)  # every step on one core at grid.py's rate
            wall = bisection_seconds(m, omega, stability, step_rate)
            print(
                f"bisection {scene.name} {m}: {took:.2f} s CPU for {steps:.3g} steps "
                f"({took / steps * 1e9:.0f} ns/step), "
                f"model {cpu:.2f} s CPU ({1e9 / step_rate(m, 4, False):.0f} ns/step), {wall:.2f} s wall on 2 threads"
            )
    print(f"bisection total: {total:.2f} s CPU, model {model['bisection']:.2f} s wall on 2 threads")
    t = time.process_time()
    write_outputs(records, root / "v.json", root / "v.md", None, datasets)
    print(f"writing md and json: {time.process_time() - t:.2f} s CPU, model {model['writing']:.2f} s")
    t = time.process_time()
    write_outputs(records, None, None, root / "figures", datasets)
    print(f"figures ({len(scenes)} scenes): {time.process_time() - t:.2f} s CPU, model {model['figures']:.2f} s")


def estimate(overrides):
    """The figure step's estimate (analysis/figures/cost.py) for ``gyrolab OVERRIDES``'s grid and figures."""
    from omegaconf import OmegaConf

    from gyrolab.analysis import figure_names, figure_step_seconds
    from gyrolab.runner.grid import build_grid

    cfg = compose(*overrides)
    grid = build_grid(cfg)
    setting = cfg.output.figures
    names = figure_names(OmegaConf.to_container(setting) if OmegaConf.is_list(setting) else setting)
    each, total = figure_step_seconds(names, grid.shape, grid.n_samples)
    words = ", ".join(f"{k}: {v:.2g} s" for k, v in each.items())
    print(f"figure step: {total:.3g} s ({words}; importing matplotlib and the figures once)")


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("what", choices=("figures", "verdict", "estimate"))
    parser.add_argument("--scenes", default="heavy_top,free_asymmetric", help="verdict: the scenes")
    parser.add_argument("overrides", nargs="*", help="estimate: the sweep's Hydra overrides")
    parser.add_argument("--kinds", default="", help="comma-separated figure kinds (default: every one)")
    args = parser.parse_args(argv)
    if args.what == "estimate":
        return estimate(args.overrides)
    with tempfile.TemporaryDirectory() as scratch:
        if args.what == "figures":
            bench_figures([k for k in args.kinds.split(",") if k], scratch)
        else:
            bench_verdict(scratch, scenes=args.scenes.split(","))


if __name__ == "__main__":
    sys.exit(main())
