"""
Benchmark: time to compute one wavelet control command, as a fraction of the period.

Cases: MIMO over 4 bearing axes and 8 sensor channels, even and odd quadrature, 1 level
(p = 1: 16 measured / 8 control coefficients) and 3 levels (p = 1, 2, 3: 112 / 56),
truncated inverse of order 5 and 10, delay 2. Timed: ``TransientController.step``
alone and the full ``WaveletControlSupervisor.step`` (controller + synthesis of the
force samples + saturation). Reported: median and 99th percentile over many periods,
and the median as a fraction of the control period at 11 Hz and 67 Hz running speed
(one revolution per period).

Run from the repository root: ``PYTHONPATH=. python bench/controller.py [--periods N]``.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from amb_controller.basis import control_basis
from amb_controller.response import PrescribedResponse
from amb_controller.supervisor import Mode, WaveletControlSupervisor
from amb_controller.synthesis import ForceLimiter
from amb_controller.transient import TransientController

SPEEDS_HZ = (11.0, 67.0)


def _time_steps(step, measured: np.ndarray) -> np.ndarray:
    out = np.empty(measured.shape[0])
    for k in range(measured.shape[0]):
        t0 = time.perf_counter()
        step(k, measured[k])
        out[k] = time.perf_counter() - t0
    return out


def main() -> None:
    """Run the benchmark and print a table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument("--periods", type=int, default=3000)
    parser.add_argument("--samples-per-rev", type=int, default=64)
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    alpha = PrescribedResponse.exponential(0.75, 0.75)
    print(
        f"{'levels':>6} {'order':>5} {'n_y':>4} {'n_u':>4} {'part':>10} "
        f"{'median us':>10} {'p99 us':>8} "
        + " ".join(f"{'frac@' + format(f, 'g') + 'Hz':>11}" for f in SPEEDS_HZ)
    )
    for levels in ((1,), (1, 2, 3)):
        basis = control_basis("haar", args.samples_per_rev, levels, n_axes=4)
        n_u = basis.n_coefficients
        n_y = 2 * n_u  # 8 sensors vs 4 axes
        for order in (5, 10):
            inverse = rng.normal(size=(order + 1, n_u, n_y)) * 1e3
            measured = rng.normal(size=(args.periods, n_y)) * 1e-6
            ctrl = TransientController(inverse, alpha, delay=2)
            ctrl_times = _time_steps(ctrl.step, measured)
            limiter = ForceLimiter(basis, limit=1e9, capacity=1e9)
            sup = WaveletControlSupervisor(limiter, 2, TransientController(inverse, alpha, 2))
            sup.set_mode(Mode.ACTIVE)
            sup_times = _time_steps(sup.step, measured)
            for part, times in (("controller", ctrl_times), ("supervisor", sup_times)):
                med, p99 = np.median(times), np.percentile(times, 99)
                fracs = " ".join(f"{med * f:11.2e}" for f in SPEEDS_HZ)
                print(
                    f"{len(levels):>6} {order:>5} {n_y:>4} {n_u:>4} {part:>10} "
                    f"{med * 1e6:10.1f} {p99 * 1e6:8.1f} {fracs}"
                )


if __name__ == "__main__":
    main()
