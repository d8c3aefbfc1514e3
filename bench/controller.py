"""
Benchmark: time to compute one wavelet control command, as a fraction of the period.

Cases: MIMO over 4 bearing axes and 8 sensor channels, even and odd quadrature, 1 level
(p = 1: 16 measured / 8 control coefficients) and 3 levels (p = 1, 2, 3: 112 / 56),
delay 2: the transient controller (eq. 8.10) with a truncated inverse of order 5 and 10, and
the predictive controller (:mod:`amb_controller.predictive`, the Markov order, horizon, moves
and weights of ``ControllerConfig``'s defaults). Timed: the controller's ``step`` alone and the
full ``WaveletControlSupervisor.step`` (controller + synthesis of the force samples +
saturation). Reported: median and 99th
percentile over many periods, the median as a fraction of the control period at 11 Hz and
67 Hz running speed (one revolution per period), and the p99 as a fraction at 67 Hz (issue
18's target: <= 5 %). The early action on a sudden unbalance
(:mod:`amb_controller.early_action`, 8 sensors, the rig's 4 disk and 2 AMB planes): its
per-period test (``end_period`` on quiet periods) and the plan it makes once when it decides.

Run from the repository root: ``PYTHONPATH=. python bench/controller.py [--periods N]``.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from amb_apps.plant_models import early_action_planes
from amb_common.rig import load_rig
from amb_controller.basis import control_basis
from amb_controller.config import ControllerConfig
from amb_controller.early_action import EarlyAction, EarlyActionConfig
from amb_controller.early_model import EarlyActionModel
from amb_controller.predictive import PredictiveController
from amb_controller.response import PrescribedResponse
from amb_controller.supervisor import Mode, WaveletControlSupervisor
from amb_controller.synthesis import ForceLimiter
from amb_controller.transient import TransientController

SPEEDS_HZ = (11.0, 67.0)
#: the predictive law's settings: the configuration's defaults
DEFAULT = ControllerConfig()
#: Markov order M of the predictive cases (identification_order's default)
PREDICTIVE_ORDER = DEFAULT.identification_order


def _print_row(law: str, levels: int, order, n_y: int, n_u: int, part: str, times) -> None:
    """One table row: median and p99 (us), the median as a fraction of each period, p99 at 67 Hz."""
    med, p99 = np.median(times), np.percentile(times, 99)
    fracs = " ".join(f"{med * f:11.2e}" for f in SPEEDS_HZ)
    print(
        f"{law:>10} {levels:>6} {order:>5} {n_y:>4} {n_u:>4} {part:>10} "
        f"{med * 1e6:10.1f} {p99 * 1e6:8.1f} {fracs} {p99 * 67.0:9.2e}"
    )


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
        f"{'law':>10} {'levels':>6} {'order':>5} {'n_y':>4} {'n_u':>4} {'part':>10} "
        f"{'median us':>10} {'p99 us':>8} "
        + " ".join(f"{'frac@' + format(f, 'g') + 'Hz':>11}" for f in SPEEDS_HZ)
        + f" {'p99@67Hz':>9}"
    )
    for levels in ((1,), (1, 2, 3)):
        basis = control_basis("haar", args.samples_per_rev, levels, n_axes=4)
        n_u = basis.n_coefficients
        n_y = 2 * n_u  # 8 sensors vs 4 axes
        measured = rng.normal(size=(args.periods, n_y)) * 1e-6
        cases = []
        for order in (5, 10):
            inverse = rng.normal(size=(order + 1, n_u, n_y)) * 1e3
            cases.append(
                ("transient", order, lambda inv=inverse: TransientController(inv, alpha, 2))
            )
        markov = rng.normal(size=(PREDICTIVE_ORDER + 1, n_y, n_u)) * 1e-6
        cases.append(
            (
                "predictive",
                PREDICTIVE_ORDER,
                lambda m=markov: PredictiveController(
                    m, 2, DEFAULT.horizon, DEFAULT.moves, DEFAULT.move_weight, DEFAULT.input_weight
                ),
            )
        )
        for law, order, make in cases:
            ctrl_times = _time_steps(make().step, measured)
            limiter = ForceLimiter(basis, limit=1e9, capacity=1e9)
            sup = WaveletControlSupervisor(limiter, 2, make())
            sup.set_mode(Mode.ACTIVE)
            sup_times = _time_steps(sup.step, measured)
            for part, times in (("controller", ctrl_times), ("supervisor", sup_times)):
                _print_row(law, len(levels), order, n_y, n_u, part, times)

    _early(rng, args.samples_per_rev, min(args.periods, 500))


def _early(rng: np.random.Generator, n: int, periods: int) -> None:
    """Time the early action's period test and its plan on a random model of the real size."""
    config = EarlyActionConfig()
    L = config.horizon_periods * n
    planes = early_action_planes(load_rig())  # the FE route's: every disk and both AMBs
    model = EarlyActionModel(
        n,
        rng.normal(size=(L, 8, 4)) * 1e-7,
        rng.normal(size=(len(planes), L + 4 * n, 8, 2)) * 1e-3,
        planes,
        tuple(range(8)),
        (2, 3, 4, 5),
    )
    early = EarlyAction(model, config, 2)
    y = rng.normal(size=(periods, n, 8)) * 2e-7
    f = np.zeros((n, 4))
    times = np.empty(periods)
    for k in range(periods):
        t0 = time.perf_counter()
        early.end_period(k, y[k], f)
        times[k] = time.perf_counter() - t0
    theta = np.array([1e-3, 0.0])
    plans = np.empty(50)
    for k in range(len(plans)):
        t0 = time.perf_counter()
        early._plan(0, n // 2, theta, 100, 102)
        plans[k] = time.perf_counter() - t0
    for part, t in (("test", times), ("plan", plans)):
        _print_row("early", 1, "-", 8, 4, part, t)


if __name__ == "__main__":
    main()
