"""
``amb-bound``: the best response any controller could give (issue 18's yardstick).

::

    amb-bound --out runs/bound [--scenarios mass_loss_1st,mass_loss_2nd] [--delays 1,2]
              [--phases own,0,0.25,0.5,0.75] [--revolutions 2] [--no-settle]

For each scenario (a key of ``amb-compare``'s matrix or a scenario file), each delay ``i`` and
each fault phase, :func:`amb_plant_sim.control_limit.control_limit` solves for the added force
(per bearing axis, within the force limit, the total control force too, every journal in its
clearance) that a clairvoyant controller with delay ``i`` would apply from the first sample a
command computed from the fault's period can reach, minimising the peak inner displacement
from the fault's revolution on, then the revolutions until the displacement stays below 10 %
of PID-only's steady amplitude at that peak; and replays it on the simulated rig.

Phases: ``own`` is the scenario's fault instant; a number ``p`` moves the fault to the sample
``round(p N)`` of the same revolution (how much a controller can see before its period ends
depends on where the fault falls). Written: ``bound.json`` (every case), ``bound.md`` (the
table) and, per scenario and delay, ``bound_<scenario>_i<delay>.png`` (the scenario's own
phase: PID only against the limit, and the limit's force).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from amb_apps.closed_loop import FAULT_KINDS, first_fault
from amb_apps.compare_cases import SCENARIOS
from amb_common.paths import config_file
from amb_common.rig import load_rig
from amb_plant_sim.control_limit import LimitResult, control_limit, fault_sample
from amb_plant_sim.errors import BoundExceededError, SimulationError
from amb_plant_sim.scenario import Scenario, load_scenario

DEFAULT_SCENARIOS = ("mass_loss_1st", "mass_loss_2nd")


def build_parser() -> argparse.ArgumentParser:
    """Return the parser of ``amb-bound``."""
    ap = argparse.ArgumentParser(
        prog="amb-bound",
        description="The best peak any controller with delay i could give after a scenario's "
        "fault (linear program on the sampled FE model, replayed on the simulated rig).",
    )
    ap.add_argument("--out", required=True, type=Path, help="output folder (created)")
    ap.add_argument(
        "--scenarios",
        default=",".join(DEFAULT_SCENARIOS),
        help=f"comma-separated keys of {sorted(SCENARIOS)} or scenario files",
    )
    ap.add_argument("--delays", default="1,2", help="controller delays i (periods)")
    ap.add_argument(
        "--phases", default="own,0,0.25,0.5,0.75", help="fault phases in its period, or 'own'"
    )
    ap.add_argument("--samples-per-rev", type=int, default=None, help="default: per scenario")
    ap.add_argument("--force-limit", type=float, default=None, help="N per axis (default rig)")
    ap.add_argument("--revolutions", type=int, default=2, help="free force revolutions (2)")
    ap.add_argument("--tail", type=int, default=4, help="periodic tail revolutions (4)")
    ap.add_argument("--no-settle", action="store_true", help="skip the settling objective")
    ap.add_argument("--quiet", action="store_true", help="no progress on stderr")
    return ap


def _csv(text: str, cast, what: str) -> list:
    try:
        return [cast(v.strip()) for v in text.split(",") if v.strip()]
    except ValueError as exc:
        raise ValueError(f"--{what}: {exc}") from None


def _phase(text: str) -> float | None:
    if text == "own":
        return None
    p = float(text)
    if not 0.0 <= p < 1.0:
        raise ValueError(f"a fault phase is in [0, 1) of a period or 'own', got {text}")
    return p


def _scenario(key: str, rig) -> tuple[str, Scenario]:
    if key in SCENARIOS:
        return key, load_scenario(config_file("scenarios") / SCENARIOS[key], rig)
    path = Path(key)
    if not path.is_file():
        raise FileNotFoundError(f"{key}: neither a scenario key {sorted(SCENARIOS)} nor a file")
    return path.stem, load_scenario(path, rig)


def fault_time(scenario: Scenario) -> float:
    """Onset of the scenario's first fault event, s."""
    fault = first_fault(scenario)
    if fault is None:
        raise ValueError(f"scenario {scenario.name}: no fault event ({', '.join(FAULT_KINDS)})")
    return fault.time


def moved(scenario: Scenario, spr: int, phase: float | None) -> tuple[Scenario, float]:
    """The scenario with its first fault at ``phase`` of its revolution, and that onset (s)."""
    t_f = fault_time(scenario)
    if phase is None:
        return scenario, t_f
    first = first_fault(scenario)
    fs = scenario.speed_hz * spr
    k = (fault_sample(scenario, t_f, spr) // spr) * spr + round(phase * spr)
    t_new = (k - 0.5) / fs  # the first sample at or after it is k
    events = tuple(replace(e, time=t_new) if e is first else e for e in scenario.events)
    return replace(scenario, events=events), t_new


def row(key: str, phase: float | None, r: LimitResult) -> dict:
    """The JSON row of one case (lengths in m, forces in N)."""
    return {
        "scenario": key,
        "phase": "own" if phase is None else phase,
        "delay": r.delay,
        "fault_phase": (r.fault_sample % r.samples_per_rev) / r.samples_per_rev,
        "acts_after_rev": (r.k0 - r.fault_sample) / r.samples_per_rev,
        "peak": r.peak,
        "replay_peak": r.replay_peak,
        "floor": r.floor,
        "pid_peak": r.pid_peak,
        "pid_steady": r.pid_steady,
        "revs_below_10pct_pid": r.revs_below_10pct_pid,
        "peak_force": r.peak_force,
        "replay_contact_samples": r.replay_contacts,
        "replay_step_by_step": r.replay_step_by_step,
        "lp_rows": r.rows,
    }


def markdown(rows: list[dict], meta: dict) -> str:
    """The table of every case."""
    lines = [
        "# amb-bound: the best response any controller could give",
        "",
        f"Rig force limit {meta['force_limit']:.0f} N per axis; {meta['samples_per_rev']} "
        f"samples/rev; free force over {meta['revolutions']} revolutions, then periodic "
        f"({meta['tail']}); wall time {meta['wall_time']:.0f} s.",
        "",
        "| scenario | i | fault at (rev of its period) | force from (rev after fault) | "
        "limit peak (um) | replayed (um) | floor (um) | PID peak (um) | limit / PID | "
        "revs below 10 % PID | peak force (N) |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        if "unavoidable" in r:
            lines.append(
                f"| {r['scenario']} | {r['delay']} | {r['phase']} | - | none: "
                f"{r['unavoidable']} | | | | | | |"
            )
            continue
        settle = "-" if r["revs_below_10pct_pid"] is None else str(r["revs_below_10pct_pid"])
        lines.append(
            f"| {r['scenario']} | {r['delay']} | {r['fault_phase']:.3f}"
            f"{' (own)' if r['phase'] == 'own' else ''} | {r['acts_after_rev']:.3f} | "
            f"{r['peak'] * 1e6:.1f} | {r['replay_peak'] * 1e6:.1f} | {r['floor'] * 1e6:.1f} | "
            f"{r['pid_peak'] * 1e6:.1f} | {r['peak'] / r['pid_peak']:.2f} | {settle} | "
            f"{r['peak_force']:.0f} |"
        )
    lines += [
        "",
        "Floor: the largest inner |x| from the fault's revolution until the force can act "
        "(no controller can change it). Replayed: the optimal force on the simulated rig "
        "(contacts, saturation), noise-free; it equals the limit while the rotor stays linear.",
    ]
    return "\n".join(lines) + "\n"


def figure(key: str, r: LimitResult, out: Path) -> Path:
    """PID-only and limit inner displacement and the limit's force around the fault."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    N = r.samples_per_rev
    n_a = (r.fault_sample // N) * N
    lo = max(0, n_a - 2 * N)
    rev = (np.arange(lo, r.end) - r.fault_sample) / N
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(9, 6), sharex=True)
    pid = r.pid_displacement[lo : r.end] * 1e6
    lim = r.replay_displacement[lo : r.end] * 1e6
    ax1.plot(rev, np.abs(pid).max(axis=1), color="0.6", label="PID only (max |x| inner)")
    ax1.plot(rev, np.abs(lim).max(axis=1), color="C3", label=f"limit, i = {r.delay} (replayed)")
    ax1.axvline(0, color="k", lw=0.6)
    ax1.axvline((r.k0 - r.fault_sample) / N, color="C3", lw=0.6, ls="--")
    ax1.set_ylabel("inner |x| (um)")
    ax1.legend(loc="upper right")
    ax1.set_title(f"{key}: the best any controller with delay {r.delay} could do")
    f = np.zeros((r.end - lo, 4))
    f[r.k0 - lo :] = r.force
    for c, name in enumerate(("b1x", "b1y", "b2x", "b2y")):
        ax2.plot(rev, f[:, c], lw=0.8, label=name)
    ax2.set_ylabel("added force (N)")
    ax2.set_xlabel("revolutions after the fault")
    ax2.legend(loc="upper right", ncol=4)
    fig.tight_layout()
    path = out / f"bound_{key}_i{r.delay}.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``amb-bound``; exit 0, 1 when a case fails, 2 on invalid arguments."""
    args = build_parser().parse_args(argv)

    def progress(text: str) -> None:
        if not args.quiet:
            print(text, file=sys.stderr, flush=True)

    try:
        rig = load_rig()
        scenarios = [_scenario(k, rig) for k in _csv(args.scenarios, str, "scenarios")]
        delays = _csv(args.delays, int, "delays")
        phases = [_phase(p) for p in _csv(args.phases, str, "phases")]
        if not delays or min(delays) < 1:
            raise ValueError(f"--delays: each delay is >= 1 period, got {args.delays}")
        if args.revolutions < 1 or args.tail < 1:
            raise ValueError("--revolutions and --tail are >= 1")
        for key, sc in scenarios:
            fault_time(sc)
            if sc.profile_hz:
                raise ValueError(f"{key}: a speed profile; the limit needs a constant speed")
    except (ValueError, TypeError, FileNotFoundError) as exc:
        print(f"amb-bound: {exc}", file=sys.stderr)
        return 2
    args.out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    rows, figs, failed = [], [], 0
    total = len(scenarios) * len(delays) * len(phases)
    spr_used = set()
    for key, sc in scenarios:
        spr = args.samples_per_rev or sc.samples_per_rev or 64
        spr_used.add(spr)
        for delay in delays:
            for phase in phases:
                case, t_f = moved(sc, spr, phase)
                label = f"{key} i={delay} phase={'own' if phase is None else phase}"
                try:
                    r = control_limit(
                        rig, case, spr, t_f, delay, args.revolutions, args.tail,
                        args.force_limit, settle=not args.no_settle,
                    )  # fmt: skip
                except BoundExceededError as exc:  # a physical verdict, not a failure
                    rows.append({"scenario": key, "phase": "own" if phase is None else phase,
                                 "delay": delay, "unavoidable": str(exc)})  # fmt: skip
                    progress(f"[{len(rows) + failed}/{total}] {label}: no limit: {exc}")
                    continue
                except SimulationError as exc:
                    failed += 1
                    progress(f"[{len(rows) + failed}/{total}] {label}: failed: {exc}")
                    continue
                rows.append(row(key, phase, r))
                progress(
                    f"[{len(rows) + failed}/{total}] {label}: limit {r.peak * 1e6:.1f} um "
                    f"(replayed {r.replay_peak * 1e6:.1f}, PID {r.pid_peak * 1e6:.1f}), "
                    f"below 10 % PID after {r.revs_below_10pct_pid} rev, "
                    f"force {r.peak_force:.0f} N, {time.perf_counter() - t0:.0f} s"
                )
                if phase is None:
                    figs.append(figure(key, r, args.out))
    meta = {
        "force_limit": float(args.force_limit or rig.amb.force_limit),
        "samples_per_rev": ",".join(str(s) for s in sorted(spr_used)),
        "revolutions": args.revolutions,
        "tail": args.tail,
        "wall_time": time.perf_counter() - t0,
    }
    doc = {**meta, "cases": rows, "figures": [p.name for p in figs]}
    (args.out / "bound.json").write_text(json.dumps(doc, indent=2, default=_json))
    (args.out / "bound.md").write_text(markdown(rows, meta))
    print(f"amb-bound: wrote {args.out / 'bound.md'}, {len(rows)} cases, {failed} failed")
    return 1 if failed else 0


def _json(value):
    if isinstance(value, np.generic):
        return value.item()
    raise TypeError(f"not JSON serialisable: {type(value)}")


if __name__ == "__main__":
    raise SystemExit(main())
