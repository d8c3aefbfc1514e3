"""
Issue 18's targets checked on an ``amb-compare`` table: one line per target and case.

The issue's controller is the receding-horizon law with the early action
(``predictive_early_i1`` / ``_i2``, :data:`CONTROLLER`); every target is read from the
table's own numbers (peaks, ``peak_to_limit``, revolutions below 10 % of PID-only's steady
amplitude, steady 1 x and residual, contact onsets) and from the robustness matrix when it was
run (``amb-compare --robustness``). The baselines are compared at the controller's own delay
(:data:`~amb_apps.compare_cases.BASELINES_AT`). A case the table lacks is left out, and the
targets ``amb-compare`` does not measure (the fault moved to 0, 1/4, 1/2, 3/4 of a period: the
early action's sweep, ``tools/early_action_sweep.py phases``) are named as such.
"""

from __future__ import annotations

from dataclasses import dataclass

from amb_apps.compare_cases import BASELINES_AT, ROBUSTNESS_SCENARIO

#: The issue-18 controller's rows (``{CONTROLLER}_i1``, ``_i2``).
CONTROLLER = "predictive_early"
#: Peak over the control limit allowed at each delay.
LIMIT_RATIO = {1: 1.5, 2: 1.1}
#: Revolutions after the fault by which the displacement must stay below 10 % of PID's.
SETTLE_REVS = 6
#: Steady displacement (1 x and the rest) allowed, as a fraction of PID-only's steady 1 x.
RESIDUAL_FRACTION = 0.02
#: Peak under a perturbed model allowed, as a multiple of the nominal peak.
ROBUST_RATIO = 1.5


@dataclass(frozen=True)
class Check:
    """One target on one case: what was measured and whether it holds."""

    target: str
    case: str
    measured: str
    met: bool


def _um(value: float) -> str:
    return f"{value * 1e6:.1f} um"


def _versus(mine: dict, name: str, theirs: dict) -> str:
    """``mine``'s peak against ``name``'s, with the difference (ties show as +-0.0x um)."""
    diff = (mine["peak"] - theirs["peak"]) * 1e6
    return f"{_um(mine['peak'])}, {name} {_um(theirs['peak'])} ({diff:+.2f} um)"


def rows_at_delay(rows: dict, i: int) -> list[str]:
    """The controller rows of a scenario with delay ``i`` (not PID, not the limits)."""
    return [n for n in rows if n != "pid" and not n.startswith("limit_") and n.endswith(f"_i{i}")]


def _below_baselines(target: str, case: str, me: dict, baselines: dict, prefix: str = "") -> Check:
    """``me``'s peak against the lowest of ``baselines`` (``{row: metrics}``, not empty)."""
    best = min(baselines, key=lambda b: baselines[b]["peak"])
    return Check(
        target,
        case,
        prefix + _versus(me, best, baselines[best]),
        me["peak"] < baselines[best]["peak"],
    )


def checks(
    table: dict, robustness: dict | None = None, unavailable: dict | None = None
) -> list[Check]:
    """Every issue-18 target the table (and the robustness matrix) can answer.

    Parameters
    ----------
    table : dict
        ``{scenario: {row: metrics}}`` of :func:`amb_apps.compare_runs.comparison`.
    robustness : dict, optional
        ``{row: {case: metrics}}`` of :func:`amb_apps.compare_runs.robustness`.
    unavailable : dict, optional
        ``{scenario: {limit row: why}}``: cases where no force sequence could keep the rotor
        off its clearance (the comparison's ``limits_unavailable``), said with the check.
    """
    out: list[Check] = []
    for key, rows in table.items():
        pid = rows.get("pid")
        for i in (1, 2):
            me = rows.get(f"{CONTROLLER}_i{i}")
            if me is None or pid is None:
                continue
            case = f"{key}, i = {i}"
            why = (unavailable or {}).get(key, {}).get(f"limit_i{i}")
            baselines = {b: rows[b] for b in BASELINES_AT[i] if b in rows}
            if key.startswith("mass_loss"):
                out += _mass_loss(case, i, me, pid, baselines)
            elif key.startswith("sync_"):
                out.append(
                    Check(
                        "150 N step synchronous force: stable, no worse than PID",
                        case,
                        f"peak {_um(me['peak'])} (PID {_um(pid['peak'])}), contact onsets "
                        f"{me['contacts']} (PID {pid['contacts']})"
                        + (f"; no limit at this delay: {why}" if why else ""),
                        me["peak"] <= pid["peak"] and me["contacts"] <= pid["contacts"],
                    )
                )
            if not key.startswith("mass_loss") and baselines:
                out.append(
                    _below_baselines(
                        "ahead of the baselines at the same delay", case, me, baselines, "peak "
                    )
                )
        if key.startswith("contact") and pid is not None:
            worse = [
                n
                for n in (*rows_at_delay(rows, 1), *rows_at_delay(rows, 2))
                if rows[n]["contacts"] > pid["contacts"] or rows[n]["peak"] > pid["peak"]
            ]
            out.append(
                Check(
                    "contact case: no controller with more contact onsets or a higher peak "
                    "than PID",
                    key,
                    f"PID {_um(pid['peak'])}, {pid['contacts']} onsets; "
                    + (f"worse: {', '.join(worse)}" if worse else "none worse"),
                    not worse,
                )
            )
    for i in (1, 2):
        cases = (robustness or {}).get(f"{CONTROLLER}_i{i}")
        if not cases or "nominal" not in cases:
            continue
        nominal = cases["nominal"]["peak"]
        worst = max((c for c in cases if c != "nominal"), key=lambda c: cases[c]["peak"])
        ratio = cases[worst]["peak"] / nominal
        out.append(
            Check(
                f"robust (model gain +-30 %, phase +-30 deg, speed +-10 %): peak <= "
                f"{ROBUST_RATIO} x nominal",
                f"{ROBUSTNESS_SCENARIO}, i = {i}",
                f"nominal {_um(nominal)}, worst {worst} {_um(cases[worst]['peak'])} "
                f"({ratio:.2f} x)",
                ratio <= ROBUST_RATIO,
            )
        )
    return out


def _mass_loss(case: str, i: int, me: dict, pid: dict, baselines: dict) -> list[Check]:
    """The mass-loss targets of one case at delay ``i``."""
    out = []
    ratio = me.get("peak_to_limit")
    if ratio is not None:
        out.append(
            Check(
                f"peak <= {LIMIT_RATIO[i]} x the limit at its delay",
                case,
                f"{ratio:.2f} x (peak {_um(me['peak'])})",
                ratio <= LIMIT_RATIO[i],
            )
        )
    if baselines:
        out.append(
            _below_baselines("peak below every baseline at the same delay", case, me, baselines)
        )
    revs = me.get("revs_below_10pct_pid")
    theirs = {b: m.get("revs_below_10pct_pid") for b, m in baselines.items()}
    sooner = revs is not None and all(r is None or revs < r for r in theirs.values())
    out.append(
        Check(
            f"below 10 % of PID's steady amplitude within {SETTLE_REVS} revolutions, sooner "
            "than every baseline",
            case,
            f"{'never' if revs is None else revs} rev; "
            + (
                ", ".join(f"{b} {'never' if r is None else r}" for b, r in theirs.items())
                or "no baseline row at this delay"
            ),
            revs is not None and revs <= SETTLE_REVS and sooner,
        )
    )
    steady = me["steady_1x"] * 1e6 + (me.get("residual_um") or 0.0)
    allowed = RESIDUAL_FRACTION * pid["steady_1x"] * 1e6
    out.append(
        Check(
            f"steady residual (1 x and the rest) <= {RESIDUAL_FRACTION:.0%} of PID's steady "
            "amplitude",
            case,
            f"{steady:.2f} um of {allowed:.2f} um allowed",
            steady <= allowed,
        )
    )
    return out


def markdown(found: list[Check], level: int = 2) -> list[str]:
    """The checks as a markdown table under a heading of ``level``.

    The targets the table cannot answer are named below it.
    """
    if not found:
        return []
    lines = [
        "",
        f"{'#' * level} Issue 18's targets ({CONTROLLER}_i1 / _i2)",
        "",
        "| target | case | measured | |",
        "|---|---|---|---|",
    ]
    for c in found:
        lines.append(f"| {c.target} | {c.case} | {c.measured} | {'met' if c.met else 'NOT MET'} |")
    lines += [
        "",
        f"{sum(c.met for c in found)} of {len(found)} met. Not measured here: the fault moved to "
        "0, 1/4, 1/2 and 3/4 of a period (`tools/early_action_sweep.py phases`)"
        + ("" if any(c.target.startswith("robust") for c in found) else "; robustness (run with "
           "`--robustness`)")
        + ".",
    ]  # fmt: skip
    return lines
