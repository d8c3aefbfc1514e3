"""Benchmark: the CPU of a suppressed warning, rclpy's throttle against ThrottledWarnings.

rclpy keys ``throttle_duration_sec`` on the caller, found with :mod:`inspect` on every call;
:class:`amb_tools.throttled_log.ThrottledWarnings` decides before calling the logger. Prints
microseconds per suppressed call of each (median of ``--repeat`` runs of ``--calls`` calls,
and every run) and the machine's 1-minute load average.

    python bench/throttled_log.py [--calls 2000] [--repeat 5]
"""

from __future__ import annotations

import argparse
import os
import statistics
import time

import rclpy
from rclpy.node import Node

from amb_tools.throttled_log import ThrottledWarnings


def _per_call(fn, calls: int) -> float:
    t0 = time.perf_counter()
    for _ in range(calls):
        fn()
    return (time.perf_counter() - t0) / calls * 1e6


def main() -> None:
    """Time both throttles on one node's logger; print every run and the median."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--calls", type=int, default=2000, help="suppressed calls per run")
    ap.add_argument("--repeat", type=int, default=5, help="runs of each")
    args = ap.parse_args()
    rclpy.init()
    try:
        node = Node("throttled_log_bench")
        logger = node.get_logger()
        ours = ThrottledWarnings(logger, period=3600.0)
        logger.warning("printed once, then throttled", throttle_duration_sec=3600.0)
        ours.warning("bench", "printed once, then held back")
        runs = {"rclpy throttle_duration_sec": [], "ThrottledWarnings": []}
        for _ in range(args.repeat):
            runs["rclpy throttle_duration_sec"].append(
                _per_call(lambda: logger.warning("held", throttle_duration_sec=3600.0), args.calls)
            )
            runs["ThrottledWarnings"].append(
                _per_call(lambda: ours.warning("bench", "held"), args.calls)
            )
        print(f"load {os.getloadavg()[0]:.1f}; us per suppressed warning, {args.calls} calls a run")
        for name, values in runs.items():
            every = " ".join(f"{v:.2f}" for v in values)
            print(f"{name:>28}: median {statistics.median(values):8.2f}   runs {every}")
        node.destroy_node()
    finally:
        rclpy.shutdown()


if __name__ == "__main__":
    main()
