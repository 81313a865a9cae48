"""Lock, journal and results file: one writer, durable chunks, the results layout (gyrolab/results/layout.py)."""

import json

import numpy as np
import pytest
import xarray as xr
from hydra import compose, initialize_config_module

from gyrolab.kernels.body import FIELDS as BODY_FIELDS
from gyrolab.results.layout import COORD_ATTRS, VARIABLE_ATTRS
from gyrolab.runner.config import register_configs
from gyrolab.runner.execute import run_chunk
from gyrolab.runner.grid import build_grid
from gyrolab.runner.store import Journal, write_results
from gyrolab.safe_files import OutputBusyError, OutputLock

register_configs()


@pytest.fixture(scope="module")
def grid():
    overrides = [
        "sweep.method=[seed_next,seed_prev]",
        "sweep.f=[10,50]",
        "sweep.theta0=[45]",
        "sweep.dt=[1e-3,1e-4]",
        "sweep.t_end=0.05",
        "output.every=1e-3",
    ]
    with initialize_config_module(config_module="gyrolab.conf", version_base=None):
        return build_grid(compose("config", overrides=overrides))


def test_second_lock_is_refused_naming_the_holder(tmp_path):
    out = tmp_path / "results.h5"
    with OutputLock(out):
        with pytest.raises(OutputBusyError, match=r"another gyrolab \(pid \d+\) is writing"):
            OutputLock(out).acquire()
        with pytest.raises(OutputBusyError, match="another gyrolab"):
            OutputLock(out).check_free()
    assert not (tmp_path / "results.h5.lock").exists()
    with OutputLock(out):  # free again once released
        pass


def test_journal_keeps_finished_chunks_and_drops_half_written_ones(tmp_path, grid):
    journal = Journal(tmp_path / "results.h5")
    journal.create({"config_hash": "abc"})
    first = run_chunk(grid, np.array([0, 2]), threads=1)
    journal.write_chunk(0, **first)
    (journal.dir / ".chunk-00001.npz.tmp123").write_bytes(b"half")
    done, number = journal.done_runs()
    assert sorted(done) == [0, 2] and number == 1
    journal.clean_temporaries()
    assert sorted(p.name for p in journal.dir.iterdir()) == ["chunk-00000.npz", "key", "manifest.json"]
    (stored,) = list(journal.chunks())
    np.testing.assert_array_equal(stored["samples"], first["samples"])
    assert journal.manifest()["config_hash"] == "abc"


def test_results_file_layout_and_attrs(tmp_path, grid):
    chunks = [run_chunk(grid, np.arange(0, 4), 2), run_chunk(grid, np.arange(4, 8), 2)]
    path = tmp_path / "r.h5"
    write_results(path, grid, chunks, {"scene": "heavy_top", "config": "a: 1\n"})
    with xr.open_dataset(path, engine="h5netcdf") as ds:
        assert dict(ds.sizes) == {
            "integrator": 2,
            "f": 2,
            "theta0": 1,
            "dt": 2,
            "time": 51,
            "xyz": 3,
            "quat": 4,
            "body_param": len(BODY_FIELDS),
        }
        assert ds["axis"].dims == ("integrator", "f", "theta0", "dt", "time", "xyz")
        assert ds["status"].dtype == np.int8 and ds["n_steps"].dtype == np.int64
        assert list(ds["integrator"].values) == ["seed_next", "seed_prev"]
        np.testing.assert_allclose(ds["time"].values, np.arange(51) * 1e-3)
        for name, attrs in VARIABLE_ATTRS.items():
            assert {k: ds[name].attrs[k] for k in attrs} == attrs
        for name, attrs in COORD_ATTRS.items():
            assert {k: ds[name].attrs[k] for k in attrs} == attrs
        assert "proportion to their steps" in ds["wall_time"].attrs["description"]
        assert ds.attrs["config"] == "a: 1\n"
        # run 5 = seed_prev, f=10, theta0=45, dt=1e-4
        run = ds.isel(integrator=1, f=0, theta0=0, dt=1)
        np.testing.assert_array_equal(run["omega"].values, chunks[1]["samples"][1][:, 3:6])
        assert int(run["n_steps"]) == 500
        for name in ("solver_iterations", "solver_iterations_max"):  # seed_* have no iterative solver: 0
            assert ds[name].dtype == np.int64 and int(run[name]) == chunks[1][name][1] == 0, name
        # each run's inputs are stored: analysis never rebuilds them from today's scene code
        np.testing.assert_array_equal(ds["body"].values, grid.bodies)
        np.testing.assert_array_equal(ds["omega0"].values, grid.omega0)
        np.testing.assert_array_equal(ds["q0"].values, grid.q0)
        assert list(ds["body_param"].values) == list(BODY_FIELDS)


def test_incomplete_journal_is_not_assembled(tmp_path, grid):
    with pytest.raises(RuntimeError, match="4 of 8 runs missing"):
        write_results(tmp_path / "r.h5", grid, [run_chunk(grid, np.arange(4), 2)], {})


def test_a_journal_without_checksums_is_verified_by_content_and_then_sealed(tmp_path, grid):
    journal = Journal(tmp_path / "results.h5")
    journal.create({"config_hash": "abc"})
    journal.write_chunk(0, **run_chunk(grid, np.array([0, 2]), threads=1))
    manifest = {k: v for k, v in journal.manifest().items() if k != "chunks"}  # as written before checksums
    journal.manifest_path.write_text(json.dumps(manifest))
    journal = Journal(tmp_path / "results.h5")
    assert journal.verify(grid.n_runs, grid.n_samples) == []
    assert list(journal.manifest()["chunks"]) == ["chunk-00000.npz"]


def test_chunk_files_load_as_np_savez_writes_them(tmp_path):
    """save_npz (the journal's writer, without np.savez's copies) gives what np.savez gives back:
    same names, dtypes, shapes (0-d kept) and bytes, Fortran-ordered input included."""
    from gyrolab.runner.store import save_npz

    rng = np.random.default_rng(5)
    arrays = {
        "samples": rng.standard_normal((3, 7, 13)),
        "runs": np.array([4, 0, 9]),
        "status": np.array([0, 1, 2], dtype=np.int8),
        "empty": np.empty((0, 4)),
        "fortran": np.asfortranarray(rng.standard_normal((4, 5))),
        "binding": np.array("cfg-hash kernel-hash"),
        "mac": np.array("0f" * 32),
    }
    with open(tmp_path / "ours.npz", "wb") as fh:
        save_npz(fh, arrays)
    with open(tmp_path / "numpy.npz", "wb") as fh:
        np.savez(fh, **arrays)
    with np.load(tmp_path / "ours.npz") as ours, np.load(tmp_path / "numpy.npz") as ref:
        assert ours.files == ref.files == list(arrays)
        for name in arrays:
            assert ours[name].dtype == ref[name].dtype and ours[name].shape == ref[name].shape, name
            assert ours[name].tobytes() == ref[name].tobytes(), name


def test_the_manifest_lists_each_chunk_by_its_hmac(tmp_path, grid):
    """One hash per chunk: the manifest names a chunk by the HMAC it carries (no second hash of the
    file); a chunk whose HMAC is not the manifest's is set aside, and an older gyrolab's entries (the
    file's sha256) are still honoured."""
    from gyrolab.runner.store import sha256

    journal = Journal(tmp_path / "results.h5")
    journal.create({"config_hash": "abc"})
    journal.write_chunk(0, **run_chunk(grid, np.array([0, 2]), threads=1))
    journal.write_chunk(1, **run_chunk(grid, np.array([1, 3]), threads=1))
    entries = journal.manifest()["chunks"]
    for name, entry in entries.items():
        with np.load(journal.dir / name) as data:
            assert entry == {"mac": str(data["mac"]), "runs": 2}

    manifest = journal.manifest()
    older = manifest["chunks"]["chunk-00001.npz"] = {"sha256": sha256(journal.dir / "chunk-00001.npz"), "runs": 2}
    manifest["chunks"]["chunk-00000.npz"]["mac"] = "ab" * 32  # listed under another HMAC
    journal.manifest_path.write_text(json.dumps(manifest))
    rejected = Journal(tmp_path / "results.h5").verify(grid.n_runs, grid.n_samples)
    assert [name for name, _ in rejected] == ["chunk-00000.npz"]
    assert "HMAC differs from the manifest's" in rejected[0][1]
    assert Journal(tmp_path / "results.h5").manifest()["chunks"] == {"chunk-00001.npz": older}

    older["sha256"] = "0" * 64  # an older entry whose file changed since
    journal.manifest_path.write_text(json.dumps(manifest | {"chunks": {"chunk-00001.npz": older}}))
    rejected = Journal(tmp_path / "results.h5").verify(grid.n_runs, grid.n_samples)
    assert rejected == [("chunk-00001.npz", "checksum differs from the manifest's (damaged file)")]


def test_stale_result_temporaries_are_removed(tmp_path):
    from gyrolab.safe_files import remove_stale_temporaries

    out = tmp_path / "results.h5"
    for name in (".results.h5.tmp123", ".results.h5.tmp9", ".other.h5.tmp5", ".results.h5.tmpx"):
        (tmp_path / name).write_bytes(b"half")
    removed = remove_stale_temporaries(out)
    assert sorted(p.name for p in removed) == [".results.h5.tmp123", ".results.h5.tmp9"]
    assert sorted(p.name for p in tmp_path.iterdir()) == [".other.h5.tmp5", ".results.h5.tmpx"]


# --------------------------------------------------------------------------- assembly (runner/assembly.py)


def test_chunk_layout_balances_one_run_against_one_time_within_the_memory_bound():
    from gyrolab.runner.assembly import CHUNK_ELEMENTS, chunk_layout

    # the 8000-run sweep: 4 methods x 100 f x 5 theta0 x 4 dt, 1001 samples
    box, tc = chunk_layout((4, 100, 5, 4), 1001, max_runs=10**6)
    runs = int(np.prod(box))
    assert box[3] == 4 and box[2] == 5 and box[0] == 1  # taken from the trailing grid dims
    assert runs * tc <= CHUNK_ELEMENTS and runs * tc > CHUNK_ELEMENTS / 2
    one_run, one_time = runs * 1001, 8000 * tc  # values read for one run's series / one time
    assert 0.5 < one_run / one_time < 2
    box, tc = chunk_layout((4, 100, 5, 4), 1001, max_runs=50)
    assert int(np.prod(box)) <= 50 and int(np.prod(box)) * tc <= CHUNK_ELEMENTS
    box, tc = chunk_layout((1, 1, 1, 1), 10**6, max_runs=1)
    assert box == (1, 1, 1, 1) and CHUNK_ELEMENTS / 2 <= tc <= CHUNK_ELEMENTS and 10**6 % tc == 0  # no waste


def test_chunks_waste_little_at_the_edges():
    """HDF5 allocates edge chunks whole: chunk lengths are chosen so that they tile each axis closely."""
    import math

    from gyrolab.runner.assembly import chunk_layout

    for shape, ns, budget in [((4, 100, 5, 4), 1001, 270), ((4, 100, 25, 10), 11, 10**5), ((3, 7, 1, 3), 997, 5)]:
        box, tc = chunk_layout(shape, ns, max_runs=budget)
        allocated = math.prod(-(-n // b) * b for n, b in zip(shape, box)) * (-(-ns // tc) * tc)
        assert allocated <= 1.02 * math.prod(shape) * ns, (shape, box, tc)
    assert chunk_layout((1, 1, 1, 2), 3, max_runs=10) == ((1, 1, 1, 2), 3)


def test_boxes_tile_the_grid_once():
    from gyrolab.runner.assembly import box_runs, boxes

    shape = (2, 3, 5, 4)
    seen = np.concatenate([box_runs(shape, where) for where in boxes(shape, (1, 2, 2, 4))])
    np.testing.assert_array_equal(np.sort(seen), np.arange(np.prod(shape)))


def test_assembly_from_the_journal_in_boxes_gives_the_same_data(tmp_path, grid, monkeypatch):
    """Journal chunks in any order and any mix of runs, boxes with ragged edges, rows read range by
    range from the chunk files: every value, dim, dtype and attr is what the in-memory layout gives."""
    from gyrolab.results.layout import RUN_VARIABLES, to_dataset
    from gyrolab.runner import assembly, store

    runs = np.random.default_rng(1).permutation(grid.n_runs)
    pieces = [np.sort(runs[:3]), np.sort(runs[3:4]), np.sort(runs[4:])]
    journal = Journal(tmp_path / "results.h5")
    journal.create({"config_hash": "abc"})
    chunks = [run_chunk(grid, p, 1) for p in pieces]
    for number, chunk in enumerate(chunks):
        journal.write_chunk(number, **chunk)
    monkeypatch.setattr(assembly, "CHUNK_ELEMENTS", 60)  # boxes of 2 runs, 3 time chunks of 17 samples
    store.assemble(journal.dir.parent / "results.h5", grid, journal, {"scene": "heavy_top"})
    raw = np.empty((grid.n_runs, grid.n_samples, chunks[0]["samples"].shape[-1]))
    per_run = {name: np.empty(grid.n_runs, dtype=dtype) for name, (dtype, _) in RUN_VARIABLES.items()}
    for chunk in chunks:
        raw[chunk["runs"]] = chunk["samples"]
        for name in per_run:
            per_run[name][chunk["runs"]] = chunk[name]
    coords = {"integrator": list(grid.methods), "f": list(grid.f), "theta0": list(grid.theta0), "dt": list(grid.dt)}
    coords["time"] = np.arange(grid.n_samples) * grid.every
    expected = to_dataset(
        raw.reshape(grid.shape + raw.shape[1:]),
        {k: v.reshape(grid.shape) for k, v in per_run.items()},
        coords,
        {"body": grid.bodies, "omega0": grid.omega0, "q0": grid.q0},
    )
    with xr.open_dataset(tmp_path / "results.h5", engine="h5netcdf") as ds:
        assert set(ds.data_vars) == set(expected.data_vars)
        for name in expected.data_vars:
            assert ds[name].dims == expected[name].dims and ds[name].dtype == expected[name].dtype, name
            np.testing.assert_array_equal(ds[name].values, expected[name].values, err_msg=name)
    import h5py

    with h5py.File(tmp_path / "results.h5") as fh:
        assert fh["theta"].chunks == (1, 1, 1, 2, 17) and fh["axis"].chunks == (1, 1, 1, 2, 17, 3)
    # boxes across runs of different journal chunks, time chunks ragged at the end (51 = 20 + 20 + 11)
    monkeypatch.setattr(store, "chunk_layout", lambda shape, ns, most: ((1, 2, 1, 1), 20))
    store.assemble(tmp_path / "ragged.h5", grid, journal, {"scene": "heavy_top"})
    with xr.open_dataset(tmp_path / "ragged.h5", engine="h5netcdf") as ds:
        for name in expected.data_vars:
            np.testing.assert_array_equal(ds[name].values, expected[name].values, err_msg=name)


def test_journal_chunk_reads_rows_in_any_order(tmp_path, grid):
    from gyrolab.runner.assembly import JournalChunk

    journal = Journal(tmp_path / "results.h5")
    journal.create({"config_hash": "abc"})
    chunk = run_chunk(grid, np.array([0, 1, 2, 5, 6]), threads=1)
    journal.write_chunk(0, **chunk)
    source = JournalChunk(journal.chunk_files()[0], grid.n_samples, chunk["samples"].shape[-1])
    for rows in ([0, 1, 2, 3, 4], [4, 0, 3], [2], []):
        np.testing.assert_array_equal(source.read_rows(np.array(rows, dtype=int)), chunk["samples"][rows])


def test_results_file_opens_with_netcdf_c(tmp_path, grid):
    """The file is netCDF-4 for netCDF-C too (engine="netcdf4", when the netCDF4 package is installed)."""
    pytest.importorskip("netCDF4")
    path = tmp_path / "r.h5"
    write_results(path, grid, [run_chunk(grid, np.arange(grid.n_runs), 2)], {"scene": "heavy_top"})
    with xr.open_dataset(path, engine="netcdf4") as c, xr.open_dataset(path, engine="h5netcdf") as h:
        assert set(c.data_vars) == set(h.data_vars) and dict(c.sizes) == dict(h.sizes)
        for name in h.data_vars:
            np.testing.assert_array_equal(c[name].values, h[name].values, err_msg=name)
        assert c.attrs["scene"] == "heavy_top"


def synthetic_chunk(grid, runs, seed=0):
    """A finished chunk as run_chunk returns it, made up (no kernel runs): finite samples, every run
    finished, distinct solver counts per run."""
    from gyrolab.results.layout import RAW_PER_SAMPLE

    runs = np.asarray(runs, dtype=np.int64)
    rng = np.random.default_rng(seed)
    return {
        "runs": runs,
        "samples": rng.uniform(-1.0, 1.0, (runs.size, grid.n_samples, RAW_PER_SAMPLE)),
        "status": np.zeros(runs.size, np.int8),
        "n_steps": np.asarray(grid.steps(runs), dtype=np.int64),
        "wall_time": np.full(runs.size, 0.5),
        "solver_iterations": 100 + 7 * runs,
        "solver_iterations_max": 3 + runs,
    }


def test_the_solver_counts_go_through_the_journal_into_the_file(tmp_path, grid):
    """A chunk's solver counts are MAC'd with it, verify, read back from the chunk file and land at
    their runs in the results file (int64, the layout's attrs)."""
    from gyrolab.runner.assembly import JournalChunk
    from gyrolab.runner.store import CHUNK_KEYS, assemble

    assert CHUNK_KEYS[-2:] == ("solver_iterations", "solver_iterations_max")
    journal = Journal(tmp_path / "results.h5")
    journal.create({"config_hash": "abc"})
    chunks = [synthetic_chunk(grid, [0, 3, 5, 6], 1), synthetic_chunk(grid, [1, 2, 4, 7], 2)]
    for number, chunk in enumerate(chunks):
        journal.write_chunk(number, **chunk)
    assert Journal(tmp_path / "results.h5").verify(grid.n_runs, grid.n_samples) == []
    for stored, chunk in zip(journal.chunks(), chunks):
        for name in ("solver_iterations", "solver_iterations_max"):
            assert stored[name].dtype == np.int64
            np.testing.assert_array_equal(stored[name], chunk[name])
    source = JournalChunk(journal.chunk_files()[1], grid.n_samples, chunks[1]["samples"].shape[-1])
    np.testing.assert_array_equal(source.per_run("solver_iterations"), chunks[1]["solver_iterations"])
    assemble(tmp_path / "results.h5", grid, journal, {"scene": "heavy_top"})
    with xr.open_dataset(tmp_path / "results.h5", engine="h5netcdf") as ds:
        for name in ("solver_iterations", "solver_iterations_max"):
            assert ds[name].dtype == np.int64 and ds[name].dims == ("integrator", "f", "theta0", "dt")
            assert {k: ds[name].attrs[k] for k in VARIABLE_ATTRS[name]} == VARIABLE_ATTRS[name]
        np.testing.assert_array_equal(ds["solver_iterations"].values.ravel(), 100 + 7 * np.arange(grid.n_runs))
        np.testing.assert_array_equal(ds["solver_iterations_max"].values.ravel(), 3 + np.arange(grid.n_runs))


def test_a_chunk_without_the_solver_counts_or_with_altered_ones_is_set_aside(tmp_path, grid):
    """A chunk of the keys before the solver counts (proof and all) is not a chunk now; counts altered
    after writing fail the chunk's HMAC; a writer that misses one is refused before anything is stored."""
    from gyrolab.runner.store import CHUNK_KEYS, PROOF_KEYS, chunk_mac, save_npz

    journal = Journal(tmp_path / "results.h5")
    journal.create({"config_hash": "abc"})
    old_keys = ("runs", "samples", "status", "n_steps", "wall_time")
    arrays = {k: v for k, v in synthetic_chunk(grid, [0, 1]).items() if k in old_keys}
    mac = chunk_mac(journal.key(), "chunk-00000.npz", journal.binding(), arrays, old_keys)
    with open(journal.dir / "chunk-00000.npz", "wb") as fh:
        save_npz(fh, {**arrays, "binding": np.array(journal.binding()), "mac": np.array(mac)})
    journal.write_chunk(1, **synthetic_chunk(grid, [2, 3]))
    with np.load(journal.dir / "chunk-00001.npz") as data:
        altered = {k: data[k] for k in (*CHUNK_KEYS, *PROOF_KEYS)}
    altered["solver_iterations"] = altered["solver_iterations"] + 1
    with open(journal.dir / "chunk-00001.npz", "wb") as fh:
        save_npz(fh, altered)
    rejected = dict(Journal(tmp_path / "results.h5").verify(grid.n_runs, grid.n_samples))
    assert rejected["chunk-00000.npz"] == "not a gyrolab chunk (no array 'solver_iterations')"
    assert "its HMAC does not match" in rejected["chunk-00001.npz"]
    assert journal.chunk_files() == []
    partial = {k: v for k, v in synthetic_chunk(grid, [4]).items() if k != "solver_iterations_max"}
    with pytest.raises(TypeError, match="missing solver_iterations_max"):
        journal.write_chunk(2, **partial)
    assert not (journal.dir / "chunk-00002.npz").exists()
