"""The Markdown of ``tools/results.py``: tables and numbers as the sections write them."""

from __future__ import annotations


def _num(v, fmt: str = ".3g", scale: float = 1.0) -> str:
    if v is None:
        return "-"
    if isinstance(v, float) and v != v:
        return "nan"
    return format(v * scale if scale != 1.0 else v, fmt)


def table(head: list[str], rows: list[list], numeric: bool = True) -> list[str]:
    """A Markdown table: first column left-aligned, the others right-aligned if ``numeric``."""
    rule = "|---|" + ("---:|" if numeric else "---|") * (len(head) - 1)
    out = ["| " + " | ".join(head) + " |", rule]
    out += ["| " + " | ".join(str(c) for c in r) + " |" for r in rows]
    return out
