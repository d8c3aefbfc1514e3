"""amb-bound: the fault moved to a phase of its period, the table and JSON, bad arguments."""

import json

import pytest

from amb_apps.bound_cli import main


def test_fault_moved_to_half_a_period_acts_one_and_a_half_revolutions_later(tmp_path, capsys):
    out = tmp_path / "bound"
    argv = ["--out", str(out), "--scenarios", "mass_loss_1st,contact_case2", "--delays", "2",
            "--phases", "0.5", "--samples-per-rev", "32", "--revolutions", "1", "--tail", "2",
            "--no-settle", "--quiet"]  # fmt: skip
    assert main(argv) == 0
    doc = json.loads((out / "bound.json").read_text())
    mass, contact = doc["cases"]
    # fault at sample N/2 of its revolution; i = 2: the force from the start of the
    # revolution two after it, 1.5 revolutions after the fault
    assert mass["fault_phase"] == 0.5
    assert mass["acts_after_rev"] == 1.5
    assert mass["floor"] <= mass["peak"] < mass["pid_peak"]
    # in the contact case the journal reaches its clearance before any force can act
    assert "clearance" in contact["unavoidable"]
    table = (out / "bound.md").read_text()
    assert "| mass_loss_1st | 2 | 0.500 | 1.500 |" in table
    assert "cases, 0 failed" in capsys.readouterr().out


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--phases", "1.5"], "in [0, 1)"),
        (["--delays", "0"], ">= 1 period"),
        (["--scenarios", "nowhere"], "neither a scenario key"),
    ],
)
def test_bad_arguments_exit_2_with_the_reason(tmp_path, capsys, args, message):
    assert main(["--out", str(tmp_path / "b"), *args]) == 2
    assert message in capsys.readouterr().err
