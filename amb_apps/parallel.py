"""
Independent simulations in parallel processes: the sweep commands' ``--jobs N``.

The sweeps (``amb-compare``, ``amb-fault-eval``, ``amb-acceptability``, ``reproduce``) run many
simulations that share nothing but their inputs. :func:`run_jobs` runs a module-level function
over a list of tasks in ``jobs`` worker processes and returns the results in the tasks' order,
so that a sweep's report is the same whatever ``jobs`` is (each simulation is deterministic:
its noise is seeded by its scenario). ``jobs = 1`` runs in this process, without a pool.

Workers are started with ``forkserver`` (a clean interpreter that imports only what the task
needs; forking a process that has loaded rclpy or a BLAS thread pool is unsafe) and inherit
the environment, so ``OPENBLAS_NUM_THREADS=1`` (``tools/env.sh``) keeps one thread per worker.
A task that raises stops the sweep with that exception, as in a serial run.
"""

from __future__ import annotations

import argparse
import multiprocessing
import os
from collections.abc import Callable, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from typing import Any


def default_jobs() -> int:
    """Return the number of cores this process may run on (``os.sched_getaffinity``)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return max(1, os.cpu_count() or 1)


def jobs_count(text: str) -> int:
    """``argparse`` type of ``--jobs``: an integer >= 1."""
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"--jobs must be an integer >= 1, got {text!r}") from None
    if n < 1:
        raise argparse.ArgumentTypeError(f"--jobs must be >= 1, got {n}")
    return n


def add_jobs_argument(ap: argparse.ArgumentParser) -> None:
    """Add ``--jobs N`` (default: :func:`default_jobs`) to a sweep command's parser."""
    ap.add_argument(
        "--jobs",
        type=jobs_count,
        default=None,
        metavar="N",
        help=f"simulations run in N parallel processes (default: the cores, {default_jobs()} here)",
    )


def run_jobs(
    fn: Callable[[Any], Any],
    tasks: Sequence[Any],
    jobs: int | None = None,
    done: Callable[[int, Any], None] | None = None,
) -> list[Any]:
    """
    Return ``[fn(t) for t in tasks]``, computed in ``jobs`` processes.

    Parameters
    ----------
    fn : callable
        A module-level function (workers import it by name); its argument and result must
        pickle.
    tasks : sequence
        Submitted in order: put the longest first for the shortest total time.
    jobs : int, optional
        Worker processes (default :func:`default_jobs`); at most ``len(tasks)`` are started;
        1 runs the tasks here, one after the other.
    done : callable, optional
        ``done(index, result)`` in this process as each task completes (progress lines).

    Raises
    ------
    ValueError
        ``jobs < 1``.
    Exception
        The first exception a task raised (the pending tasks are cancelled).
    """
    jobs = default_jobs() if jobs is None else int(jobs)
    if jobs < 1:
        raise ValueError(f"jobs must be >= 1, got {jobs}")
    results: list[Any] = [None] * len(tasks)
    if jobs == 1 or len(tasks) <= 1:
        for i, task in enumerate(tasks):
            results[i] = fn(task)
            if done is not None:
                done(i, results[i])
        return results
    ctx = multiprocessing.get_context("forkserver")
    with ProcessPoolExecutor(max_workers=min(jobs, len(tasks)), mp_context=ctx) as pool:
        pending: dict[Future, int] = {pool.submit(fn, t): i for i, t in enumerate(tasks)}
        try:
            while pending:
                finished, _ = wait(pending, return_when=FIRST_COMPLETED)
                for fut in finished:
                    i = pending.pop(fut)
                    results[i] = fut.result()
                    if done is not None:
                        done(i, results[i])
        except BaseException:
            for fut in pending:
                fut.cancel()
            raise
    return results
