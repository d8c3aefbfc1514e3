"""
How early could the fault monitor see a fault at its thresholds? A noise-free bound.

For each scenario of ``config/scenarios/faults`` that matches ``--match`` (default: the
contact cases), the plant core simulates the run once; the filterbank core and the monitor
run on the measured (noisy) displacement as in ``amb-fault-eval``, and a second monitor runs
on the simulator's noise-free displacement (``truth['true_displacement']``) with the noisy
run's calibrated thresholds. Printed per case and wavelet, in samples after the true onset
(contacts: the first sample with a contact force, however light):

- ``clean >1``: the first coefficient completion at which a noise-free feature exceeds its
  threshold (any level, frame, plane): with measurement noise the ratio can reach 1 earlier
  only by chance, so no detector on these features and thresholds can be reliably earlier;
- ``clean >=3``: the same for ``confirm_ratio`` (a single-feature confirmation);
- ``detected``: the detection the monitor reported (the matched event), and the peak force
  of the first simulated touch.

The thresholds are those that give no false alarm in 10 simulated minutes (``k = 8``
robust standard deviations, ``bench/fault_monitor.py``); where ``detected`` is close to
``clean >1``, a later detection is the touch being below the noise at those thresholds, not
the logic after the crossing.

Run: ``python bench/fault_detectability.py [--match contact] [--wavelet haar,db2,db4]``.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # before numpy is imported
ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402

from amb_apps.evaluation import run_case, simulate_case  # noqa: E402
from amb_common.rig import load_rig  # noqa: E402
from amb_fault_monitor.config import MonitorConfig  # noqa: E402
from amb_fault_monitor.monitor import FaultMonitor  # noqa: E402
from amb_fault_monitor.records import FilterbankAdapter  # noqa: E402


def clean_ratios(case, wavelet: str, thresholds: dict, sync_threshold) -> list:
    """Feature ratios of the noise-free displacement against the noisy run's thresholds."""
    spr = case.samples_per_rev
    block = case.block
    clean = block.truth["true_displacement"]
    monitor = FaultMonitor(MonitorConfig(spr))
    adapter = FilterbankAdapter(spr, wavelet)
    trace: list = []
    for i in range(block.sample_index.size):
        rec = adapter.step(int(block.sample_index[i]), clean[i], block.angle[i], block.omega[i])
        monitor.step(rec)
        if monitor.calibrated and monitor.trace is None:
            # the noisy run's thresholds replace the ones calibrated on noise-free data
            monitor.set_thresholds(thresholds, sync_threshold)
            monitor.trace = trace
    return trace


def noisy_run(case, wavelet: str):
    """The evaluation's run, plus its thresholds (a second, identical monitor calibrates)."""
    res = run_case(case, wavelet)
    spr = case.samples_per_rev
    block = case.block
    monitor = FaultMonitor(MonitorConfig(spr))
    adapter = FilterbankAdapter(spr, wavelet)
    for i in range(block.sample_index.size):
        monitor.step(
            adapter.step(
                int(block.sample_index[i]), block.displacement[i], block.angle[i], block.omega[i]
            )
        )
        if monitor.calibrated:
            break
    return res, monitor.thresholds, monitor.sync_threshold


def first_above(trace: list, start: int, level: float) -> int | None:
    """Samples after ``start`` until a traced ratio first exceeds ``level`` (None: never)."""
    for n, _level, _frame, _first, _last, ratio in trace:
        if n >= start and float(np.max(ratio)) > level:
            return n - start
    return None


def main(argv: list[str] | None = None) -> int:
    """Print the noise-free detection bound of each case and wavelet (module docstring)."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[1])
    ap.add_argument("--scenarios", default=str(ROOT / "config" / "scenarios" / "faults"))
    ap.add_argument("--match", default="contact", help="only files whose name contains this")
    ap.add_argument("--wavelet", default="haar,db2,db4")
    args = ap.parse_args(argv)
    rig = load_rig()
    files = sorted(p for p in Path(args.scenarios).glob("*.yaml") if args.match in p.name)
    if not files:
        raise SystemExit(f"no scenario matches {args.match!r} in {args.scenarios}")
    print(
        f"{'case':34s}{'wavelet':>8s}{'fault':>22s}{'touch N':>9s}"
        f"{'clean >1':>10s}{'clean >=3':>10s}{'detected':>10s}  (samples after the true onset)"
    )
    for path in files:
        case = simulate_case(path, rig)
        for wavelet in args.wavelet.split(","):
            res, thr, sync_thr = noisy_run(case, wavelet)
            trace = clean_ratios(case, wavelet, thr, sync_thr)
            for m in res.matches:
                true = m.get("true_onset_sample")
                if true is None:
                    continue
                b1, b3 = first_above(trace, true, 1.0), first_above(trace, true, 3.0)
                peak = m.get("first_contact_peak_n")
                print(
                    f"{case.name[:33]:34s}{wavelet:>8s}{m['expected']:>22s}"
                    f"{'' if peak is None else f'{peak:.0f}':>9s}"
                    f"{'-' if b1 is None else b1:>10}{'-' if b3 is None else b3:>10}"
                    f"{m.get('detection_delay_samples', '-'):>10}",
                    flush=True,
                )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
