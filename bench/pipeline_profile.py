"""Profile of the four-node loop over DDS: CPU per sample of each node, and where it goes.

Runs one lock-step case of ``bench/pipeline.py`` (same scenario, model and nodes) with
``AMB_CPU_LOG`` (or, with ``--cprofile``, ``AMB_PROFILE``) set, so that every node writes its
process CPU timeline at shutdown (:mod:`amb_tools.node_main`); prints, per node, the CPU
seconds used between the plant's first and last sample (start-up and discovery excluded), CPU
microseconds per sample and the share of that wall time, the samples the filterbank processed
(a node set that drops samples to catch up in ``realtime`` does less than one sample's work per
plant sample) and the CPU per processed sample, then (``--cprofile``) the top functions
of each node by own time and by cumulative time. cProfile inflates Python-heavy code by up to
about 2x: read its table for where the time goes, the ``AMB_CPU_LOG`` run for how much.

    python bench/pipeline_profile.py [--case 67:32] [--duration 4] [--cprofile] [--top 15]
        [--keep DIR] [--set NODE.PARAM:=VALUE ...] [--composed [--apart NODE]] [--without NODE ...]
"""

from __future__ import annotations

import argparse
import os
import pstats
import shutil
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from pipeline import COMPLETE, node_cpu, prepare, processed_samples, run_mode


def main() -> None:
    """Run one case with per-node CPU logs and print the CPU per sample of each node."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--case", default="67:32", help="speed_hz:samples_per_rev")
    ap.add_argument("--duration", type=float, default=4.0, help="simulated s")
    ap.add_argument("--mode", default="lockstep", choices=("lockstep", "realtime"))
    ap.add_argument("--cprofile", action="store_true", help="also cProfile every node")
    ap.add_argument("--top", type=int, default=15, help="functions listed per node")
    ap.add_argument("--keep", type=Path, default=None, help="keep the run folder here")
    ap.add_argument("--set", action="append", default=[], help="extra amb-run --set")
    ap.add_argument(
        "--composed", action="store_true", help="filterbank, monitor, controller in one process"
    )
    ap.add_argument(
        "--without", action="append", default=[], help="amb-run --without NODE (repeatable)"
    )
    ap.add_argument(
        "--apart", action="append", default=[], help="amb-run --apart NODE (with --composed)"
    )
    args = ap.parse_args()
    hz, spr = args.case.split(":")
    work = Path(tempfile.mkdtemp(prefix="amb_profile_"))
    try:
        scenario, model = prepare(float(hz), int(spr), args.duration, work)
        prof = work / "profile"
        env = dict(os.environ)
        env.pop("AMB_PROFILE", None)
        env.pop("AMB_CPU_LOG", None)
        env["AMB_PROFILE" if args.cprofile else "AMB_CPU_LOG"] = str(prof)
        out = run_mode(
            scenario,
            model,
            args.mode,
            work / args.mode,
            env=env,
            extra=args.set,
            run_args=(["--composed"] if args.composed else [])
            + [a for n in args.without for a in ("--without", n)]
            + [a for n in args.apart for a in ("--apart", n)],
        )
        log = (out / "logs" / "plant_sim.log").read_text()
        m = COMPLETE.search(log)
        samples = round(float(hz) * int(spr) * args.duration)
        print(f"case {hz} Hz x {spr} ({samples} samples), {args.mode}: {m.group(0) if m else '?'}")
        wall = float(m.group("wall")) if m else float("nan")
        print(f"{'node':>20} {'cpu s':>7} {'us/sample':>10} {'cpu/wall':>9}")
        total = bridge = 0.0
        for name, cpu in node_cpu(prof, wall).items():
            total += cpu
            bridge += cpu if name == "plant_sim" else 0.0
            print(f"{name:>20} {cpu:7.2f} {cpu / samples * 1e6:10.1f} {cpu / wall:9.0%}")
        print(f"{'all nodes':>20} {total:7.2f} {total / samples * 1e6:10.1f} {total / wall:9.0%}")
        rest = total - bridge  # issue 17's budget: the node set, the plant (a rig's bridge) apart
        print(f"{'plant excepted':>20} {rest:7.2f} {rest / samples * 1e6:10.1f} {rest / wall:9.0%}")
        processed = processed_samples(out / "bag")
        if processed:
            # a node set that cannot keep up drops samples to catch up (realtime): its CPU per
            # plant sample then understates the work of one sample
            print(
                f"samples the filterbank processed (2 x its coefficient messages in the bag): "
                f"{processed} of {samples} ({processed / samples:.0%}); plant excepted "
                f"{rest / processed * 1e6:.1f} us per processed sample"
            )
        if args.cprofile:
            for f in sorted(prof.glob("*.prof")):
                for key in ("tottime", "cumulative"):
                    print(f"\n===== {f.stem}: top {args.top} by {key}")
                    pstats.Stats(str(f)).sort_stats(key).print_stats(args.top)
    finally:
        if args.keep is not None:
            shutil.copytree(work, args.keep, dirs_exist_ok=True)
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
