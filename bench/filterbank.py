"""
Benchmark of the wavelet filterbank core (prints numbers; not a test).

Streaming: cost per sample of ChannelFrontEnd (8 sensor channels, fixed + rotating
frames, even + odd quadrature = 32 channels) followed by AnalysisFilterbank.step at
8 levels, for haar and db4 (target <= 50 us per sample). Block: analyze_block against
pywt.wavedec(mode="zero", axis=0) on the same (N, 32) array, ratio measured in one run
(target: within 2x of PyWavelets).

Run from the repository root: ``PYTHONPATH=. python bench/filterbank.py [--samples 8192]
[--repeats 5]`` (or with the package installed).
"""

from __future__ import annotations

import argparse
import statistics
import time
import warnings

import numpy as np
import pywt

from amb_wavelet.analysis import AnalysisFilterbank, analyze_block
from amb_wavelet.frontend import ChannelFrontEnd
from amb_wavelet.synthesis import SynthesisFilterbank


def _median_time(fn, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def main() -> None:
    """Time the streaming and block filterbanks and print the cost per sample and the ratios."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    ap.add_argument("--samples", type=int, default=8192)
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    n, reps = args.samples, args.repeats
    spr, level = 64, 8
    rng = np.random.default_rng(1)
    xy = 1e-5 * rng.standard_normal((n, 8))
    theta = 2 * np.pi * np.arange(n) / spr
    print(f"samples={n} repeats={reps} samples_per_rev={spr} level={level}")
    print("streaming, per sample (median of repeats):")
    for wavelet in ("haar", "db4"):
        fe = ChannelFrontEnd(spr)
        bank = AnalysisFilterbank(wavelet, level, fe.n_channels)
        syn = SynthesisFilterbank(wavelet, level, fe.n_channels)
        rows = list(xy)
        angles = theta.tolist()

        def run_frontend(fe=fe, rows=rows, angles=angles):
            fe.reset()
            for r, a in zip(rows, angles, strict=True):
                fe.step(r, a)

        chans = fe.process_block(xy, theta)
        crow = list(chans)

        def run_bank(bank=bank, crow=crow):
            bank.reset()
            for c in crow:
                bank.step(c)

        def run_both(fe=fe, bank=bank, rows=rows, angles=angles):
            fe.reset()
            bank.reset()
            for r, a in zip(rows, angles, strict=True):
                bank.step(fe.step(r, a))

        def run_round_trip(bank=bank, syn=syn, crow=crow):
            bank.reset()
            syn.reset()
            for c in crow:
                syn.step(bank.step(c))

        t_fe = _median_time(run_frontend, reps) / n * 1e6
        t_bank = _median_time(run_bank, reps) / n * 1e6
        t_both = _median_time(run_both, reps) / n * 1e6
        t_rt = _median_time(run_round_trip, reps) / n * 1e6
        print(
            f"  {wavelet:5s} front-end {t_fe:6.1f} us | filterbank {t_bank:6.1f} us | "
            f"front-end + filterbank {t_both:6.1f} us (target <= 50) | "
            f"analysis + synthesis {t_rt:6.1f} us"
        )
    print("block throughput, (N, 32) array, 8 levels:")
    big = 1e-5 * rng.standard_normal((max(n, 65536), 32))
    for wavelet in ("haar", "db4"):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)
            t_pywt = _median_time(
                lambda w=wavelet: pywt.wavedec(big, w, mode="zero", level=level, axis=0), reps
            )
        t_ours = _median_time(lambda w=wavelet: analyze_block(big, w, level), reps)
        rate = big.shape[0] / t_ours / 1e6
        print(
            f"  {wavelet:5s} analyze_block {t_ours * 1e3:7.2f} ms ({rate:5.2f} Msample/s) | "
            f"pywt.wavedec {t_pywt * 1e3:7.2f} ms | ratio ours/pywt {t_ours / t_pywt:5.2f} "
            "(target <= 2)"
        )


if __name__ == "__main__":
    main()
