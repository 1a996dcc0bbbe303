"""Campaigns on Dask: the client and cluster that sweeps, validations and discoveries share.

:func:`dask_client` opens a ``dask.distributed`` client: without an address, an embedded
``LocalCluster`` with one worker process per core and one thread per worker (each task runs the FMU
in its own process); with ``tcp://HOST:PORT``, the cluster a scheduler there runs.

:func:`ship_fmu` hands the client's FMU to the workers (its bytes go to each worker once, through
Dask), and :func:`use_fmu` on a worker points :mod:`tether.fmu` at that copy, so every worker runs
the very binary the client would: rows equal a serial run's bit for bit whatever the cluster.

:func:`run_tasks` submits one task per item and hands each result back as it finishes, with
progress on stderr.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import logging
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Callable, Iterable, Iterator, Sequence

#: --scheduler value that asks for the embedded local cluster explicitly
LOCAL = "local"


class CampaignError(RuntimeError):
    """The cluster could not be reached or used; ``str(e)`` is one line naming the address."""


def cores() -> int:
    """The cores this process may run on."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not Linux
        return max(1, os.cpu_count() or 1)


def check_address(scheduler: str) -> str:
    """A scheduler's address (``PROTOCOL://HOST:PORT``) or "local"; CampaignError otherwise."""
    if scheduler != LOCAL and "://" not in scheduler:
        raise CampaignError(f"--scheduler {scheduler}: expected an address such as tcp://127.0.0.1:8786 "
                            f"(or '{LOCAL}' for the embedded cluster)")
    return scheduler


@contextlib.contextmanager
def dask_client(scheduler: str | None = None, n_workers: int | None = None,
                progress: Callable[[str], None] | None = None) -> Iterator:
    """A ``distributed.Client``: the embedded local cluster (``scheduler`` None or "local";
    ``n_workers`` processes, default one per core, one thread each) or the scheduler at
    ``scheduler`` (``tcp://HOST:PORT``). Closed on leaving, the embedded cluster with it."""
    from dask.distributed import Client, LocalCluster

    say = progress or (lambda _line: None)
    if scheduler in (None, LOCAL):
        n = n_workers or cores()
        say(f"starting a local Dask cluster: {n} worker process{'es' if n > 1 else ''}, 1 thread each")
        # its HTTP endpoints on a free port: the fixed default collides with any other cluster here
        cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=":0",
                               silence_logs=logging.CRITICAL)   # a task's error comes back with its result
        try:
            client = Client(cluster)
            try:
                yield client
            finally:
                client.close()
        finally:
            cluster.close()
        return
    check_address(scheduler)
    try:
        client = Client(scheduler, timeout="5s")    # a scheduler answers in milliseconds; retried till then
    except (OSError, TimeoutError) as e:
        raise CampaignError(f"--scheduler {scheduler}: cannot reach a Dask scheduler there ({e})") from None
    try:
        n = len(client.scheduler_info().get("workers", {}))
        say(f"connected to the Dask scheduler at {scheduler}: {n} worker{'s' if n != 1 else ''}")
        yield client
    finally:
        client.close()


# ---------------------------------------------------------------------------------------------
# the FMU on the workers
def fmu_bytes() -> tuple[str, bytes]:
    """(sha256, bytes) of the FMU this process would run."""
    from .fmu import fmu_path

    data = fmu_path().read_bytes()
    return hashlib.sha256(data).hexdigest(), data


def _package_version() -> str:
    from . import __version__

    return __version__


def ship_fmu(client):
    """Hand the client's FMU to the cluster once; pass the returned future to :func:`use_fmu`."""
    return client.scatter([(*fmu_bytes(), _package_version())], hash=False, broadcast=True)[0]   # one piece (a tuple alone is split)


_shipped: dict[str, str] = {}   # on a worker: sha256 -> the FMU file written there


def use_fmu(shipped: tuple[str, bytes, str]) -> None:
    """On a worker: run the shipped FMU (written once per process into a temporary directory); the
    worker's package must be the client's version."""
    digest, data, version = shipped
    if _package_version() != version:
        import socket

        raise CampaignError(f"the worker on {socket.gethostname()} has tether {_package_version()}, the client "
                            f"{version}: install the client's version on every worker")
    path = _shipped.get(digest)
    if path is None:
        path = _shipped[digest] = str(_shipped_file(digest, data))
    os.environ["KT_FMU"] = path


def _shipped_file(digest: str, data: bytes) -> Path:
    """The shipped FMU as one file of the temporary directory per FMU (its digest), written by the
    first worker process of this machine and shared by the rest: a worker closed with its cluster
    runs no exit handler, and a file of its own per process was left behind each time (with its
    extracted folder, tether.fmu). Written beside it and renamed into place, never seen half
    written."""
    target = Path(tempfile.gettempdir()) / f"tether-fmu-shipped-{digest[:16]}.fmu"
    if target.is_file() and target.stat().st_size == len(data):
        return target
    fd, part = tempfile.mkstemp(prefix=target.name + ".", suffix=".part", dir=target.parent)
    with os.fdopen(fd, "wb") as f:
        f.write(data)
    os.replace(part, target)
    return target


# ---------------------------------------------------------------------------------------------
def run_tasks(client, fn: Callable, items: Sequence, *args, label: str = "task",
              progress: Callable[[str], None] | None = None) -> Iterable[tuple[int, object]]:
    """Submit ``fn(item, *args)`` for each item; yield ``(index, result)`` as each finishes.

    A task that raised re-raises here (the first one to finish so). Progress (done/total, rate,
    time left) goes to ``progress`` at most once a second and at the end."""
    from dask.distributed import as_completed

    futures = [client.submit(fn, item, *args, pure=False) for item in items]
    index = {f.key: i for i, f in enumerate(futures)}
    total = len(futures)
    t0 = last = time.monotonic()
    done = 0
    try:
        for fut in as_completed(futures):
            result = _result(fut, f"{label} {index[fut.key] + 1} of {total}")
            done += 1
            now = time.monotonic()
            if progress and (now - last >= 1.0 or done == total):
                last = now
                rate = done / max(now - t0, 1e-9)
                left = (total - done) / rate if rate > 0 else float("nan")
                progress(f"  {done}/{total} {label}s done, {rate:.1f}/s, about {left:.0f} s left")
            yield index[fut.key], result
    finally:
        client.cancel([f for f in futures if not f.done()])


def _result(future, what: str):
    """A task's result; its own errors (a simulation that failed, ...) as they are, the cluster's
    (a worker lost, a connection closed) as one CampaignError line."""
    try:
        return future.result()
    except Exception as e:  # noqa: BLE001 - sorted below
        if type(e).__module__.split(".")[0] == "tether":
            raise
        raise CampaignError(f"{what} failed on the cluster ({type(e).__name__}: {e})") from e


def stderr_progress(line: str) -> None:
    sys.stderr.write(line + "\n")
    sys.stderr.flush()


def call_with_fmu(call: tuple, shipped):
    """A Dask task: ``fn(*args)`` for ``call`` = (fn, args) on a worker, with the client's FMU
    (see :func:`ship_fmu`)."""
    fn, args = call
    use_fmu(shipped)
    return fn(*args)


def map_on_cluster(scheduler: str | None, fn: Callable, arg_tuples: Sequence[tuple], label: str = "task",
                   progress: Callable[[str], None] | None = stderr_progress,
                   each: Callable[[int, object], None] | None = None) -> list:
    """``[fn(*args) for args in arg_tuples]``, each call a task on the cluster at ``scheduler``
    (None or "local": the embedded one), in the order given; ``each(index, result)`` as each
    finishes."""
    results: list = [None] * len(arg_tuples)
    with dask_client(scheduler, progress=progress) as client:
        fmu = ship_fmu(client)
        for i, r in run_tasks(client, call_with_fmu, [(fn, a) for a in arg_tuples], fmu, label=label,
                              progress=progress):
            results[i] = r
            if each is not None:
                each(i, r)
    return results


# ---------------------------------------------------------------------------------------------
@contextlib.contextmanager
def spawned_cluster(folder: Path, workers: int = 2, timeout: float = 60.0) -> Iterator[str]:
    """`dask scheduler` and ``workers`` `dask worker` processes (one thread each) of this
    environment on 127.0.0.1, each in a session of its own, as on a cluster of separate machines;
    yields the scheduler's address and stops them all on leaving, even on failure. Their logs go
    to ``folder``."""
    from dask.distributed import Client

    dask = str(Path(sys.executable).with_name("dask"))
    folder = Path(folder)
    sched_file = folder / "scheduler.json"
    procs: list[subprocess.Popen] = []

    def start(*args) -> None:
        with open(folder / f"dask-{len(procs)}.log", "w") as log:
            procs.append(subprocess.Popen([dask, *args], stdout=log, stderr=subprocess.STDOUT, cwd=folder,
                                          start_new_session=True))

    try:
        start("scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard", "--scheduler-file", str(sched_file))
        deadline = time.monotonic() + timeout
        while not sched_file.is_file():
            if time.monotonic() > deadline or procs[0].poll() is not None:
                raise CampaignError(f"dask scheduler did not start (log: {folder / 'dask-0.log'})")
            time.sleep(0.1)
        for _ in range(workers):
            start("worker", "--scheduler-file", str(sched_file), "--host", "127.0.0.1", "--nthreads", "1",
                  "--nworkers", "1", "--no-dashboard")
        address = json.loads(sched_file.read_text())["address"]
        with Client(address, timeout=f"{timeout}s") as client:
            client.wait_for_workers(workers, timeout=timeout)
        yield address
    finally:
        _stop(procs)


def _stop(procs: Sequence[subprocess.Popen]) -> None:
    """SIGTERM each process's session (the worker a nanny started with it), SIGKILL what stays."""
    for p in reversed(procs):
        if p.poll() is None:
            os.killpg(p.pid, signal.SIGTERM)
    for p in procs:
        try:
            p.wait(timeout=15)
        except subprocess.TimeoutExpired:
            os.killpg(p.pid, signal.SIGKILL)
            p.wait()
