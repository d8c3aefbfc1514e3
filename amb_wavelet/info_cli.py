"""
``amb-wavelet-info``: Table 4.1 uncertainty measures and wavelet plots (figures 4.7-4.13).

Examples
--------
``amb-wavelet-info`` prints the twelve rows of Table 4.1;
``amb-wavelet-info --wavelets haar,db4 --k 2 --json`` prints JSON;
``amb-wavelet-info --plot figs/`` also writes ``wavelets.png`` (scaling and wavelet
functions, figures 4.7, 4.9, 4.10), ``spectra.png`` (Fourier transform magnitudes,
figures 4.8, 4.11) and ``uncertainty_vs_order.png`` (figure 4.13).
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from amb_wavelet.errors import WaveletNameError
from amb_wavelet.filters import get_filters
from amb_wavelet.synthesis import basis_function
from amb_wavelet.uncertainty import Uncertainty, uncertainty

__all__ = ["TABLE_4_1_WAVELETS", "main"]

#: Rows of thesis Table 4.1, in its order.
TABLE_4_1_WAVELETS = (
    "haar",
    "db2",
    "db4",
    "db8",
    "db16",
    "sym2",
    "sym4",
    "sym8",
    "coif1",
    "coif2",
    "coif4",
    "dmey",
)

#: Detail level used to draw the (near-continuous) wavelet shapes.
PLOT_LEVEL = 7


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="amb-wavelet-info",
        description="Heisenberg and balanced uncertainty of orthogonal wavelets "
        "(Cade 2006, eq. 4.29-4.36, Table 4.1) and wavelet plots.",
    )
    p.add_argument(
        "--wavelets",
        default=",".join(TABLE_4_1_WAVELETS),
        help="comma-separated PyWavelets names (default: the rows of Table 4.1)",
    )
    p.add_argument("--k", type=float, default=1.0, help="weight k of M(k), eq. 4.36")
    p.add_argument("--json", action="store_true", help="print JSON instead of a table")
    p.add_argument("--plot", metavar="DIR", help="write PNG figures into DIR")
    return p


def _table(rows: list[Uncertainty], k: float) -> str:
    head = (
        f"{'wavelet':<8} {'dw (rad/sample)':>16} {'dt (samples)':>13} {'dw*dt':>8} {f'M({k:g})':>8}"
    )
    lines = [f"Wavelet uncertainties, k = {k:g} (thesis Table 4.1)", head, "-" * len(head)]
    for u in rows:
        lines.append(
            f"{u.wavelet:<8} {u.delta_omega:>#16.4g} {u.delta_t:>#13.4g} {u.product:>#8.4g} "
            f"{u.balanced:>#8.4g}"
        )
    return "\n".join(lines)


def _plot(names: list[str], k: float, out: Path) -> list[Path]:
    # heavy, optional: matplotlib, only with --plot
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out.mkdir(parents=True, exist_ok=True)
    written = []
    scale = 2.0**PLOT_LEVEL  # samples per unit time of the mother wavelet
    fig, axes = plt.subplots(len(names), 2, figsize=(9, 1.9 * len(names) + 0.6), squeeze=False)
    for row, name in zip(axes, names, strict=True):
        for ax, kind, title in zip(
            row, ("approximation", "detail"), ("scaling function", "wavelet"), strict=True
        ):
            g = basis_function(name, PLOT_LEVEL, kind) * np.sqrt(scale)
            t = np.arange(g.size) / scale
            ax.plot(t, g, lw=1.0)
            ax.set_title(f"{name}: {title}", fontsize=9)
            ax.set_ylabel("amplitude (-)")
            ax.grid(alpha=0.3)
        row[0].set_xlabel("t / T (-), T = wavelet unit time")
        row[1].set_xlabel("t / T (-), T = wavelet unit time")
    fig.tight_layout()
    path = out / "wavelets.png"
    fig.savefig(path, dpi=120)
    plt.close(fig)
    written.append(path)

    fig, ax = plt.subplots(figsize=(7, 4))
    nfft = 1 << 16
    for name in names:
        g = basis_function(name, PLOT_LEVEL, "detail")
        spec = np.abs(np.fft.rfft(g, nfft))
        f = np.fft.rfftfreq(nfft) * scale  # cycles per unit time
        ax.plot(f, spec / spec.max(), lw=1.0, label=name)
    ax.set_xlim(0, 4)
    ax.set_xlabel("frequency x T (cycles per wavelet unit time, -)")
    ax.set_ylabel("|Fourier transform| / max (-)")
    ax.set_title("Fourier transform magnitude of the wavelets (figures 4.8, 4.11)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    path = out / "spectra.png"
    fig.savefig(path, dpi=120)
    plt.close(fig)
    written.append(path)

    fig, (a1, a2) = plt.subplots(1, 2, figsize=(10, 4))
    for family, orders in (("db", range(1, 21)), ("sym", range(2, 21)), ("coif", range(1, 18))):
        us = [uncertainty(f"{family}{n}", k) for n in orders]
        lengths = [get_filters(f"{family}{n}").length for n in orders]
        a1.plot(lengths, [u.product for u in us], "o-", ms=3, label=family)
        a2.plot(lengths, [u.balanced for u in us], "o-", ms=3, label=family)
    a1.set_ylabel("Heisenberg uncertainty dw*dt (rad)")
    a2.set_ylabel(f"balanced uncertainty M({k:g}) (sample units, eq. 4.36)")
    for a in (a1, a2):
        a.set_xlabel("filter length L (taps)")
        a.grid(alpha=0.3)
        a.legend()
    fig.suptitle("Uncertainty against filter length (figure 4.13)")
    fig.tight_layout()
    path = out / "uncertainty_vs_order.png"
    fig.savefig(path, dpi=120)
    plt.close(fig)
    written.append(path)
    return written


def main(argv: Sequence[str] | None = None) -> int:
    """
    Run the command.

    Parameters
    ----------
    argv : sequence of str, optional
        Arguments without the program name (default ``sys.argv[1:]``).

    Returns
    -------
    int
        Exit status: 0 on success, 2 for bad arguments (unknown wavelet, negative k).
    """
    args = _parser().parse_args(argv)
    names = [n.strip() for n in args.wavelets.split(",") if n.strip()]
    try:
        if not names:
            raise ValueError("--wavelets is empty; give e.g. --wavelets haar,db4")
        rows = [uncertainty(n, args.k) for n in names]
    except (WaveletNameError, ValueError) as exc:
        print(f"amb-wavelet-info: error: {exc}", file=sys.stderr)
        return 2
    names = [u.wavelet for u in rows]
    written = _plot(names, args.k, Path(args.plot)) if args.plot else []
    if args.json:
        doc = {
            "k": args.k,
            "units": {"delta_omega": "rad/sample", "delta_t": "samples"},
            "rows": [u.as_dict() for u in rows],
            "figures": [str(p) for p in written],
        }
        print(json.dumps(doc, indent=2))
    else:
        print(_table(rows, args.k))
        for p in written:
            print(f"wrote {p}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
