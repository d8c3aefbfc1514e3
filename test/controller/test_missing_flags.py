"""Reading the plant's ``STATUS_COMMAND_MISSING`` flags (``command_ledger.MissingFlags``).

The plant's contract (README, bridge contract; ``plant_sim``'s ``partial_commands``): every
sample of a period run without its command is flagged; a command applied from sample j on
leaves samples j.. unflagged. One reading serves the pipeline and the sampled-harmonic baseline.
"""

from __future__ import annotations

from amb_controller.command_ledger import MISSING, RESUMED, MissingFlags

N = 8


def _read(flags: MissingFlags, periods: dict[int, list[bool]]) -> list[tuple[int, int, str]]:
    out = []
    for m, samples in periods.items():
        for pos, missing in enumerate(samples):
            flag = flags.observe(m, pos, missing)
            if flag is not None:
                out.append((m, pos, flag))
    return out


def test_a_partial_period_is_missing_up_to_its_command_and_resumed_once() -> None:
    seen = _read(MissingFlags(), {3: [True] * 5 + [False] * 3, 4: [False] * N})
    assert seen == [(3, p, MISSING) for p in range(5)] + [(3, 5, RESUMED)]


def test_a_whole_missing_period_never_resumes_in_the_next_one() -> None:
    # the next period's first sample unflagged is a new period with its command, not a resume
    seen = _read(MissingFlags(), {3: [True] * N, 4: [False] * N, 5: [False, True] + [False] * 6})
    assert seen == [(3, p, MISSING) for p in range(N)] + [(5, 1, MISSING), (5, 2, RESUMED)]


def test_a_healthy_stream_reports_nothing() -> None:
    assert _read(MissingFlags(), {m: [False] * N for m in range(4)}) == []
