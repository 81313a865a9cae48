"""An adversary sharing the machine (issue 27): links and special files planted where gyrolab writes
are refused in one line and never followed (the victim keeps its bytes); labels read from a file
cannot choose where a figure goes."""

import os
import subprocess
import sys

import h5py
import numpy as np
import pytest

from gyrolab.analysis.figures import cli
from gyrolab.analysis.files.combine import main as combine_main
from gyrolab.runner.store import Journal
from gyrolab.safe_files import OutputLock, UnsafePathError, atomic_replace, atomic_write, inside, safe_name

from helpers import gyrolab, make_file

SECRET = b"the victim's own bytes\n"
ONE_RUN = [
    "sweep.method=[seed_next]",
    "sweep.f=[10]",
    "sweep.theta0=[30]",
    "sweep.dt=[1e-3]",
    "sweep.t_end=0.01",
    "output.every=1e-3",
    "output.figures=false",
]


@pytest.fixture
def victim(tmp_path):
    path = tmp_path / "victim"
    path.write_bytes(SECRET)
    return path


def one_line(text):
    lines = text.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in text, text
    return lines[0]


# --------------------------------------------------------------------------- the write layer


def test_atomic_replace_refuses_a_link_at_the_destination(tmp_path, victim):
    out = tmp_path / "results.h5"
    out.symlink_to(victim)
    with pytest.raises(UnsafePathError, match="symbolic link"):
        atomic_replace(out, lambda tmp: tmp.write_bytes(b"data"))
    assert victim.read_bytes() == SECRET and out.is_symlink()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["results.h5", "victim"]  # no temporary left


def test_atomic_replace_refuses_a_fifo_and_a_directory(tmp_path):
    fifo, directory = tmp_path / "fifo.png", tmp_path / "dir.png"
    os.mkfifo(fifo)
    directory.mkdir()
    for path, kind in ((fifo, "a FIFO"), (directory, "a directory")):
        with pytest.raises(UnsafePathError, match=kind):
            atomic_write(path, lambda fh: fh.write(b"x"))


def test_a_link_at_the_old_temporary_names_is_never_followed(tmp_path, victim):
    """Before issue 27 the temporaries were ``.<name>.tmp<pid>``, the pid readable in the lock: a link
    planted there was written through.  Now they live in a fresh private directory."""
    out = tmp_path / "results.h5"
    planted = tmp_path / f".results.h5.tmp{os.getpid()}"
    planted.symlink_to(victim)
    atomic_replace(out, lambda tmp: tmp.write_bytes(b"data"))
    assert victim.read_bytes() == SECRET
    assert out.read_bytes() == b"data" and not out.is_symlink()


def test_journal_chunk_and_manifest_temporaries_do_not_follow_links(tmp_path, victim):
    out = tmp_path / "results.h5"
    journal = Journal(out)
    journal.create({"config_hash": "x", "n_runs": 1, "shape": [1, 1, 1, 1], "n_samples": 2})
    for name in (".chunk-00000.npz.tmp", ".manifest.json.tmp"):
        (journal.dir / f"{name}{os.getpid()}").symlink_to(victim)
    journal.write_chunk(
        0,
        np.array([0]),
        np.zeros((1, 2, 8)),
        status=np.zeros(1, np.int8),
        n_steps=np.ones(1, np.int64),
        wall_time=np.ones(1),
        solver_iterations=np.zeros(1, np.int64),
        solver_iterations_max=np.zeros(1, np.int64),
    )
    assert victim.read_bytes() == SECRET
    chunk = journal.dir / "chunk-00000.npz"
    assert chunk.is_file() and not chunk.is_symlink() and "chunk-00000.npz" in journal.manifest()["chunks"]


@pytest.mark.parametrize("kind", ["link", "directory", "fifo", "dangling link"])
def test_the_lock_is_never_opened_through_a_link_or_special_file(tmp_path, victim, kind):
    out = tmp_path / "results.h5"
    lock = tmp_path / "results.h5.lock"
    {
        "link": lambda: lock.symlink_to(victim),
        "directory": lock.mkdir,
        "fifo": lambda: os.mkfifo(lock),
        "dangling link": lambda: lock.symlink_to(tmp_path / "absent"),
    }[kind]()
    for call in (OutputLock(out).check_free, OutputLock(out).acquire):
        with pytest.raises(UnsafePathError, match="results.h5.lock"):
            call()
    assert victim.read_bytes() == SECRET and not (tmp_path / "absent").exists()


def test_the_lock_holds_its_owner_and_a_stale_one_is_taken_over(tmp_path):
    out = tmp_path / "results.h5"
    (tmp_path / "results.h5.lock").write_text("12345 otherhost 2020-01-01T00:00:00Z\n")  # its writer died
    with OutputLock(out) as lock:
        pid, host, started = lock.path.read_text().split()
        assert int(pid) == os.getpid() and host == os.uname().nodename and started.endswith("Z")
    assert not lock.path.exists()


# --------------------------------------------------------------------------- the commands


@pytest.mark.slow
@pytest.mark.parametrize("planted", ["results.h5.lock", "results.h5"])
def test_gyrolab_refuses_a_link_where_it_would_write(tmp_path, victim, planted):
    run = tmp_path / "run"
    run.mkdir()
    (run / planted).symlink_to(victim)
    result = gyrolab(*ONE_RUN, "output.overwrite=true", f"hydra.run.dir={run}", cwd=tmp_path)
    assert result.returncode == 2, result.stderr
    assert one_line(result.stderr).startswith(f"gyrolab: error: {run / planted}: is a symbolic link")
    assert victim.read_bytes() == SECRET
    assert sorted(p.name for p in run.iterdir()) == [planted]


@pytest.fixture(scope="module")
def two_scenes(tmp_path_factory):
    root = tmp_path_factory.mktemp("two_scenes")
    (root / "a").mkdir()
    (root / "b").mkdir()
    a = make_file(root / "a" / "results.h5", "sweep.f=[10]")
    b = make_file(root / "b" / "results.h5", "sweep.f=[5]", "scene=free_symmetric")
    return a, b


def test_combine_refuses_a_link_as_its_output(tmp_path, victim, two_scenes, capsys):
    out = tmp_path / "combined.h5"
    out.symlink_to(victim)
    assert combine_main([*map(str, two_scenes), "-o", str(out), "--overwrite"]) == 2
    assert one_line(capsys.readouterr().err).startswith(f"gyrolab-combine: error: {out}: is a symbolic link")
    assert victim.read_bytes() == SECRET


def test_plot_refuses_a_link_as_its_figure(tmp_path, victim, two_scenes, capsys):
    out = tmp_path / "energy.png"
    out.symlink_to(victim)
    with pytest.raises(SystemExit) as done:
        cli.main(["energy", str(two_scenes[0]), "-o", str(out)])
    assert done.value.code == 2
    assert "is a symbolic link" in one_line(capsys.readouterr().err)
    assert victim.read_bytes() == SECRET


def test_docs_tables_refuse_a_link_before_any_work(tmp_path, victim, two_scenes, capsys):
    from gyrolab.analysis.reports import peer_table

    out = tmp_path / "peer_problems.md"
    out.symlink_to(victim)
    assert peer_table.main([str(two_scenes[0]), "-o", str(out)]) == 2
    assert "is a symbolic link" in one_line(capsys.readouterr().err)
    assert victim.read_bytes() == SECRET


def test_peer_table_needs_an_output():
    """Without -o it overwrote ./docs/peer_problems.md of whatever directory it ran in."""
    from gyrolab.analysis.reports import peer_table

    with pytest.raises(SystemExit) as done:
        peer_table.main(["x.h5"])
    assert done.value.code == 2


# --------------------------------------------------------------------------- labels from files


def test_safe_name_keeps_ordinary_labels_and_defuses_paths():
    assert safe_name("heavy_top", 0) == "heavy_top" and safe_name("job1", 0) == "job1"
    assert safe_name("../..", 3) == "3" and safe_name("/", "m0") == "m0" and safe_name("", 1) == "1"
    assert "/" not in safe_name("/etc/cron.d/evil", 0) and not safe_name("../../x", 0).startswith(".")
    with pytest.raises(UnsafePathError):
        inside("/tmp/a", "/tmp/a/../b")


@pytest.fixture(scope="module")
def evil(two_scenes, tmp_path_factory):
    """A combined file whose scene labels are an absolute path and ``../..`` (the adversary's file)."""
    root = tmp_path_factory.mktemp("evil") / "deep" / "er"
    root.mkdir(parents=True)
    path = root / "evil.h5"
    assert combine_main([*map(str, two_scenes), "-o", str(path)]) == 0
    with h5py.File(path, "r+") as fh:
        labels = fh["scene"]
        assert labels.shape == (2,)
        labels[...] = np.array([str(root.parent.parent / "abs_evil"), "../.."], dtype=object)
    return path


def files_under(root):
    return sorted(str(p.relative_to(root)) for p in root.rglob("*") if p.is_file())


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["standard", "energy"])
def test_plot_labels_cannot_write_outside(evil, kind):
    top = evil.parent.parent.parent
    before = files_under(top)
    result = subprocess.run(
        [sys.executable, "-m", "gyrolab.analysis.figures.cli", kind, str(evil)], capture_output=True, text=True, cwd=top
    )
    assert "Traceback" not in result.stderr, result.stderr
    new = sorted(set(files_under(top)) - set(before))
    assert new and all(p.startswith("deep/er/") for p in new), new
    assert not (top / "abs_evil").exists()


def test_verdict_figures_cannot_write_outside(tmp_path, monkeypatch):
    import matplotlib.pyplot as plt

    from gyrolab.analysis.verdicts import figures as verdict_figures

    monkeypatch.setattr(verdict_figures, "scene_figure", lambda *a: plt.figure(figsize=(1, 1)))
    out = tmp_path / "figs"
    out.mkdir()
    records = [{"kind": "summary", "scene": "../../.."}, {"kind": "summary", "scene": "heavy_top"}]
    paths = verdict_figures.draw_figures(records, [], out)
    assert [p.name for p in paths] == ["verdict_0.png", "verdict_heavy_top.png"]
    assert sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*.png")) == [p.relative_to(tmp_path) for p in paths]


# --------------------------------------------------------------------------- faults at the HDF5 layer


def test_a_crash_while_writing_the_results_is_one_oserror(tmp_path, capfd):
    """libhdf5 segfaulted on a full disk; in_child keeps the crash and its noise in a child."""
    import signal

    from gyrolab.runner.store import in_child

    def crash():
        os.write(2, b"HDF5-DIAG: Error detected in HDF5 (1.14.2)\n" * 400)
        os.kill(os.getpid(), signal.SIGSEGV)

    with pytest.raises(OSError) as err:
        in_child(crash, tmp_path / "results.h5")
    assert "killed by SIGSEGV" in str(err.value) and err.value.filename == str(tmp_path / "results.h5")
    assert capfd.readouterr().err == ""


def test_a_full_disk_in_the_child_is_enospc(tmp_path):
    import errno

    from gyrolab.runner.store import in_child

    def full():
        raise OSError(errno.ENOSPC, "Can't write data (file write failed: errno = 28, No space left on device)")

    with pytest.raises(OSError) as err:
        in_child(full, tmp_path / "results.h5")
    assert err.value.errno == errno.ENOSPC and "No space left" in str(err.value)


def test_the_child_writes_what_the_parent_asked(tmp_path):
    from gyrolab.runner.store import in_child

    in_child(lambda: (tmp_path / "x").write_bytes(b"done"), tmp_path / "x")
    assert (tmp_path / "x").read_bytes() == b"done"


# --------------------------------------------------------------------------- the journal's proof


@pytest.fixture(scope="module")
def tiny_grid():
    from hydra import compose, initialize_config_module

    from gyrolab.runner.config import register_configs
    from gyrolab.runner.grid import build_grid

    register_configs()
    with initialize_config_module(config_module="gyrolab.conf", version_base=None):
        cfg = compose("config", overrides=[*ONE_RUN[:2], "sweep.theta0=[30,45]", *ONE_RUN[3:]])
    return build_grid(cfg)


def journal_with_chunks(root, grid, config_hash="h"):
    from gyrolab.runner.execute import run_chunk

    journal = Journal(root / "results.h5")
    journal.create({"config_hash": config_hash, "n_runs": grid.n_runs})
    journal.write_chunk(0, **run_chunk(grid, np.array([0]), 1))
    return journal


def reseal_unlisted(journal, name):
    """The adversary's trick: drop the chunk's manifest entry (it is then judged by content alone)."""
    import json

    manifest = json.loads(journal.manifest_path.read_text())
    manifest["chunks"].pop(name, None)
    journal.manifest_path.write_text(json.dumps(manifest))


def test_a_chunk_of_another_sweep_is_refused_even_unlisted(tmp_path, tiny_grid):
    """A chunk-*.npz copied from a ``scene.M=2`` run's journal (same grid shape) into ours."""
    ours = journal_with_chunks(tmp_path / "ours", tiny_grid)
    other = journal_with_chunks(tmp_path / "other", tiny_grid, config_hash="scene.M=2's hash")
    foreign = ours.dir / "chunk-00001.npz"
    (other.dir / "chunk-00000.npz").rename(foreign)
    reseal_unlisted(ours, foreign.name)
    rejected = Journal(tmp_path / "ours" / "results.h5").verify(tiny_grid.n_runs, tiny_grid.n_samples)
    assert [name for name, _ in rejected] == ["chunk-00001.npz"]
    assert "another sweep" in rejected[0][1]


def test_invented_zeros_with_status_0_are_refused(tmp_path, tiny_grid):
    journal = journal_with_chunks(tmp_path, tiny_grid)
    path = journal.dir / "chunk-00001.npz"
    n = 1
    with open(path, "wb") as fh:
        np.savez(
            fh,
            runs=np.array([1]),
            samples=np.zeros((n, tiny_grid.n_samples, 8)),
            status=np.zeros(n, np.int8),
            n_steps=np.ones(n, np.int64),
            wall_time=np.ones(n),
            solver_iterations=np.zeros(n, np.int64),
            solver_iterations_max=np.zeros(n, np.int64),
            binding=np.array(journal.binding()),  # even with the right binding, read from the manifest
            mac=np.array("0" * 64),
        )
    rejected = Journal(tmp_path / "results.h5").verify(tiny_grid.n_runs, tiny_grid.n_samples)
    assert [(name, "HMAC" in why) for name, why in rejected] == [("chunk-00001.npz", True)]
    assert sorted(Journal(tmp_path / "results.h5").done_runs()[0]) == [0]


def test_a_chunk_copied_under_another_name_is_refused(tmp_path, tiny_grid):
    import shutil

    journal = journal_with_chunks(tmp_path, tiny_grid)
    shutil.copy(journal.dir / "chunk-00000.npz", journal.dir / "chunk-00007.npz")
    rejected = Journal(tmp_path / "results.h5").verify(tiny_grid.n_runs, tiny_grid.n_samples)
    assert [name for name, _ in rejected] == ["chunk-00007.npz"]


def test_odd_journal_entries_are_set_aside_unread(tmp_path, tiny_grid, victim):
    journal = journal_with_chunks(tmp_path, tiny_grid)
    (journal.dir / "chunk-abc.npz").write_bytes(b"x")
    (journal.dir / "chunk-00001.npz.npz").write_bytes(b"x")
    (journal.dir / "chunk--1.npz").write_bytes(b"x")
    (journal.dir / "chunk-00002.npz").symlink_to(victim)
    (journal.dir / "chunk-00003.npz").mkdir()
    os.mkfifo(journal.dir / "chunk-00004.npz")  # opened for reading, it would hang
    (journal.dir / "rejected").write_bytes(b"a file where the rejected chunks go")
    rejected = Journal(tmp_path / "results.h5").verify(tiny_grid.n_runs, tiny_grid.n_samples)
    names = sorted(name for name, _ in rejected)
    assert names == sorted(
        ["rejected", "chunk-abc.npz", "chunk-00001.npz.npz", "chunk--1.npz", *(f"chunk-0000{k}.npz" for k in (2, 3, 4))]
    )
    assert victim.read_bytes() == SECRET
    assert sorted(Journal(tmp_path / "results.h5").done_runs()[0]) == [0]
    assert Journal(tmp_path / "results.h5").verify(tiny_grid.n_runs, tiny_grid.n_samples) == []


def test_resume_after_a_kernel_edit_is_refused(tmp_path):
    from gyrolab.runner.config import ConfigError
    from gyrolab.runner.preflight import output_state

    out = tmp_path / "results.h5"
    Journal(out).create({"config_hash": "h", "kernel_source_hash": "0123456789abcdef-old-code"})
    with pytest.raises(ConfigError, match=r"other kernel code \(kernel_source_hash 0123456789ab.*overwrite"):
        output_state(out, "h", False, True)
    Journal(out).create({"config_hash": "h"})  # this code's hash
    assert output_state(out, "h", False, True) == "resume"


# --------------------------------------------------------------------------- bounded readers


@pytest.fixture(scope="module")
def sparse_bomb(two_scenes, tmp_path_factory):
    """A results file (a real one's attrs and coordinates) whose energy declares 2.4 GB in chunks
    never written: ~40 kB on disk."""
    path = tmp_path_factory.mktemp("bomb") / "bomb.h5"
    with h5py.File(path, "w") as fh, h5py.File(two_scenes[0], "r") as good:
        for key, value in good.attrs.items():
            fh.attrs[key] = value
        fh.create_dataset("energy", shape=(300, 1000, 1000), dtype="f8", chunks=(1, 100, 1000))
    assert path.stat().st_size < 100_000
    return path


def test_a_small_file_declaring_gigabytes_is_refused_without_loading(sparse_bomb, tmp_path, capsys):
    from gyrolab.analysis.files.compare import main as compare_main

    with pytest.raises(SystemExit) as done:
        cli.main(["energy", str(sparse_bomb), "-o", str(tmp_path / "e.png")])
    assert done.value.code == 2
    assert compare_main([str(sparse_bomb), str(sparse_bomb)]) == 2
    assert combine_main([str(sparse_bomb), "-o", str(tmp_path / "c.h5")]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 3 and all("declare 2.4 GB" in line for line in lines), lines
    assert not list(tmp_path.iterdir())


def test_the_memory_budget_refuses_a_file_too_big_to_load(two_scenes, monkeypatch):
    from gyrolab.limits import LimitError, check_file_sizes, declared_bytes

    check_file_sizes(two_scenes[0])  # an ordinary file passes
    with pytest.raises(LimitError, match="more than the"):
        check_file_sizes(two_scenes[0], budget=declared_bytes(two_scenes[0]) - 1)


def test_yaml_attrs_are_parsed_with_limits():
    import yaml

    from gyrolab.limits import LimitError, safe_yaml

    laughs = "a: &a [x, x, x, x, x, x, x, x, x]\n" + "".join(
        f"{c}: &{c} [{', '.join([f'*{p}'] * 9)}]\n" for p, c in zip("abcdefgh", "bcdefghi")
    )
    with pytest.raises(LimitError, match="nodes"):
        safe_yaml(laughs)
    with pytest.raises(LimitError, match="itself|deeper"):
        safe_yaml("&a [*a]")
    with pytest.raises(LimitError, match="characters"):
        safe_yaml("x: " + "y" * (2 << 20))
    config = "sweep:\n  f: [10, 50]\n  dt: [0.001]\nscene:\n  name: heavy_top\n"
    assert safe_yaml(config) == yaml.safe_load(config)


def test_a_billion_run_grid_is_refused_in_well_under_a_second():
    import time

    from hydra import compose, initialize_config_module

    from gyrolab.runner.config import ConfigError, register_configs
    from gyrolab.runner.grid import build_grid

    register_configs()
    axes = [
        "sweep.f=${linspace:1,100,1000}",
        "sweep.theta0=${linspace:1,89,1000}",
        "sweep.dt=${logspace:1e-4,1e-3,1000}",
    ]
    with initialize_config_module(config_module="gyrolab.conf", version_base=None):
        cfg = compose("config", overrides=["sweep.method=[seed_next]", *axes, "runner.dry_run=true"])
    started = time.process_time()
    with pytest.raises(ConfigError, match=r"= 1e\+09 runs, more than the 1e\+07") as err:
        build_grid(cfg)
    assert time.process_time() - started < 1.0 and "\n" not in str(err.value)


# --------------------------------------------------------------------------- the embedded Dask cluster

INTRUDER = """
import sys
from distributed import Client

address = sys.argv[1]
for attempt in (address, address.replace("tls://", "tcp://")):
    try:
        client = Client(attempt, timeout=5)
    except Exception as err:
        print("refused", type(err).__name__)
        continue
    print("ran", client.submit(lambda: 42).result(timeout=10))
"""


@pytest.mark.slow
def test_another_local_process_cannot_submit_work_to_the_embedded_cluster(tmp_path):
    pytest.importorskip("distributed")
    from gyrolab.runner.dask_backend import DaskCluster

    with DaskCluster.start_local(1) as cluster:
        scheduler = cluster.local.scheduler
        assert scheduler.address.startswith("tls://127.0.0.1:")
        listening = [s.getsockname()[0] for s in scheduler.http_server._sockets.values()]
        assert listening and set(listening) == {"127.0.0.1"}, listening  # the dashboard too
        assert all(w.startswith("tls://127.0.0.1:") for w in cluster.workers)
        intruder = subprocess.run(
            [sys.executable, "-c", INTRUDER, scheduler.address], capture_output=True, text=True, timeout=120
        )
        assert "ran" not in intruder.stdout and intruder.stdout.count("refused") == 2, intruder
        assert cluster.client.submit(lambda: 42).result(timeout=30) == 42  # gyrolab itself can


def test_a_dry_run_starts_no_cluster_and_plans_at_most_the_cores():
    from gyrolab.runner.dask_backend import DaskCluster

    cores = len(os.sched_getaffinity(0))
    planned = DaskCluster.planned_local(40)
    assert planned.client is None and len(planned.workers) == min(40, cores)
    planned.close()


# --------------------------------------------------------------------------- config, combine and compare gaps

GAPS = [
    (["output.variables=[]"], "output.variables=[]: names no variable"),
    (["sweep.t_end=0.1005"], "sweep.t_end=0.1005: not a multiple of output.every=0.001"),
    (["scene=heavy_body", "scene.omega1=1e200"], "scene: the initial state at f=10.0, theta0=30.0 overflows float64"),
    (["sweep.theta0=${sweep.t_end}"], "sweep.theta0=0.01: a sweep axis is a list"),
    (["runner.connect_timeout=1e308"], "runner.connect_timeout=1e+308: must be > 0 s and at most"),
]


@pytest.mark.parametrize("overrides, message", GAPS)
def test_config_gaps_are_one_line(overrides, message):
    from hydra import compose, initialize_config_module

    from gyrolab.runner.config import ConfigError, register_configs
    from gyrolab.runner.grid import build_grid

    register_configs()
    with initialize_config_module(config_module="gyrolab.conf", version_base=None):
        cfg = compose("config", overrides=[*ONE_RUN, *overrides])
    with pytest.raises(ConfigError) as err:
        build_grid(cfg)
    assert str(err.value).startswith(message) and "\n" not in str(err.value), err.value


def test_a_scheduler_file_that_is_a_device_is_refused_unread():
    from gyrolab.runner.config import ConfigError
    from gyrolab.runner.dask_backend import read_scheduler_file

    with pytest.raises(ConfigError, match=r"runner.scheduler_file=/dev/zero: is a device"):
        read_scheduler_file("/dev/zero")


def altered(source, root, change):
    import shutil

    path = root / f"{change.__name__}.h5"
    shutil.copy(source, path)
    with h5py.File(path, "r+") as fh:
        change(fh)
    return path


def energy_as_float32(fh):
    values = fh["energy"][...]
    attrs = dict(fh["energy"].attrs)
    dims = fh["energy"].attrs.get("DIMENSION_LIST")
    del fh["energy"]
    fh.create_dataset("energy", data=values.astype(np.float32))
    for key, value in attrs.items():
        if key != "DIMENSION_LIST":
            fh["energy"].attrs[key] = value
    assert dims is not None


def nan_f(fh):
    fh["f"][0] = np.nan


@pytest.mark.parametrize(
    "change, message",
    [
        (nan_f, "coordinate f has a non-finite value"),
        (energy_as_float32, "variable energy has dtype float32, expected float64"),
    ],
)
def test_combine_refuses_a_nan_coordinate_and_a_foreign_dtype(two_scenes, tmp_path, capsys, change, message):
    bad = altered(two_scenes[0], tmp_path, change)
    assert combine_main([str(two_scenes[1]), str(bad), "-o", str(tmp_path / "c.h5")]) == 2
    line = one_line(capsys.readouterr().err)
    assert message in line, line
    assert not (tmp_path / "c.h5").exists()


def test_compare_refuses_a_newer_layout(two_scenes, tmp_path, capsys):
    from gyrolab.analysis.files.compare import main as compare_main

    newer = altered(two_scenes[0], tmp_path, lambda fh: fh.attrs.modify("layout_version", 99))
    assert compare_main([str(newer), str(two_scenes[0])]) == 2
    assert "layout_version=99 is newer" in one_line(capsys.readouterr().err)


def test_combine_on_sigterm_leaves_no_temporary_nor_lock(two_scenes, tmp_path, monkeypatch, capsys):
    import signal

    from gyrolab.analysis.files import combine

    out = tmp_path / "c.h5"
    real = combine.xr.Dataset.to_netcdf

    def killed_while_writing(ds, path, *args, **kwargs):
        real(ds, path, *args, **kwargs)
        os.kill(os.getpid(), signal.SIGTERM)

    monkeypatch.setattr(combine.xr.Dataset, "to_netcdf", killed_while_writing)
    assert combine_main([*map(str, two_scenes), "-o", str(out)]) == 128 + signal.SIGTERM
    assert one_line(capsys.readouterr().err) == f"gyrolab-combine: interrupted (SIGTERM); {out} is untouched"
    assert list(tmp_path.iterdir()) == []
    assert signal.getsignal(signal.SIGTERM) is not combine._interrupted


# --------------------------------------------------------------------------- signals and half-made journals


def one_run_cfg(*extra):
    from hydra import compose, initialize_config_module

    from gyrolab.runner.config import register_configs

    register_configs()
    with initialize_config_module(config_module="gyrolab.conf", version_base=None):
        return compose("config", overrides=[*ONE_RUN, *extra])


def test_a_failed_first_manifest_write_leaves_no_journal(tmp_path, monkeypatch, capsys):
    import errno

    from gyrolab.runner import store
    from gyrolab.runner import sweep as app

    real = store.atomic_write

    def failing(path, write, **kwargs):
        if path.name == "manifest.json":
            raise OSError(errno.EIO, "Input/output error", str(path))
        return real(path, write, **kwargs)

    monkeypatch.setattr(store, "atomic_write", failing)
    with pytest.raises(SystemExit) as done:
        app.run_sweep(one_run_cfg(), str(tmp_path))
    assert done.value.code == app.EXIT_FAILED
    assert "I/O error writing" in one_line(capsys.readouterr().err)
    assert list(tmp_path.iterdir()) == []  # no .partial to block the rerun or a resume


def test_an_interrupt_just_after_the_rename_reports_a_complete_file(tmp_path, monkeypatch, capsys):
    import signal

    from gyrolab import safe_files
    from gyrolab.runner import signals
    from gyrolab.runner import sweep as app

    real = safe_files.fsync_dir

    def interrupted(directory):
        real(directory)
        if (tmp_path / "results.h5").exists():
            raise signals.Interrupted(signal.SIGTERM)

    monkeypatch.setattr(safe_files, "fsync_dir", interrupted)
    with pytest.raises(SystemExit) as done:
        app.run_sweep(one_run_cfg(), str(tmp_path))
    assert done.value.code == 128 + signal.SIGTERM
    err = capsys.readouterr().err
    assert "after the results were complete" in one_line(err) and "Finish with" not in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["results.h5"]


def test_an_interrupt_in_the_figure_step_says_the_results_are_complete(tmp_path, monkeypatch, capsys):
    from gyrolab.runner import sweep as app

    def interrupted(out, names):
        raise KeyboardInterrupt

    monkeypatch.setattr(app, "make_figures", interrupted)
    with pytest.raises(SystemExit) as done:
        app.run_sweep(one_run_cfg("output.figures=true"), str(tmp_path))
    assert done.value.code == 130
    line = one_line(capsys.readouterr().err)
    assert "after the results were complete" in line and "nothing was saved" not in line
    assert (tmp_path / "results.h5").is_file()


def test_compare_pairs_near_duplicate_coordinates_with_themselves():
    from gyrolab.analysis.files.compare import _match

    dts = [1e-3, 1.0000000001e-3]
    assert _match(dts, dts) == [0, 1] and _match(dts, dts[::-1]) == [1, 0]
    assert _match([1e-3 * (1 + 1e-12)], dts) == [0]  # still within tolerance of the nearest


def test_two_labels_that_sanitise_alike_do_not_share_a_file():
    from gyrolab.analysis.figures.cli import _member_tag

    class Member:
        def __init__(self, label):
            self.attrs = {"combined_member": f"scene={label}"}

    used = set()
    tags = [_member_tag(Member(label), k, used) for k, label in enumerate(["x", "../x", "/x"])]
    assert tags == ["x", "x_1", "x_2"]


def test_a_killed_writers_private_directory_is_removed_and_a_link_there_not_followed(tmp_path, victim):
    from gyrolab.safe_files import remove_stale_temporaries

    out = tmp_path / "results.h5"
    stale = tmp_path / ".results.h5.tmp123.abcd"
    stale.mkdir()
    (stale / "results.h5").write_bytes(b"half")
    linked = tmp_path / ".results.h5.tmp124.efgh"
    linked.symlink_to(victim.parent / "elsewhere", target_is_directory=True)
    (victim.parent / "elsewhere").mkdir()
    (victim.parent / "elsewhere" / "keep").write_bytes(SECRET)
    removed = remove_stale_temporaries(out)
    assert removed == [stale] and not stale.exists()
    assert (victim.parent / "elsewhere" / "keep").read_bytes() == SECRET  # a link is no private directory
