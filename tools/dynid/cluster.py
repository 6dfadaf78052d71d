"""Where a fit's tasks run: in this process (the default: a process pool forked per run), or on a Dask
`distributed` cluster.

`dynid fit --workers N` starts a `LocalCluster` of N single-threaded worker processes on this machine;
`--scheduler ADDRESS` connects to a running cluster (`dask scheduler` and `dask worker` processes, on other hosts:
docs/deployment.md#many-runs-on-a-dask-cluster). Tasks are plain functions with picklable arguments (a robot
configuration, a run's path, the settings, a block range), so a worker reads the data itself: the data must be at
the same path on every worker (a shared file system), and no log travels through the scheduler.

Results come back in the order the tasks were given, whatever order they finish in, so a fit on a cluster sums
exactly what the serial fit sums, in the same order. A task that raises (bad data) raises the same error here; a
cluster that fails raises `ClusterError`, one line and exit code 3: a task whose worker died
`distributed.scheduler.allowed-failures` times (3), no worker at all for longer than the scheduler's
`distributed.scheduler.no-workers-timeout` (a LocalCluster's: 120 s; a running cluster's: its own, none by default,
when the fit waits for workers to come back), the scheduler gone. A worker that dies once is replaced (its nanny
restarts it) or its tasks move to the others: the fit goes on, with the same result.

Layer: above errors, progress and interrupt; `distributed` is imported only when a cluster is asked for. Ctrl-C:
a local cluster's workers never get it (they start with SIGINT blocked), this process answers it and closes the
cluster; one that comes while the cluster starts is held and delivered once it is up (dynid.interrupt).
"""

from __future__ import annotations

import contextlib
import os
import warnings
from collections.abc import Callable, Iterator, Sequence
from typing import Any

from .errors import DataNote, InputError
from .interrupt import sigint_held
from .progress import RunProgress

CONNECT_TIMEOUT_S = 20.0
NO_WORKERS_TIMEOUT = "120s"  # a LocalCluster's; a running cluster's is its scheduler's (docs/deployment.md)


class ClusterError(InputError):
    """The cluster could not be reached or failed during the run (not the data's fault)."""

    exit_code = 3


class DaskCluster:
    """Tasks on a Dask cluster: a new `LocalCluster` of `workers` processes, or the one at `scheduler`."""

    def __init__(self, workers: int | None = None, scheduler: str | None = None) -> None:
        from multiprocessing import resource_tracker

        try:
            import dask
            from distributed import Client, LocalCluster
        except ImportError as e:  # pragma: no cover - distributed is a dependency
            raise ClusterError(f"Dask distributed is not installed ({e}): pip install distributed") from None
        self._local = None
        try:
            if scheduler is not None:
                self.name = f"the Dask cluster at {scheduler}"
                self.client = Client(scheduler, timeout=CONNECT_TIMEOUT_S, set_as_default=False)
            else:
                self.name = f"a local Dask cluster of {workers} worker process{'es' * (workers != 1)}"
                # One thread a worker: the tasks are numpy and Pinocchio loops that hold the GIL between calls
                # Tasks wait for a worker no longer than this (a cluster whose every worker died stops the fit)
                timeouts = {"distributed.scheduler.no-workers-timeout": NO_WORKERS_TIMEOUT}
                # The workers start with SIGINT blocked (they inherit it: dynid.interrupt): the terminal's Ctrl-C
                # reaches the whole process group, and each worker printed its KeyboardInterrupt traceback; this
                # process alone answers it, and closing the cluster ends them. A Ctrl-C while they start is held, not
                # lost, and delivered once the cluster is up (ignored here, it was lost: the fit ran to its end).
                # multiprocessing's resource tracker is started before: starting it unblocks SIGINT in the thread
                # that does (CPython's resource_tracker.ensure_running), which would be the cluster's IO loop, the
                # thread its workers are started from.
                resource_tracker.ensure_running()
                with dask.config.set(timeouts), sigint_held(children=True):
                    # ":0": the scheduler's HTTP server on a free port (8787 may be another cluster's)
                    self._local = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                               dashboard_address=":0", silence_logs=50)
                self.client = Client(self._local, set_as_default=False)
            self.workers = len(self.client.scheduler_info().get("workers", {}))
        except (OSError, TimeoutError, ValueError) as e:
            self.close()
            where = f"--scheduler {scheduler}" if scheduler else f"--workers {workers}"
            raise ClusterError(f"{where}: no Dask cluster there ({type(e).__name__}: {e})") from None
        except BaseException:  # Ctrl-C (held over the start, delivered here): the workers end with the cluster
            self.close()
            raise
        if self.workers == 0:
            self.close()
            raise ClusterError(f"{self.name} has no worker")

    def map(self, fn: Callable[..., Any], tasks: Sequence[tuple], label: str, runs: Sequence[int] | None = None,
            chunks: Sequence[int] | None = None) -> list[Any]:
        from distributed import as_completed

        progress = RunProgress(label, runs, chunks)
        # pure=False: a task reads a file, which may change between two fits with the same arguments
        futures = [self.client.submit(fn, *args, pure=False, key=f"{label}-{i}") for i, args in enumerate(tasks)]
        index = {f.key: i for i, f in enumerate(futures)}
        with _failures(self.name):
            try:
                for future in as_completed(futures, loop=self.client.loop):
                    future.result()  # raises the task's own error (a DataError: exit 2) as soon as it comes
                    progress.done(index[future.key])
                out = self.client.gather(futures)
            except BaseException:
                self.client.cancel(futures)
                raise
            finally:
                progress.close()
        return out

    def close(self) -> None:
        with contextlib.suppress(Exception):
            if getattr(self, "client", None) is not None:
                self.client.close()
        with contextlib.suppress(Exception):
            if self._local is not None:
                self._local.close()


@contextlib.contextmanager
def _failures(name: str) -> Iterator[None]:
    """The cluster's own failures as one line each (the data's errors pass through unchanged)."""
    from distributed import KilledWorker
    from distributed.comm.core import CommClosedError
    from distributed.scheduler import NoValidWorkerError, NoWorkerError

    try:
        yield
    except KilledWorker as e:
        raise ClusterError(f"{name}: a task was lost with its worker too many times ({e.args[0] if e.args else e}); "
                           "a worker that dies on every try (out of memory?) stops the fit") from None
    except (NoWorkerError, NoValidWorkerError):
        raise ClusterError(f"{name}: no worker left to run the fit's tasks (every worker is gone, for longer than the "
                           "scheduler's distributed.scheduler.no-workers-timeout)") from None
    except (CommClosedError, OSError, TimeoutError) as e:
        raise ClusterError(f"{name}: lost the connection to the cluster ({type(e).__name__}: {e})") from None


def executor(workers: int | None = None, scheduler: str | None = None) -> DaskCluster | None:
    """The cluster the command line asks for (`--workers N`, `--scheduler ADDRESS`); None: in-process. A local
    cluster has at most one worker a CPU this process may run on: each worker is a process of its own that imports
    dynid and holds its runs' blocks, and more of them than CPUs only share the CPUs and multiply the memory."""
    if workers is not None and scheduler is None and workers > (cpus := len(os.sched_getaffinity(0))):
        warnings.warn(DataNote(f"--workers {workers}: this process may run on {cpus} CPU{'s' * (cpus != 1)}; "
                               f"{cpus} worker{'s' * (cpus != 1)} started"), stacklevel=2)
        workers = cpus
    if scheduler is not None and (why := scheduler_problem(scheduler)):  # the API's; the CLI's parser refuses first
        raise InputError(f"--scheduler {scheduler!r}: {why}")
    if scheduler is not None or workers is not None:
        return DaskCluster(workers, scheduler)
    return None


def scheduler_problem(address: str) -> str:
    """Why no plain Dask scheduler has `address` ('' where one may: [tcp://]HOST:PORT), before any connection (a
    walkthrough's '127.0.0.1' without its port, 'http://...' and '' each waited 40 s and left a traceback; 'tls://'
    needs a security context dynid does not take, and was a traceback, exit 1)."""
    scheme, sep, location = address.partition("://")
    if not sep:
        scheme, location = "tcp", address
    host, colon, port = location.rpartition(":")
    if scheme == "tls":
        return ("a TLS scheduler needs a security context, which dynid does not take; reach it over tcp:// (an SSH "
                "tunnel, a private network)")
    if scheme != "tcp" or not colon or not host or not port.isdigit() or not 0 < int(port) < 65536:
        return "not a Dask scheduler's address: give [tcp://]HOST:PORT, e.g. tcp://127.0.0.1:8786"
    return ""
