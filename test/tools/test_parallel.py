"""
The sweeps' ``--jobs``: results in the tasks' order, errors raised, and a simulation run in a
worker process equal to the same run in this one (deterministic runs, the same table for
any ``--jobs``).
"""

import argparse
import math

import numpy as np
import pytest

from amb_apps.parallel import default_jobs, jobs_count, run_jobs

# the task: a function the workers can import by name (a test module is not importable
# there: pytest imports it with importlib); math.isqrt raises ValueError on a negative


@pytest.mark.parametrize("jobs", [1, 2, 3])
def test_results_come_in_the_tasks_order_and_progress_sees_each_once(jobs):
    seen = []
    out = run_jobs(math.isqrt, [x * x for x in range(7)], jobs, lambda i, r: seen.append((i, r)))
    assert out == list(range(7))
    assert sorted(seen) == [(x, x) for x in range(7)]


@pytest.mark.parametrize("jobs", [1, 2])
def test_a_failing_task_raises_its_own_error(jobs):
    with pytest.raises(ValueError, match="must be nonnegative"):
        run_jobs(math.isqrt, [1, -1, 4], jobs)


def test_jobs_argument_accepts_positive_integers_only():
    assert jobs_count("3") == 3
    for bad in ("0", "-2", "two"):
        with pytest.raises(argparse.ArgumentTypeError):
            jobs_count(bad)
    with pytest.raises(ValueError, match="jobs must be >= 1"):
        run_jobs(math.isqrt, [1], 0)
    assert default_jobs() >= 1


def test_a_compare_row_run_in_a_worker_equals_the_same_row_run_here():
    # the worker rebuilds the matrix from its arguments and identifies its own model: the
    # run must be the same, sample for sample, as in this process (nothing random is left
    # unseeded, nothing is inherited from the parent)
    from amb_apps.compare_cases import Matrix
    from amb_apps.compare_runs import _row_task
    from amb_common.paths import config_file

    matrix = Matrix(config_file("scenarios"), 16, None, True)
    tasks = [(matrix.args, "mass_loss_1st", "pid"), (matrix.args, "mass_loss_1st", "wavelet_i1")]
    here = [_row_task(t) for t in tasks]
    there = run_jobs(_row_task, tasks, 2)
    for (r1, rad1, _, e1), (r2, rad2, _, e2) in zip(here, there, strict=True):
        assert e1 is None and e2 is None
        np.testing.assert_array_equal(r1.displacement, r2.displacement)
        np.testing.assert_array_equal(r1.wavelet_force, r2.wavelet_force)
        assert (rad1 is None and rad2 is None) or math.isclose(rad1, rad2, rel_tol=1e-12)
    assert np.any(here[1][0].wavelet_force != 0.0)  # the controller acted in that run
