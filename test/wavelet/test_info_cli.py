"""The amb-wavelet-info command."""

from __future__ import annotations

import json

import pytest

from amb_wavelet.info_cli import main


def test_default_table_has_the_twelve_rows(capsys: pytest.CaptureFixture[str]) -> None:
    assert main([]) == 0
    out = capsys.readouterr().out
    assert "Table 4.1" in out
    rows = [line.split() for line in out.splitlines()[3:]]
    assert [r[0] for r in rows] == [
        "haar", "db2", "db4", "db8", "db16", "sym2",
        "sym4", "sym8", "coif1", "coif2", "coif4", "dmey",
    ]  # fmt: skip
    assert rows[0][1:] == [
        "1.136",
        "0.5000",
        "0.5679",
        "1.540",
    ]  # thesis: 1.136 0.5000 0.5677 1.540
    assert rows[-1][1:] == ["0.9146", "1.107", "1.013", "2.063"]  # thesis row, all digits


def test_json_and_k(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["--wavelets", "haar,db4", "--k", "2", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["k"] == 2.0 and [r["wavelet"] for r in doc["rows"]] == ["haar", "db4"]
    haar = doc["rows"][0]
    assert haar["balanced"] == pytest.approx(haar["delta_omega"] ** 2 + 2 * 0.25, rel=1e-12)
    assert doc["units"] == {"delta_omega": "rad/sample", "delta_t": "samples"}


@pytest.mark.slow
def test_plot_writes_pngs(tmp_path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["--wavelets", "haar,db2", "--plot", str(tmp_path)]) == 0
    names = sorted(p.name for p in tmp_path.iterdir())
    assert names == ["spectra.png", "uncertainty_vs_order.png", "wavelets.png"]
    assert all((tmp_path / n).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" for n in names)


@pytest.mark.parametrize("bad", ["bior2.2", "nope", ""])
def test_bad_wavelet_exit_2(bad: str, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["--wavelets", bad]) == 2
    assert "error" in capsys.readouterr().err
