"""Run the missing chunks of a grid on a Dask cluster (``runner.backend=dask``).

The driver (the ``gyrolab`` process) plans every chunk up front with the
local planner (``grid.plan_chunks``, made finer until each worker gets
several chunks), submits one task per chunk, and writes each result through
the local journal as it arrives: one writer, crash-safe, resumable, the same
progress bar.  A worker integrates a chunk with the same batch kernel as the
local backend; each run's result does not depend on its chunk nor on the
thread count, so the file equals a local run's (wall_time aside).

Workers: a worker plugin compiles (or loads from numba's cache) the sweep's
kernels once per worker process, also on a worker that joins or restarts
mid-sweep.  A worker process integrates one chunk at a time with as many
numba threads as it has Dask threads (capped by its NUMBA_NUM_THREADS), so
nothing is oversubscribed.  A worker lost mid-sweep loses only its running
chunks: Dask reruns them elsewhere (up to ``distributed.scheduler.
allowed-failures`` worker deaths per chunk); task errors are retried
``RETRIES`` times.

``runner.address=local`` starts a LocalCluster inside the process
(``runner.threads`` or all cores as one-thread worker processes, never more
than the cores).  It is private to this process: every service (scheduler,
workers, the dashboard) listens on 127.0.0.1 only, and every connection is
TLS with a certificate generated for this sweep (``local_security``: Dask's
``Security.temporary()`` when the ``cryptography`` package is installed,
else one made by the ``openssl`` command in a private temporary directory);
the scheduler requires the client certificate, so another process on the
machine cannot connect, let alone submit work.  A dry run starts no
cluster (``planned_local``: the plan of the workers it would start).
"""

import asyncio
import json
import logging
import os
import shutil
import signal
import socket
import subprocess
import tempfile
import threading
import time
import uuid
from urllib.parse import urlsplit

import numba
import numpy as np
from distributed import Client, LocalCluster, WorkerPlugin, as_completed, get_worker
from numba.core import event

from ..version import __version__
from .config import ConfigError
from .execute import (
    BackendError,
    chunk_delay,
    chunk_estimate,
    integrate_chunk,
    segment_files_seconds,
    warm_up_methods,
)
from .grid import estimate_seconds, plan_chunks, runs_in_blocks
from .segments import SegmentedChunk, cut_in_time, integrate_segment, segment_length

LOCAL = "local"  # runner.address that starts a LocalCluster in this process
CHUNKS_PER_WORKER = 4  # at least this many chunks per worker: balance and small losses on a worker crash
MAX_SCHEDULER_FILE = 1 << 20  # bytes; a Dask scheduler file is a few hundred
RETRIES = 2  # reruns of a chunk whose task raised (a lost worker is handled by Dask's allowed-failures)

# --------------------------------------------------------------------------- worker side

_CHUNK_LOCK = threading.Lock()  # one chunk (or warm-up) at a time per worker process
# Counters of this worker process, read by tests through Client.run: warm-ups done, chunks
# integrated, and numba JIT events (compile or cache load) that happened inside chunks.
STATS = {"warm_ups": 0, "chunks": 0, "jit_in_chunks": 0}


def numba_threads(nthreads):
    """numba threads of one chunk on a worker with ``nthreads`` Dask threads."""
    return max(1, min(int(nthreads), numba.config.NUMBA_NUM_THREADS))


class _JitCount(event.Listener):
    def __init__(self):
        self.count = 0

    def on_start(self, ev):
        self.count += 1

    def on_end(self, ev):
        pass


def run_chunk_task(method, runs, inputs, n_samples, threshold, delay=0.0):
    """Dask task: integrate one chunk (``execute.integrate_chunk``) on this worker."""
    threads = numba_threads(get_worker().state.nthreads)
    with _CHUNK_LOCK:
        numba.set_num_threads(threads)
        jit = _JitCount()
        with event.install_listener("numba:compiler_lock", jit):
            result = integrate_chunk(method, runs, inputs, n_samples, threshold, threads)
        STATS["chunks"] += 1
        STATS["jit_in_chunks"] += jit.count
    if delay:
        time.sleep(delay)  # test hook (GYROLAB_TEST_CHUNK_DELAY of the driver)
    return result


def run_segment_task(task, delay=0.0):
    """Dask task: integrate one time segment of a chunk (``segments.integrate_segment(*task)``)."""
    threads = numba_threads(get_worker().state.nthreads)
    with _CHUNK_LOCK:
        numba.set_num_threads(threads)
        result = integrate_segment(*task, threads)
        STATS["chunks"] += 1
    if delay:
        time.sleep(delay)
    return result


class WarmUp(WorkerPlugin):
    """Compiles (or loads) the sweep's kernels when a worker starts or the plugin is registered.

    ``inputs`` are one run's kernel inputs (``Grid.inputs``): the argument types of every chunk."""

    def __init__(self, methods, inputs, threshold, blocks=False):
        self.methods, self.inputs, self.threshold, self.blocks = tuple(methods), inputs, float(threshold), blocks

    async def setup(self, worker):
        # In a thread, so the worker keeps answering the scheduler while numba compiles.
        await asyncio.get_running_loop().run_in_executor(None, self.warm)

    def warm(self):
        with _CHUNK_LOCK:
            warm_up_methods(self.methods, self.inputs, self.threshold, self.blocks)
            STATS["warm_ups"] += 1


def worker_info(dask_worker):
    """What the driver needs to know of a worker (run through ``Client.run``)."""
    return {
        "nthreads": dask_worker.state.nthreads,
        "threads": numba_threads(dask_worker.state.nthreads),
        "gyrolab": __version__,
        "numba": numba.__version__,
        "pid": os.getpid(),
    }


# --------------------------------------------------------------------------- connecting


def read_scheduler_file(path):
    """The scheduler address in a Dask scheduler file (JSON); ConfigError naming the key."""
    from ..safe_files import UnsafePathError, open_regular

    key = f"runner.scheduler_file={path}"
    try:  # a regular file, read up to MAX_SCHEDULER_FILE bytes (/dev/zero or a FIFO: refused)
        with os.fdopen(open_regular(os.path.expanduser(path), os.O_RDONLY), "rb") as fh:
            text = fh.read(MAX_SCHEDULER_FILE + 1).decode(errors="replace")
    except FileNotFoundError:
        raise ConfigError(f"{key}: no such file") from None
    except UnsafePathError as err:
        raise ConfigError(f"{key}: {str(err).split(': ', 1)[1]}") from None
    except OSError as err:
        raise ConfigError(f"{key}: cannot read it ({err.strerror})") from None
    if len(text) > MAX_SCHEDULER_FILE:
        raise ConfigError(f"{key}: not a Dask scheduler file (more than {MAX_SCHEDULER_FILE} bytes)")
    try:
        address = json.loads(text)["address"]
    except (ValueError, KeyError, TypeError):
        raise ConfigError(f"{key}: not a Dask scheduler file (JSON with an 'address')") from None
    return str(address)


def check_scheduler(address, key, timeout):
    """ConfigError (naming ``key``) unless a Dask scheduler answers at ``address`` within ``timeout`` s."""
    parts = urlsplit(address)
    try:
        host, port = parts.hostname, parts.port
    except ValueError:
        host = port = None
    if parts.scheme not in ("tcp", "tls") or not host or not port:
        raise ConfigError(f"{key}: expected tcp://host:port, tls://host:port (or local)")
    try:
        socket.create_connection((host, port), timeout=timeout).close()
    except socket.gaierror:
        raise ConfigError(f"{key}: unknown host {host}") from None
    except ConnectionRefusedError:
        raise ConfigError(f"{key}: nothing listens at {host}:{port} (connection refused)") from None
    except OSError as err:
        reason = f"no answer within {timeout:g} s" if isinstance(err, TimeoutError) else err.strerror or err
        raise ConfigError(f"{key}: cannot connect to {host}:{port} ({reason})") from None
    try:
        reply = asyncio.run(asyncio.wait_for(_identity(address, timeout), timeout))
    except Exception as err:  # whatever a non-Dask peer makes the protocol raise
        raise ConfigError(f"{key}: not a Dask scheduler ({type(err).__name__})") from None
    if not isinstance(reply, dict) or reply.get("type") != "Scheduler":
        raise ConfigError(f"{key}: not a Dask scheduler")


async def _identity(address, timeout):
    from distributed.comm import connect
    from distributed.security import Security

    # TLS settings (a tls:// scheduler's CA and client certificate) from Dask's config
    comm = await connect(address, timeout=timeout, **Security().get_connection_args("client"))
    try:
        await comm.write({"op": "identity", "reply": True})
        return await comm.read()
    finally:
        await comm.close()


def local_security(directory):
    """distributed.Security for a cluster private to this process: TLS on every connection, a
    self-signed certificate made now (``directory``: a private temporary directory for its files
    when ``openssl`` makes it), required of every client and worker.  ConfigError when neither
    the ``cryptography`` package nor the ``openssl`` command is there to make one."""
    from distributed.security import Security

    try:
        return Security.temporary()  # needs the cryptography package
    except ImportError:
        pass
    openssl = shutil.which("openssl")
    if openssl is None:
        raise ConfigError(
            f"runner.address={LOCAL}: the embedded cluster runs with TLS and needs the cryptography "
            "package (pip install cryptography) or the openssl command to make its certificate"
        )
    key, cert = os.path.join(directory, "key.pem"), os.path.join(directory, "cert.pem")
    made = subprocess.run(
        [openssl, "req", "-x509", "-newkey", "rsa:2048", "-nodes", "-keyout", key, "-out", cert, "-days", "7"]
        + ["-subj", "/CN=gyrolab-local", "-addext", "subjectAltName=IP:127.0.0.1"],
        capture_output=True,
        timeout=120,
    )
    if made.returncode != 0:
        raise ConfigError(f"runner.address={LOCAL}: openssl could not make the cluster's certificate")
    os.chmod(key, 0o600)
    return Security(
        tls_ca_file=cert,
        tls_client_cert=cert,
        tls_client_key=key,
        tls_scheduler_cert=cert,
        tls_scheduler_key=key,
        tls_worker_cert=cert,
        tls_worker_key=key,
        require_encryption=True,
    )


def local_workers(threads=None):
    """Worker processes of the embedded cluster: ``runner.threads`` or every core, at most the cores."""
    cores = len(os.sched_getaffinity(0))
    return min(int(threads), cores) if threads is not None else cores


def open_cluster(runner, dry_run=False):
    """Connect to the cluster of ``runner`` (its address or scheduler file), or start a
    LocalCluster for ``address=local`` (for a dry run: only the plan of one, nothing started).
    ConfigError (one line naming the key and value) when it cannot be reached, has no workers,
    or its workers run other versions."""
    timeout = float(runner.connect_timeout)
    if runner.address == LOCAL:
        if dry_run:
            return DaskCluster.planned_local(runner.threads)
        return DaskCluster.start_local(runner.threads)
    if runner.threads is not None:
        raise ConfigError(
            f"runner.threads={runner.threads}: with a Dask cluster the workers' threads decide "
            "(dask worker --nthreads); leave it unset"
        )
    if runner.scheduler_file is not None:
        key = f"runner.scheduler_file={runner.scheduler_file}"
        address = read_scheduler_file(runner.scheduler_file)
        check_scheduler(address, f"{key} (scheduler {address})", timeout)
    else:
        key, address = f"runner.address={runner.address}", str(runner.address)
        check_scheduler(address, key, timeout)
    try:
        client = Client(address, timeout=timeout, set_as_default=False)
    except Exception as err:
        raise ConfigError(f"{key}: cannot connect ({type(err).__name__}: {err})") from None
    cluster = DaskCluster(client, None, address)
    try:
        cluster.check_workers(key, timeout)
    except BaseException:
        cluster.close()
        raise
    return cluster


class DaskCluster:
    """A connected Dask client (and the LocalCluster it started, if any) that runs chunks."""

    def __init__(self, client, local, address, private=None):
        self.client, self.local, self.address = client, local, address
        self.private = private  # the temporary directory of the embedded cluster's certificate
        self.workers = {}

    @classmethod
    def planned_local(cls, threads=None):
        """The embedded cluster as a dry run plans it: its workers' threads, nothing started."""
        n = local_workers(threads)
        cluster = cls(None, None, LOCAL)
        cluster.workers = {f"worker-{k}": {"nthreads": 1, "threads": 1} for k in range(n)}
        return cluster

    @classmethod
    def start_local(cls, threads=None):
        """A LocalCluster of one-thread worker processes, one per core (or ``threads``, at most
        the cores), on 127.0.0.1 only, with TLS and a certificate of its own (``local_security``)."""
        n = local_workers(threads)
        private = tempfile.TemporaryDirectory(prefix="gyrolab-dask-")
        try:
            security = local_security(private.name)
        except BaseException:
            private.cleanup()
            raise
        # Worker processes inherit an ignored SIGINT: Ctrl-C in the terminal interrupts this
        # driver (which stops them), not each worker with a traceback of its own.
        previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
        try:
            local = LocalCluster(
                n_workers=n,
                threads_per_worker=1,
                processes=True,
                host="127.0.0.1",
                protocol="tls://",
                security=security,
                dashboard_address=None,
                worker_dashboard_address=None,
                scheduler_kwargs={"dashboard_address": "127.0.0.1:0"},  # its HTTP port: any free one, local
                silence_logs=logging.ERROR,
            )
        except BaseException:
            private.cleanup()
            raise
        finally:
            signal.signal(signal.SIGINT, previous)
        cluster = cls(Client(local, set_as_default=False, security=security), local, LOCAL, private)
        try:
            cluster.check_workers(f"runner.address={LOCAL}", 60.0, n_workers=n)
        except BaseException:
            cluster.close()
            raise
        return cluster

    def check_workers(self, key, timeout, n_workers=1):
        """Wait for ``n_workers`` workers (a cluster of our own: all it started, so that the plan and the
        banner count them; a scheduler of the user's: the first); ConfigError unless every worker imports
        this gyrolab and numba."""
        try:
            self.client.wait_for_workers(n_workers, timeout=timeout)
        except TimeoutError:
            try:
                seen = len(self.client.scheduler_info().get("workers", {}))
            except Exception:  # what the scheduler said last is only for the message
                seen = 0
            has = "no workers" if seen == 0 else f"{seen} of its {n_workers} workers"
            raise ConfigError(f"{key}: the scheduler has {has} (waited {timeout:g} s)") from None
        try:
            self.workers = self.client.run(worker_info)
        except Exception as err:
            raise ConfigError(f"{key}: its workers cannot run gyrolab ({type(err).__name__}: {err})") from None
        for address, info in self.workers.items():
            if (info["gyrolab"], info["numba"]) != (__version__, numba.__version__):
                raise ConfigError(
                    f"{key}: worker {address} runs gyrolab {info['gyrolab']} with numba {info['numba']}, "
                    f"this process gyrolab {__version__} with numba {numba.__version__}"
                )

    @property
    def threads(self):
        """numba threads of the whole cluster (one chunk at a time per worker)."""
        return sum(info["threads"] for info in self.workers.values())

    def describe(self):
        return f"{len(self.workers)} Dask workers ({self.threads} threads) at {self.address}"

    @property
    def chunk_threads(self):
        """numba threads of one chunk on the smallest worker (chunks are sized for it)."""
        return min((info["threads"] for info in self.workers.values()), default=1)

    def estimate_seconds(self, grid, chunks):
        """Estimated compute time (s) of the chunks spread evenly over the workers (no JIT)."""
        return estimate_seconds(grid, chunks, self.chunk_threads) / max(len(self.workers), 1)

    def segment_files_seconds(self, grid, chunks, chunk_seconds):
        """Estimated wall time (s) of the segment files of the chunks cut in time (written here, by the
        client, as their segments arrive)."""
        return segment_files_seconds(grid, chunks, self.chunk_threads, chunk_seconds)

    def plan(self, grid, runs, chunk_seconds):
        """Chunks of ``runs`` as the local planner makes them (sized for the smallest worker),
        made finer until there are CHUNKS_PER_WORKER per worker or chunks cannot shrink."""
        threads = self.chunk_threads
        target = CHUNKS_PER_WORKER * max(len(self.workers), 1)
        seconds = float(chunk_seconds)
        chunks = plan_chunks(grid, runs, threads, seconds)
        while chunks and len(chunks) < target and max(len(c) for c in chunks) > threads:
            seconds /= 2
            finer = plan_chunks(grid, runs, threads, seconds)
            if len(finer) == len(chunks) and seconds < 1e-6 * chunk_seconds:
                break  # blocks of MIN_BLOCK_RUNS long runs: no finer in runs (they are cut in time)
            chunks = finer
        return chunks

    remote = True  # the sweep says where it runs

    def start(self):
        """Nothing before the first chunk: each worker sets its own numba threads (numba_threads)."""

    def warm_up(self, grid):
        """Register the warm-up plugin: every worker compiles the sweep's kernels now, and
        every worker that joins later does so before its first chunk."""
        self.plugin = f"gyrolab-warm-up-{uuid.uuid4().hex[:8]}"
        inputs = grid.inputs(np.zeros(1, dtype=np.int64))
        try:
            blocks = any(runs_in_blocks(m, grid.n_runs // len(grid.methods), grid.driven) for m in grid.methods)
            self.client.register_plugin(WarmUp(grid.methods, inputs, grid.threshold, blocks), name=self.plugin)
        except Exception as err:
            raise BackendError(
                f"the warm-up of the kernels failed on the Dask workers at {self.address}: {type(err).__name__}: {err}"
            ) from None

    def run_missing(self, grid, journal, todo, chunk_seconds, first_number, progress=None):
        """Run the runs in ``todo`` (flat numbers) on the cluster, storing each finished chunk
        in ``journal`` as it arrives; ``progress(runs, steps)`` after each one.  A long chunk on the
        block path goes segment by segment (runner/segments.py), as on the local backend: each
        segment a task, journaled when it arrives, the next submitted then; a chunk a killed sweep
        left part-way goes on from its last segment.

        BackendError when the cluster gives up on a chunk (the journal keeps the rest)."""
        todo = np.asarray(todo, dtype=np.int64)
        resumed, rejected = journal.open_segments(todo, grid.n_runs, grid.n_samples)
        journal.report_set_aside(rejected)
        segmented = [SegmentedChunk(grid, number, arrays["runs"], arrays) for number, arrays in resumed]
        going_on = np.concatenate([c.runs for c in segmented]) if segmented else todo[:0]
        chunks = self.plan(grid, np.setdiff1d(todo, going_on), chunk_seconds)
        threads, token, delay = self.chunk_threads, uuid.uuid4().hex[:8], chunk_delay()
        futures = as_completed(loop=self.client.loop)
        what = {}  # future key -> (chunk number, runs) or a SegmentedChunk
        estimates = {}

        def submit(fn, *args, key):
            future = self.client.submit(fn, *args, key=key, retries=RETRIES, pure=False)
            futures.add(future)
            return future

        def next_segment(chunk):
            """Submit the chunk's next segment, or store the chunk when it is complete."""
            while not chunk.finished:
                n = segment_length(grid, chunk.runs, estimates[chunk.number], chunk_seconds, chunk.done)
                task = chunk.task(n)
                if task is not None:
                    key = f"gyrolab-segment-{token}-{chunk.number}-{chunk.done}"
                    what[submit(run_segment_task, task, delay, key=key).key] = chunk
                    return
                steps = chunk.absorb(journal, None)  # every run diverged: the rest is NaN, nothing to integrate
                if progress is not None:
                    progress(0, steps)
            journal.write_chunk(chunk.number, **chunk.chunk())
            journal.remove_segment(chunk.number)
            if progress is not None:
                progress(len(chunk.runs), 0)

        for chunk in segmented:
            estimates[chunk.number] = chunk_estimate(grid, chunk.runs, threads, {})
            if progress is not None:
                progress(0, chunk.steps_done())
            next_segment(chunk)
        for i, runs in enumerate(chunks):
            number, estimate = first_number + i, chunk_estimate(grid, runs, threads, {})
            if cut_in_time(grid, runs, estimate, chunk_seconds):
                estimates[number] = estimate
                next_segment(SegmentedChunk(grid, number, runs))
                continue
            method = grid.methods[int(grid.index(runs[:1])[0][0])]
            args = (method, runs, grid.inputs(runs), grid.n_samples, grid.threshold, delay)
            what[submit(run_chunk_task, *args, key=f"gyrolab-chunk-{token}-{i}").key] = (number, runs)
        try:
            # Results are fetched one at a time: until the driver has journaled a chunk, the
            # chunks done after it wait in the workers' memory, not in the driver's.
            for future in futures:
                try:
                    result = future.result()
                except Exception as error:  # the task raised on every retry, or Dask gave up on it
                    raise BackendError(
                        f"the Dask cluster at {self.address} failed on a chunk: {type(error).__name__}: {error}"
                    ) from None
                owner = what.pop(future.key)
                future.release()
                if isinstance(owner, SegmentedChunk):
                    steps = owner.absorb(journal, result)
                    if progress is not None:
                        progress(0, steps)
                    next_segment(owner)
                    continue
                number, runs = owner
                journal.write_chunk(number, **result)
                if progress is not None:
                    progress(len(runs), int(grid.steps(runs).sum()))
        finally:
            left = list(futures.futures)  # submitted, not finished
            futures.clear()
            if left:
                self.client.cancel(left)

    def close(self):
        """Unregister the warm-up plugin, disconnect, stop a LocalCluster we started."""
        if self.client is None:  # a dry run's plan: nothing was started
            return
        try:
            if getattr(self, "plugin", None) and self.client.status == "running":
                self.client.unregister_worker_plugin(self.plugin)
        except Exception:
            pass  # the cluster is going away or already gone: nothing left to clean
        finally:
            self.client.close()
            if self.local is not None:
                self.local.close()
            if self.private is not None:
                self.private.cleanup()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
