#!/usr/bin/env python3
"""
Regenerate ``docs/results.md``: the measured numbers that the code's docstrings point to.

The docstrings say what the code does and why; where a reason is a measurement they cite a
section of ``docs/results.md`` (``docs/results.md#<section>``). This script makes each section
by running the project's own commands (console scripts, ``make demo``, the benchmarks in
``bench/``) as subprocesses, parsing what they print or write, and writing the numbers with the
command, the commit, the date, the machine (``nproc``, CPU model) and its load, so that a number
cannot go stale silently: rerun the section. It never imports the application's modules.

::

    make results                                  # every section (long: see --list)
    make results SECTIONS="modal prediction"      # some sections; the others are kept
    python tools/results.py --list                # the sections, their commands and cost
    python tools/results.py --dry-run [SECTION ...]   # the commands, nothing run or written

Run it from the repository with the workspace sourced (``source tools/env.sh``; ``make
results`` does it). Progress goes to stderr. If a command fails (an exit status it does not
allow) or its output cannot be parsed, the script says which, with the command and the end of
its output, writes the sections finished before it, and exits with status 1.

This module is the entry point: the document (its section blocks, citations, machine, commit)
and the command line. Its modules beside it, which it imports by name (a script's own directory
is first on ``sys.path``): ``results_sections`` (each section and ``SECTIONS``) with
``results_benchmarks`` (the timing benchmarks' sections), ``results_parsers`` (each command's
output read into numbers), ``results_commands`` (running a command) and ``results_markdown``
(tables).

Numbers that no command regenerates cheaply (one-off experiments, the history of a design) are
in ``docs/history.md``, ``docs/controller_notes.md`` and ``docs/fault_monitor_notes.md``.
"""

from __future__ import annotations

import argparse
import datetime as _dt
import json
import os
import platform
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from results_commands import ROOT, run_command
from results_markdown import table
from results_parsers import ResultsError
from results_sections import BY_NAME, SECTIONS, Section

DOCUMENT = ROOT / "docs" / "results.md"
#: How the code cites a section (the test checks that every cited anchor exists).
CITE = re.compile(r"docs/results\.md#([A-Za-z0-9_-]+)")


# --------------------------------------------------------------------------------------------
# The document
# --------------------------------------------------------------------------------------------

_BLOCK = re.compile(
    r"<!-- section (?P<name>[A-Za-z0-9_-]+) begin -->\n(?P<body>.*?)<!-- section (?P=name) end -->",
    re.S,
)
_META = re.compile(r"<!-- meta (?P<json>\{.*?\}) -->")


def read_blocks(text: str) -> dict[str, str]:
    """The section blocks of an existing document, by name (text between the markers)."""
    return {m["name"]: m["body"] for m in _BLOCK.finditer(text)}


def block_meta(body: str) -> dict:
    """The metadata line of a section block ({} when the section was never generated)."""
    m = _META.search(body)
    return json.loads(m["json"]) if m else {}


def citations() -> dict[str, list[str]]:
    """Section name -> files that cite ``docs/results.md#<name>`` (code, tools, README, docs)."""
    out: dict[str, list[str]] = {}
    paths = [
        *ROOT.glob("amb_*/**/*.py"),
        *ROOT.glob("tools/*"),
        *ROOT.glob("bench/*.py"),
        ROOT / "README.md",
        *ROOT.glob("docs/*.md"),
        *ROOT.glob("config/*.yaml"),
    ]
    for path in sorted(paths):
        script = path.name == "results.py" or path.match("tools/results_*.py")  # this script
        if path == DOCUMENT or not path.is_file() or script:
            continue
        for name in set(CITE.findall(path.read_text(errors="replace"))):
            out.setdefault(name, []).append(str(path.relative_to(ROOT)))
    return out


def machine() -> dict:
    """nproc, CPU model, OS and Python of this machine."""
    model = platform.processor() or "unknown"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                model = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return {
        "nproc": os.cpu_count(),
        "cpu": model,
        "os": f"{platform.system()} {platform.release()}",
        "python": platform.python_version(),
    }


def commit() -> str:
    """The commit the numbers were measured on (``+dirty`` with uncommitted code changes)."""

    def git(*a: str) -> str:
        out = subprocess.run(["git", *a], cwd=ROOT, capture_output=True, text=True)
        return out.stdout.strip() if out.returncode == 0 else ""

    head = git("rev-parse", "--short=12", "HEAD") or "unknown"
    dirty = [
        line
        for line in git("status", "--porcelain", "--untracked-files=no").splitlines()
        if not line.endswith("docs/results.md")
    ]
    return head + ("+dirty" if dirty else "")


def render_block(section: Section, meta: dict, body: list[str]) -> str:
    """The text between a section's markers."""
    cmds = "\n".join(meta["commands"])
    load = meta["load_before"], meta["load_after"]
    lines = [
        f"<!-- meta {json.dumps(meta, sort_keys=True)} -->",
        "",
        "```bash",
        cmds,
        "```",
        "",
        f"Measured {meta['date']} on commit `{meta['commit']}`, {meta['machine']['nproc']} CPUs "
        f"({meta['machine']['cpu']}; {meta['machine']['os']}, Python "
        f"{meta['machine']['python']}), 1-minute load average {load[0]:.2f} before and "
        f"{load[1]:.2f} after; {meta['wall_s']:.1f} s wall. Regenerate: `make results "
        f"SECTIONS={section.name}`.",
        "",
        *body,
    ]
    return "\n".join(lines) + "\n"


def placeholder(section: Section, args) -> str:
    """The block of a section never generated: its commands and how to generate it."""
    cmds = "\n".join(c.shell() for c in section.commands(Path("$WORK") / section.name, args))
    return (
        "Not generated yet. Commands:\n\n```bash\n"
        + cmds
        + f"\n```\n\nGenerate: `make results SECTIONS={section.name}`.\n"
    )


def render_document(blocks: dict[str, str]) -> str:
    """The whole document from the section blocks (every section has a block)."""
    rows = []
    for s in SECTIONS:
        meta = block_meta(blocks[s.name])
        when = (
            f"{meta['date']}, `{meta['commit']}`, load {meta['load_before']:.2f}"
            if meta
            else "not generated yet"
        )
        rows.append([f"[{s.name}](#{s.name})", s.regenerates, s.cost, when])
    cited = citations()
    lines = [
        "# Measured results",
        "",
        "<!-- Generated by tools/results.py: edit the script, not this file. -->",
        "This document is generated: `make results` regenerates every section, "
        '`make results SECTIONS="modal prediction"` (or `python tools/results.py modal '
        "prediction` after `source tools/env.sh`) only those and keeps the others as they "
        "are. Each section names its commands and the commit, date, machine and load it was "
        "measured with; timings depend on the machine and on what else runs on it. The code's "
        "docstrings cite these sections (`docs/results.md#<section>`) instead of quoting "
        "numbers. Measurements that no command regenerates cheaply are in `docs/history.md`, "
        "`docs/controller_notes.md` and `docs/fault_monitor_notes.md`.",
        "",
        *table(["section", "regenerates", "cost (rough)", "generated"], rows, numeric=False),
    ]
    for s in SECTIONS:
        lines += [
            "",
            f'<a id="{s.name}"></a>',
            "",
            f"## {s.name}: {s.title}",
            "",
            f"<!-- section {s.name} begin -->",
            blocks[s.name].rstrip("\n"),
            f"<!-- section {s.name} end -->",
        ]
        if cited.get(s.name):
            lines += ["", "Cited by: " + ", ".join(f"`{c}`" for c in cited[s.name]) + "."]
    return "\n".join(lines) + "\n"


# --------------------------------------------------------------------------------------------
# Main
# --------------------------------------------------------------------------------------------


def build_parser() -> argparse.ArgumentParser:
    """The command line of this script."""
    ap = argparse.ArgumentParser(
        prog="tools/results.py",
        description="Regenerate docs/results.md by running the project's commands.",
    )
    ap.add_argument(
        "sections",
        nargs="*",
        metavar="SECTION",
        help=f"sections to regenerate (default: all): {', '.join(BY_NAME)}",
    )
    ap.add_argument("--list", action="store_true", help="list the sections and exit")
    ap.add_argument(
        "--dry-run", action="store_true", help="print the commands; run and write nothing"
    )
    ap.add_argument("--out", type=Path, default=DOCUMENT, help="document (default docs/results.md)")
    ap.add_argument("--keep", type=Path, default=None, help="keep the commands' outputs in DIR")
    return ap


def _selected(args) -> list[Section]:
    names = [n for item in args.sections for n in item.replace(",", " ").split()]
    unknown = [n for n in names if n not in BY_NAME]
    if unknown:
        raise SystemExit(
            f"tools/results.py: unknown section(s) {', '.join(unknown)}; known: "
            f"{', '.join(BY_NAME)}"
        )
    return [BY_NAME[n] for n in names] if names else list(SECTIONS)


def run_section(section: Section, work: Path, args) -> str:
    """Run one section's commands; return its block (raises ResultsError on failure)."""
    before = os.getloadavg()[0]
    date = _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds")
    t0 = time.monotonic()
    section_work = work / section.name
    section_work.mkdir(parents=True, exist_ok=True)
    cmds = section.commands(section_work, args)
    outs = [run_command(section.name, c, section_work) for c in cmds]
    body = section.report(outs, section_work)
    meta = {
        "date": date,
        "commit": commit(),
        "machine": machine(),
        "load_before": round(before, 2),
        "load_after": round(os.getloadavg()[0], 2),
        "wall_s": round(time.monotonic() - t0, 1),
        "commands": [c.shell() for c in cmds],
    }
    return render_block(section, meta, body)


def main(argv: list[str] | None = None) -> int:
    """Run the selected sections and rewrite the document; 0 on success, 1 on a failure."""
    args = build_parser().parse_args(argv)
    chosen = _selected(args)
    if args.list:
        for s in SECTIONS:
            cmds = "; ".join(c.shell() for c in s.commands(Path("$WORK") / s.name, args))
            print(f"{s.name:12s} {s.cost:17s} {s.title}\n{'':30s}{cmds}")
        return 0
    if args.dry_run:
        for s in chosen:
            for c in s.commands(Path("$WORK") / s.name, args):
                print(f"{s.name}: {c.shell()}" + (f"   # {c.why}" if c.why else ""))
        return 0
    existing = read_blocks(args.out.read_text()) if args.out.is_file() else {}
    work = args.keep or Path(tempfile.mkdtemp(prefix="amb-results-"))
    work.mkdir(parents=True, exist_ok=True)
    blocks = dict(existing)
    done: list[str] = []
    status = 0
    try:
        for i, s in enumerate(chosen, 1):
            print(f"[results] section {i}/{len(chosen)}: {s.name} ({s.cost})", file=sys.stderr)
            try:
                blocks[s.name] = run_section(s, work, args)
                done.append(s.name)
            except ResultsError as exc:
                print(f"[results] FAILED: {exc}", file=sys.stderr)
                status = 1
                break
    finally:
        if args.keep is None:
            shutil.rmtree(work, ignore_errors=True)
    for s in SECTIONS:  # never generated: its current commands
        if not block_meta(blocks.get(s.name, "")):
            blocks[s.name] = placeholder(s, args)
    args.out.write_text(render_document(blocks))
    print(
        f"[results] wrote {args.out} ({', '.join(done) or 'no section regenerated'})",
        file=sys.stderr,
    )
    return status


if __name__ == "__main__":
    raise SystemExit(main())
