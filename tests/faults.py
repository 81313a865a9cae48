"""Fault injection for tests/test_faults.py: damaged files and journals, signals, a full disk.

- ``BAD_FILES``: {name: make(path, good)} writes a bad results file at ``path``
  (``good``: a valid results file to damage or strip);
- ``CHUNK_FAULTS``: {name: damage(journal, chunk_path)} damages one journal
  chunk; those marked ``resealed`` rewrite the manifest's checksum, so the
  deeper content checks (not the checksum) must catch them;
- ``interrupt(...)``: start a sweep, wait for a point of integration or
  assembly, send a signal;
- ``small_disk(root)``: a tmpfs of a few MB when this process may mount one
  (root in a container), else None; ``fill(dir)`` fills its file system.
"""

import contextlib
import errno
import io
import json
import os
import random
import shutil
import subprocess
import sys
import time
from pathlib import Path

import h5py
import numpy as np
import xarray as xr

from gyrolab.runner.store import Journal, sha256

from helpers import start

# --------------------------------------------------------------------------- bad results files


def _strip_variable(name):
    def make(path, good):
        with xr.open_dataset(good, engine="h5netcdf") as ds:
            ds.load().drop_vars(name).to_netcdf(path, engine="h5netcdf")

    return make


def _foreign_hdf5(path, good):
    with h5py.File(path, "w") as fh:
        fh["x"] = np.arange(10.0)
        fh.attrs["scene"] = "heavy_top"


def _foreign_netcdf(path, good):
    xr.Dataset({"x": ("time", np.arange(5.0))}, coords={"time": np.arange(5.0)}).to_netcdf(path, engine="h5netcdf")


def _no_layout_version(path, good):
    with xr.open_dataset(good, engine="h5netcdf") as ds:
        ds = ds.load()
    # no layout version and no provenance: not a layout-0 gyrolab file either (those are read)
    for key in ("layout_version", "gyrolab_version"):
        ds.attrs.pop(key, None)
    ds.to_netcdf(path, engine="h5netcdf")


def _truncated(path, good):
    data = Path(good).read_bytes()
    Path(path).write_bytes(data[: len(data) // 2])


def _damaged_metadata(path, good):
    """The superblock and root group header overwritten (bytes 8..2048 after the signature)."""
    data = bytearray(Path(good).read_bytes())
    rng = random.Random(1)
    for i in range(8, min(2048, len(data))):
        data[i] = rng.randrange(256)
    Path(path).write_bytes(bytes(data))


def _edit(change):
    """A fault made by ``change(ds) -> ds`` on the good file loaded in memory, written with h5netcdf."""

    def make(path, good):
        with xr.open_dataset(good, engine="h5netcdf") as ds:
            ds = change(ds.load())
        ds.to_netcdf(path, engine="h5netcdf")

    return make


def _coord(dim, change):
    """The coordinate ``dim`` replaced by ``change(values)`` (same length)."""

    def edit(ds):
        return ds.assign_coords({dim: (dim, change(ds[dim].values.copy()), ds[dim].attrs)})

    return _edit(edit)


def _set(values, index, value):
    values[index] = value
    return values


def _twice(dim):
    """Every run stored twice along ``dim`` (a duplicate coordinate value)."""
    return _edit(lambda ds: xr.concat([ds, ds], dim=dim, data_vars="minimal", coords="minimal", compat="override"))


def _variable(name, change):
    return _edit(lambda ds: ds.assign({name: change(ds[name])}))


def _attrs(**attrs):
    return _edit(lambda ds: ds.assign_attrs(attrs))


def _body(field, value):
    def edit(ds):
        body = ds["body"].copy()
        body.loc[{"body_param": field}] = value
        return ds.assign(body=body)

    return _edit(edit)


def _time_scaled(path, good):
    """The time axis stretched to end at 1e308 s (attrs left as they were)."""
    _coord("time", lambda t: t / t[-1] * 1e308)(path, good)


def _huge_time_and_attrs(path, good):
    """The time axis, t_end and every stretched together to 1e308 s: consistent with each other, not with dt."""

    def edit(ds):
        last = float(ds["time"].values[-1])  # divided first: 1e308 / last overflows
        ds = ds.assign_coords(time=("time", ds["time"].values / last * 1e308, ds["time"].attrs))
        return ds.assign_attrs(
            t_end=float(ds.attrs["t_end"]) / last * 1e308, every=float(ds.attrs["every"]) / last * 1e308
        )

    _edit(edit)(path, good)


# Faults in the content of a readable file: every command must refuse them (one line, exit 2) or, for
# VALID_FILES, answer correctly.
CONTENT_FAULTS = {
    "zero_runs_f": _edit(lambda ds: ds.isel(f=slice(0, 0))),
    "zero_runs_integrator": _edit(lambda ds: ds.isel(integrator=slice(0, 0))),
    "zero_samples": _edit(lambda ds: ds.isel(time=slice(0, 0))),
    "one_sample": _edit(lambda ds: ds.isel(time=[0])),
    "duplicate_f": _twice("f"),
    "duplicate_dt": _twice("dt"),
    "nan_f": _coord("f", lambda v: v * np.nan),
    "inf_dt": _coord("dt", lambda v: v * np.inf),
    "nan_theta0": _coord("theta0", lambda v: v * np.nan),
    "nan_time": _coord("time", lambda t: _set(t, 5, np.nan)),
    "inf_time": _coord("time", lambda t: _set(t, -1, np.inf)),
    "time_not_increasing": _coord("time", lambda t: _set(t, 3, t[1])),
    "time_reversed": _coord("time", lambda t: t[::-1].copy()),
    "negative_dt": _coord("dt", lambda v: -v),
    "zero_dt": _coord("dt", lambda v: v * 0.0),
    "int_samples": _variable("energy", lambda v: (v * 1000).astype(np.int64)),
    "float32_samples": _variable("axis", lambda v: v.astype(np.float32)),
    "float_status": _variable("status", lambda v: v.astype(np.float64) + 0.5),
    "status_7": _variable("status", lambda v: v * 0 + 7),
    "status_minus_3": _variable("status", lambda v: v * 0 - 3),
    "solver_iterations_minus_2": _variable("solver_iterations", lambda v: v * 0 - 2),
    "solver_max_over_total": _variable("solver_iterations_max", lambda v: v + 1),
    "float_solver_iterations": _variable("solver_iterations", lambda v: v.astype(np.float64) + 0.5),
    "energy_without_time": _variable("energy", lambda v: v.isel(time=0)),
    "axis_without_xyz": _variable("axis", lambda v: v.isel(xyz=0)),
    "xyz_relabelled": _coord("xyz", lambda v: np.array(["a", "b", "c"])),
    "body_param_relabelled": _coord("body_param", lambda v: np.array([f"p{k}" for k in range(v.size)])),
    "layout_99": _attrs(layout_version=99),
    "layout_minus_1": _attrs(layout_version=-1),
    "layout_string": _attrs(layout_version="three"),
    "layout_fraction": _attrs(layout_version=2.5),
    "unknown_scene": _attrs(scene="no_such_scene"),
    "unknown_invariant": _attrs(conserved="energy warp_factor"),
    "body_nan_moment": _body("I1", np.nan),
    "body_negative_moment": _body("I2", -1.0),
    "t_end_inconsistent": _attrs(t_end=5.0),
    "every_inconsistent": _attrs(every=0.5),
    "huge_time": _time_scaled,
    "huge_time_and_attrs": _huge_time_and_attrs,
}

# Files that are valid: every command answers them correctly (exit 0 and its output) or refuses in one
# line with exit 2 before writing anything (e.g. ``gyrolab-plot seed`` on a file that is not a
# seed_figures job, ``work-precision`` without a peer).
VALID_FILES = {
    "ordinary": lambda path, good: shutil.copyfile(good, path),
    # a method this gyrolab does not know (a newer gyrolab's, or renamed): its data are still data
    "unknown_integrator": _coord("integrator", lambda v: np.array(["no_such_method"] * v.size)),
}
# gyrolab-compare's right answer for each valid file against the good one: SAME (0) or DIFFERENT (1)
VALID_COMPARE = {"ordinary": 0, "unknown_integrator": 1}

BAD_FILES = {
    "empty": lambda path, good: Path(path).write_bytes(b""),
    "garbage": lambda path, good: Path(path).write_bytes(os.urandom(4096)),
    "truncated": _truncated,
    "damaged_metadata": _damaged_metadata,
    "foreign_hdf5": _foreign_hdf5,
    "foreign_netcdf": _foreign_netcdf,
    "no_layout_version": _no_layout_version,
    "missing_energy": _strip_variable("energy"),
    "missing_status": _strip_variable("status"),
    "missing_solver_iterations": _strip_variable("solver_iterations"),
    "directory": lambda path, good: Path(path).mkdir(),
    **CONTENT_FAULTS,
}


# --------------------------------------------------------------------------- damaged journal chunks


def _rewrite(journal, path, **changes):
    """Rewrite a chunk with some arrays changed and reseal its manifest checksum."""
    with np.load(path) as data:
        arrays = {k: data[k] for k in data.files}
    arrays.update(changes)
    with open(path, "wb") as fh:
        np.savez(fh, **arrays)
    reseal(journal, path)


def reseal(journal, path):
    """Make the manifest's entry agree with the chunk file as it now is: the HMAC the file carries
    ("mac"), or, for a file that no longer has one, the file's sha256 as an older gyrolab listed it."""
    manifest = json.loads(journal.manifest_path.read_text())
    entry = manifest["chunks"][path.name]
    entry.pop("mac", None)
    entry.pop("sha256", None)
    try:
        with np.load(path) as data:
            if "runs" in data.files:
                entry["runs"] = int(data["runs"].size)
            entry["mac"] = str(data["mac"])
    except Exception:  # a file damaged on purpose, or one without a proof
        entry["sha256"] = sha256(path)
    journal.manifest_path.write_text(json.dumps(manifest))


def _flip_byte(journal, path):
    data = bytearray(path.read_bytes())
    data[len(data) // 2] ^= 0xFF
    path.write_bytes(bytes(data))


def _unlisted(journal, path):
    manifest = json.loads(journal.manifest_path.read_text())
    del manifest["chunks"][path.name]
    journal.manifest_path.write_text(json.dumps(manifest))


def _nan_finished(journal, path):
    with np.load(path) as data:
        samples = data["samples"].copy()
    samples[0, 3:] = np.nan
    _rewrite(journal, path, samples=samples)


def _foreign(journal, path):
    with open(path, "wb") as fh:
        np.savez(fh, x=np.arange(3))
    reseal(journal, path)


CHUNK_FAULTS = {
    "empty": lambda j, p: p.write_bytes(b""),
    "truncated": lambda j, p: p.write_bytes(p.read_bytes()[: p.stat().st_size // 2]),
    "flipped_byte": _flip_byte,
    "garbage": lambda j, p: p.write_bytes(os.urandom(2048)),
    "unlisted_truncated": lambda j, p: (_unlisted(j, p), p.write_bytes(p.read_bytes()[: p.stat().st_size // 2])),
    "unlisted_nan_samples_status_0": lambda j, p: (_nan_finished(j, p), _unlisted(j, p)),
    # resealed: the checksum matches, the content must be checked
    "resealed_truncated": lambda j, p: (p.write_bytes(p.read_bytes()[: p.stat().st_size // 2]), reseal(j, p)),
    "resealed_foreign": _foreign,
    "resealed_runs_out_of_range": lambda j, p: _rewrite(j, p, runs=np.load(p)["runs"] + 10**6),
    "resealed_negative_runs": lambda j, p: _rewrite(j, p, runs=np.load(p)["runs"] - 10**6),
    "resealed_wrong_sample_shape": lambda j, p: _rewrite(j, p, samples=np.load(p)["samples"][:, :-1]),
    "resealed_wrong_status_shape": lambda j, p: _rewrite(j, p, status=np.load(p)["status"][:-1]),
    "resealed_nan_samples_status_0": _nan_finished,
    "resealed_duplicate_runs": None,  # made by the test: a copy of another chunk under a new name
}

MANIFEST_FAULTS = {
    "empty": b"",
    "garbage": b"\x00\xffnot json",
    "not_an_object": b"[1, 2, 3]",
    "no_config_hash": b'{"n_runs": 16}',
    "bad_chunks_table": b'{"config_hash": "x", "chunks": [1]}',
    "bad_n_runs": b'{"config_hash": "x", "n_runs": -3, "chunks": {}}',
}


def damage_chunk(run_dir, fault, index=0):
    """Apply CHUNK_FAULTS[fault] to the ``index``-th chunk of ``run_dir``'s journal; returns its name."""
    journal = Journal(Path(run_dir) / "results.h5")
    files = journal.chunk_files()
    path = files[index]
    if fault == "resealed_duplicate_runs":
        other = files[(index + 1) % len(files)]
        copy = journal.dir / "chunk-09999.npz"
        shutil.copy(other, copy)
        manifest = json.loads(journal.manifest_path.read_text())
        manifest["chunks"][copy.name] = dict(manifest["chunks"][other.name])
        journal.manifest_path.write_text(json.dumps(manifest))
        return copy.name
    CHUNK_FAULTS[fault](journal, path)
    return path.name


# --------------------------------------------------------------------------- signals


def stray_files(run_dir):
    """Everything in ``run_dir`` but the results file (journal, lock, temporaries)."""
    return sorted(p.name for p in Path(run_dir).iterdir() if p.name != "results.h5")


def interrupt(args, run_dir, cwd, sig, phase, rng, chunks=(1, 4)):
    """Start ``gyrolab args`` and send ``sig`` at a random point of ``phase``:
    "integration" (after a random number of stored chunks in ``chunks`` and a random
    fraction of a chunk delay) or "assembly" (while the results temporary is written).
    Returns (returncode, stderr)."""
    run_dir = Path(run_dir)
    delay = {"integration": {"GYROLAB_TEST_CHUNK_DELAY": 0.2}, "assembly": {"GYROLAB_TEST_ASSEMBLY_DELAY": 0.05}}[phase]
    proc = start(*args, f"hydra.run.dir={run_dir}", cwd=cwd, **delay)
    partial = run_dir / "results.h5.partial"
    if phase == "integration":
        want = rng.randint(*chunks)
        ready = lambda: len(list(partial.glob("chunk-*.npz"))) >= want  # noqa: E731
    else:
        ready = lambda: any(run_dir.glob(".results.h5.tmp*"))  # noqa: E731
    deadline = time.monotonic() + 120
    while not ready():
        if proc.poll() is not None:
            raise AssertionError(f"finished before the {phase} point: {proc.communicate()}")
        if time.monotonic() > deadline:
            proc.kill()
            raise AssertionError("timed out")
        time.sleep(0.01)
    time.sleep(rng.uniform(0, 0.15))
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=60)
    return proc.returncode, err


# --------------------------------------------------------------------------- a full disk


@contextlib.contextmanager
def small_disk(root, megabytes=8):
    """A tmpfs of ``megabytes`` at ``root/disk`` if we may mount one, else yields None."""
    mount = Path(root) / "disk"
    mount.mkdir()
    ok = (
        os.geteuid() == 0
        and shutil.which("mount")
        and subprocess.run(
            ["mount", "-t", "tmpfs", "-o", f"size={megabytes}m", "tmpfs", str(mount)], capture_output=True, timeout=10
        ).returncode
        == 0
    )
    try:
        yield mount if ok else None
    finally:
        if ok:
            subprocess.run(["umount", "-l", str(mount)], capture_output=True, timeout=10)


def fill(directory):
    """Fill the file system of ``directory`` with a ballast file; returns its path (remove it to free)."""
    ballast = Path(directory) / "ballast"
    fd = os.open(ballast, os.O_WRONLY | os.O_CREAT, 0o644)
    block = b"\0" * (1 << 16)
    try:
        while True:
            os.write(fd, block)
    except OSError as err:
        if err.errno != errno.ENOSPC:
            raise
    finally:
        os.close(fd)
    return ballast


# --------------------------------------------------------------------------- the bad-file matrix


def call(main, argv):
    """Run a console entry point in-process: (status, stderr, exception or None)."""
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        try:
            status, raised = main(argv), None
        except SystemExit as exit_:
            status, raised = exit_.code, None
        except Exception as exc:  # a traceback the user would see
            status, raised = None, exc
    return status, err.getvalue(), raised


def analysis_commands(good):
    """{name: (main, argv(FILE))} of every analysis command given one results file; ``good``: the
    valid file gyrolab-compare's other operand is."""
    from gyrolab.analysis.figures.cli import main as plot_main
    from gyrolab.analysis.figures.registry import FIGURES
    from gyrolab.analysis.files.compare import main as compare_main
    from gyrolab.analysis.verdicts.verdict import main as verdict_main

    commands = {f"plot {kind}": (plot_main, lambda f, kind=kind: [kind, f]) for kind in FIGURES}
    commands["plot seed"] = (plot_main, lambda f: ["seed", f])
    commands["plot standard"] = (plot_main, lambda f: ["standard", f])
    commands["compare A"] = (compare_main, lambda f: [f, str(good)])
    commands["compare B"] = (compare_main, lambda f: [str(good), f])
    commands["verdict"] = (verdict_main, lambda f: [f])
    return commands


def command_names():
    """The names of ``analysis_commands``, without a file to give them."""
    from gyrolab.analysis.figures.registry import FIGURES

    return [*(f"plot {kind}" for kind in FIGURES), "plot seed", "plot standard", "compare A", "compare B", "verdict"]


SEED_PNGS = {"seed_regimes.png", "seed_remark1.png", "seed_next_vs_prev.png"}
OUTCOMES = ("traceback", "silent", "refused", "answered", "other")


def made(fault, good, cache):
    """The file ``fault`` (BAD_FILES or VALID_FILES) made from ``good`` once in the directory ``cache``."""
    path = Path(cache) / f"{fault}.h5"
    if not os.path.lexists(path):
        (VALID_FILES.get(fault) or BAD_FILES[fault])(path, good)
    return path


def matrix_case(directory, good, fault, command, cache=None):
    """Run ``command`` (``command_names``) on the file ``fault`` (BAD_FILES or VALID_FILES) made in the empty
    ``directory``: (outcome, detail).  Outcomes: "traceback" (an exception reached the user), "silent"
    (a bad file answered: exit 0, or compare's 1), "refused" (one line, exit 2, nothing written),
    "answered" (a valid file answered correctly), "other" (anything else: several lines, files
    written before a refusal, a wrong answer to a valid file)."""
    directory = Path(directory)
    path = directory / "bad.h5"
    source = made(fault, good, cache or directory.parent)
    if source.is_dir():
        path.mkdir()
    else:
        shutil.copyfile(source, path)
    before = {p.name for p in directory.rglob("*")}
    main, argv = analysis_commands(good)[command]
    status, err, raised = call(main, argv(str(path)))
    written = {p.name for p in directory.rglob("*")} - before
    lines = err.strip().splitlines()
    if raised is not None or "Traceback" in err:
        return "traceback", f"{type(raised).__name__}: {raised}" if raised else err[-300:]
    if status == 2:
        ok = len(lines) == 1 and not written
        return ("refused" if ok else "other"), f"{len(lines)} lines, wrote {sorted(written)}: {err.strip()[:200]}"
    answered = status in (0, 1) if command.startswith("compare") else status == 0
    if not answered:
        return "other", f"exit {status}: {err.strip()[:200]}"
    if fault not in VALID_FILES:
        return "silent", f"exit {status}, wrote {sorted(written)}"
    right = {
        "plot seed": SEED_PNGS <= written,
        "compare A": status == VALID_COMPARE[fault],
        "compare B": status == VALID_COMPARE[fault],
        "verdict": True,
    }.get(command, bool(written))  # a figure: written
    return ("answered" if right else "other"), f"exit {status}, wrote {sorted(written)}"


def report(root, faults=None, commands=None, made_dir=None, out=sys.stdout):
    """Run the matrix (``faults`` x ``commands``, default all) under the directory ``root``, the files
    made once in ``made_dir`` (default under ``root``; kept there for another run); print each case
    that is neither refused nor answered, then the counts per outcome.  Returns {outcome: count}."""
    from helpers import make_file

    root = Path(root)
    made_dir = Path(made_dir or root / "made")
    made_dir.mkdir(exist_ok=True)
    good = made_dir / "good.h5"
    if not good.exists():
        make_file(good, "sweep.f=[10]")
    counts = dict.fromkeys(OUTCOMES, 0)
    for fault in faults or [*BAD_FILES, *VALID_FILES]:
        for command in commands or command_names():
            case = root / f"{fault}--{command.replace(' ', '_')}"
            case.mkdir()
            outcome, detail = matrix_case(case, good, fault, command, made_dir)
            counts[outcome] += 1
            if outcome not in ("refused", "answered"):
                print(f"{outcome:9} {fault:24} {command:20} {detail}", file=out, flush=True)
    cases = sum(counts.values())
    print(f"cases {cases}: " + ", ".join(f"{k} {v}" for k, v in counts.items()), file=out, flush=True)
    return counts


if __name__ == "__main__":  # python tests/faults.py [FAULT ...]: the bad-file matrix's counts
    import argparse
    import tempfile

    import matplotlib

    matplotlib.use("Agg")
    parser = argparse.ArgumentParser(description="the bad-file x analysis-command matrix: counts per outcome")
    parser.add_argument("faults", nargs="*", help="faults to run (default: all of BAD_FILES and VALID_FILES)")
    parser.add_argument("--command", action="append", help="commands to run (default: all)")
    parser.add_argument("--made", help="directory to keep the made files in, for another run (default: a temporary)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        report(tmp, args.faults or None, args.command, args.made)
