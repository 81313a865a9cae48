"""runner.backend=dask end to end: a real Dask LocalCluster (2 worker processes, 1 thread each)
started here, the ``gyrolab`` command in a subprocess pointed at it, files compared with the
local backend's (wall_time and provenance aside: ``test_runner_cli.data``)."""

import json
import os
import re
import signal
import socket

import numpy as np
import pytest
import xarray as xr
from hydra import compose, initialize_config_module

pytest.importorskip("distributed")
from distributed import Client, LocalCluster  # noqa: E402

from gyrolab.runner import dask_backend  # noqa: E402
from gyrolab.runner.config import register_configs  # noqa: E402
from gyrolab.runner.grid import build_grid  # noqa: E402

from helpers import (  # noqa: E402
    SLOW,
    TINY,
    assert_ok,
    chunk_count,
    data,
    gyrolab,
    start,
    tiny_reference,
    wait_for,
)

N_RUNS = 16  # TINY: 2 methods x 2 f x 2 theta0 x 2 dt; with SLOW chunking, one run per chunk on 1-thread workers
TIMEOUT = ["runner.connect_timeout=5"]


def local_cluster(n_workers, **kwargs):
    return LocalCluster(
        n_workers=n_workers,
        threads_per_worker=1,
        processes=True,
        dashboard_address=None,
        scheduler_kwargs={"dashboard_address": ":0"},
        **kwargs,
    )


@pytest.fixture(scope="module")
def client():
    with local_cluster(2) as cluster, Client(cluster) as client:
        client.wait_for_workers(2, timeout=60)
        yield client


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """TINY on the local backend (numba threads in-process)."""
    return tiny_reference(tmp_path_factory.mktemp("local"))


def on_cluster(client):
    return ["runner.backend=dask", f"runner.address={client.scheduler.address}", *TIMEOUT]


def stats(client):
    return client.run(lambda: dict(dask_backend.STATS))


@pytest.mark.slow
def test_cluster_sweep_file_equals_the_local_one(client, reference, tmp_path):
    before = stats(client)
    result = gyrolab(*TINY, *SLOW, *on_cluster(client), f"hydra.run.dir={tmp_path / 'run'}", cwd=tmp_path)
    assert_ok(result)
    assert "running on 2 Dask workers (2 threads)" in result.stdout
    xr.testing.assert_identical(data(tmp_path / "run" / "results.h5"), data(reference))
    with xr.open_dataset(tmp_path / "run" / "results.h5", engine="h5netcdf") as ds:
        assert ds.attrs["threads"] == 2 and np.all(ds["wall_time"].values > 0)
    assert sorted(p.name for p in (tmp_path / "run").iterdir()) == ["results.h5"]
    # Each worker: one numba thread, warmed up once, then no JIT (compile or cache load) in any chunk.
    assert [info["threads"] for info in client.run(dask_backend.worker_info).values()] == [1, 1]
    after = stats(client)
    chunks = {w: after[w]["chunks"] - before[w]["chunks"] for w in after}
    assert sum(chunks.values()) == N_RUNS and min(chunks.values()) > 0, chunks
    for w in after:
        assert after[w]["warm_ups"] - before[w]["warm_ups"] == 1
        assert after[w]["jit_in_chunks"] == before[w]["jit_in_chunks"]
    assert all(
        not plugins
        for plugins in client.run(
            lambda dask_worker: [p for p in dask_worker.plugins if p.startswith("gyrolab")]
        ).values()
    )


@pytest.mark.slow
def test_a_worker_killed_mid_sweep_loses_nothing(client, reference, tmp_path):
    run = tmp_path / "run"
    pids = client.run(os.getpid)
    proc = start(*TINY, *SLOW, *on_cluster(client), f"hydra.run.dir={run}", cwd=tmp_path, GYROLAB_TEST_CHUNK_DELAY=0.5)
    wait_for(lambda: chunk_count(run) >= 2, proc)
    busy = [w for w, keys in client.processing().items() if any(str(k).startswith("gyrolab-chunk") for k in keys)]
    assert busy, "no worker holds a chunk: the sweep finished too soon for this test"
    os.kill(pids[busy[0]], signal.SIGKILL)
    out, err = proc.communicate(timeout=180)
    assert proc.returncode == 0 and "Traceback" not in err, err
    xr.testing.assert_identical(data(run / "results.h5"), data(reference))
    client.wait_for_workers(2, timeout=60)  # the nanny's replacement, for the other tests
    assert pids[busy[0]] not in client.run(os.getpid).values()
    # A replacement that joined mid-sweep was warmed before its first chunk.
    assert all(s["jit_in_chunks"] == 0 for s in stats(client).values())


@pytest.mark.slow
def test_interrupted_cluster_sweep_resumes_on_the_local_backend(client, reference, tmp_path):
    run = tmp_path / "run"
    proc = start(*TINY, *SLOW, *on_cluster(client), f"hydra.run.dir={run}", cwd=tmp_path, GYROLAB_TEST_CHUNK_DELAY=0.3)
    wait_for(lambda: chunk_count(run) >= 2, proc)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130 and "Traceback" not in err and "Finish with: gyrolab" in err, err
    resumed = gyrolab(*TINY, *SLOW, f"hydra.run.dir={run}", "runner.resume=true", cwd=tmp_path)
    assert_ok(resumed)
    assert "runs already done" in resumed.stdout
    xr.testing.assert_identical(data(run / "results.h5"), data(reference))


@pytest.mark.slow
def test_address_local_starts_its_own_cluster(reference, tmp_path):
    result = gyrolab(*TINY, "runner=dask", "runner.threads=2", f"hydra.run.dir={tmp_path / 'run'}", cwd=tmp_path)
    assert_ok(result)
    assert "running on 2 Dask workers (2 threads) at local" in result.stdout
    xr.testing.assert_identical(data(tmp_path / "run" / "results.h5"), data(reference))


@pytest.mark.slow
def test_dry_run_on_a_cluster_plans_several_chunks_per_worker_and_writes_nothing(client, tmp_path):
    result = gyrolab(*TINY, *on_cluster(client), "runner.dry_run=true", cwd=tmp_path)
    assert_ok(result)
    planned = re.search(r"; (\d+) chunks on 2 Dask workers \(2 threads\)", result.stdout)
    assert planned and int(planned.group(1)) >= 2 * dask_backend.CHUNKS_PER_WORKER, result.stdout
    assert list(tmp_path.iterdir()) == []


def composed(*overrides):
    register_configs()
    with initialize_config_module(config_module="gyrolab.conf", version_base=None):
        return compose("config", overrides=list(overrides))


@pytest.mark.parametrize("threads, n_workers", [(1, 2), (4, 3), (2, 16)])
def test_plan_covers_every_run_once_with_several_chunks_per_worker(threads, n_workers):
    grid = build_grid(composed("sweep=default"))
    cluster = dask_backend.DaskCluster(None, None, "test")
    cluster.workers = {f"w{i}": {"threads": threads} for i in range(n_workers)}
    chunks = cluster.plan(grid, np.arange(grid.n_runs), chunk_seconds=10.0)
    runs = np.concatenate(chunks)
    assert np.array_equal(np.sort(runs), np.arange(grid.n_runs))
    assert len(chunks) >= min(dask_backend.CHUNKS_PER_WORKER * n_workers, grid.n_runs // threads)
    for chunk in chunks:
        assert len(set(grid.index(chunk)[0])) == 1  # one method per chunk


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture(scope="module")
def no_workers():
    with LocalCluster(
        n_workers=0, processes=True, dashboard_address=None, scheduler_kwargs={"dashboard_address": ":0"}
    ) as cluster:
        yield cluster.scheduler_address


DASK = "runner.backend=dask"
BAD = [
    ([DASK], "runner.backend=dask: needs runner.address"),
    (
        ["runner.address=tcp://127.0.0.1:8786"],
        "runner.address=tcp://127.0.0.1:8786: only used with runner.backend=dask",
    ),
    (
        [DASK, "runner.address=tcp://127.0.0.1:{port}"],
        "runner.address=tcp://127.0.0.1:{port}: nothing listens at 127.0.0.1:{port}",
    ),
    ([DASK, "runner.address=scheduler:8786"], "runner.address=scheduler:8786: expected tcp://host:port"),
    (
        [DASK, "runner.address={no_workers}", "runner.connect_timeout=1"],
        "runner.address={no_workers}: the scheduler has no workers",
    ),
    ([DASK, "runner.scheduler_file={tmp}/none.json"], "runner.scheduler_file={tmp}/none.json: no such file"),
    ([DASK, "runner.scheduler_file={tmp}/old.h5"], "runner.scheduler_file={tmp}/old.h5: not a Dask scheduler"),
    (
        [DASK, "runner.scheduler_file={tmp}/stale.json"],
        "runner.scheduler_file={tmp}/stale.json (scheduler tcp://127.0.0.1:{port}): nothing listens",
    ),
    ([DASK, "runner.address={cluster}", "runner.threads=4"], "runner.threads=4: with a Dask cluster"),
    ([DASK, "runner.address=local", "runner.connect_timeout=0"], "runner.connect_timeout=0.0"),
]


@pytest.mark.slow
@pytest.mark.parametrize("args, message", BAD, ids=[" ".join(a)[:50] for a, _ in BAD])
def test_bad_cluster_input_is_one_line_status_2_and_no_file(client, no_workers, tmp_path, args, message):
    existing = tmp_path / "old.h5"
    existing.write_bytes(b"an earlier result")
    port = free_port()
    (tmp_path / "stale.json").write_text(json.dumps({"address": f"tcp://127.0.0.1:{port}"}))
    values = {"tmp": tmp_path, "port": port, "no_workers": no_workers, "cluster": client.scheduler.address}
    result = gyrolab("sweep=tiny", *TIMEOUT, *[a.format(**values) for a in args], cwd=tmp_path)
    assert result.returncode == 2, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("gyrolab: error: "), result.stderr
    assert message.format(**values) in lines[0]
    assert sorted(p.name for p in tmp_path.rglob("*")) == ["old.h5", "stale.json"]
    assert existing.read_bytes() == b"an earlier result"


@pytest.mark.slow
def test_long_chunks_go_segment_by_segment_on_the_cluster_and_resume_anywhere(client, tmp_path):
    from test_segments import SWEEP, segment_samples  # 64 runs of rk4, 30 sample intervals

    cut = ("runner.chunk_seconds=1e-6", "output.figures=false")  # the shortest segments
    local = tmp_path / "local"
    assert_ok(gyrolab(*SWEEP, *cut, f"hydra.run.dir={local}", cwd=tmp_path))
    before = stats(client)
    whole = tmp_path / "cluster"
    assert_ok(gyrolab(*SWEEP, *cut, *on_cluster(client), f"hydra.run.dir={whole}", cwd=tmp_path))
    xr.testing.assert_identical(data(whole / "results.h5"), data(local / "results.h5"))
    after = stats(client)
    # one task a segment: more than one (segments lengthen as the samples so far grow: WRITE_SHARE)
    assert sum(after[w]["chunks"] - before[w]["chunks"] for w in after) >= 3

    run = tmp_path / "run"
    partial = run / "results.h5.partial"
    proc = start(*SWEEP, *cut, *on_cluster(client), f"hydra.run.dir={run}", cwd=tmp_path, GYROLAB_TEST_CHUNK_DELAY=0.3)

    wait_for(lambda: segment_samples(partial) >= 4, proc)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130 and "Finish with: gyrolab" in err, err
    resumed = gyrolab(*SWEEP, *cut, f"hydra.run.dir={run}", "runner.resume=true", cwd=tmp_path)
    assert_ok(resumed)
    xr.testing.assert_identical(data(run / "results.h5"), data(local / "results.h5"))
