"""The fault monitor does not depend on the mother wavelet (thesis section 5.2): haar, db2, db4.

"The method of fault identification presented is based around the compact support of the
mother wavelet. It is therefore independent of the choice of wavelet used" (section 5.2,
figures 5.19-5.26 repeat the 67 Hz cases with Daubechies 2 and 4). The thesis subset of the
scenario suite (``config/scenarios/faults``) is simulated once with the plant core and the
monitor runs on it with each wavelet; the reference is the simulator's truth (fault times
from the scenario files, contact onsets from the contact force). The whole suite is run by
``amb-fault-eval --wavelet haar,db2,db4`` (its results: ``docs/results.md``, fault-eval); it
is not a test because its contact cases are slow to simulate on a loaded machine. The subset
holds the cases the thesis shows:

- 430 g cm loss at 67 Hz that leads to contacts half a revolution later (figures 5.1-5.6,
  5.19-5.26, and the contacts a loss leads to, figure 5.27 case 2);
- a bearing contact at 67 Hz and one at 29 Hz (figures 5.4-5.6, 5.16-5.18), and the rub of a
  misaligned AB2 at 67 Hz (figures 5.1-5.6), whose smooth 50-313 N touches leave the 68.7 Hz
  mode ringing (decided a mass loss with haar and db2 until the 1 x level's change had to be
  coherent: ``amb_fault_monitor.phasor``);
- 430 g cm losses at 18 and 29 Hz (figures 5.7-5.12);
- the 516 g cm loss at 19 Hz, figure 5.27 case 1.

On the rig model calibrated in issue 16 the 430 g cm loss at 29 Hz (just under the third
critical speed) and case 1 saturate the bearings' force and then touch: their scenario files
expect the contact too (the thesis saw contacts in case 2 only), and a test here checks that
every case touches exactly when its file says so. The monitor's contact rules were tuned on
the earlier model; ``KNOWN`` lists, per wavelet, the cases it now gets wrong and why
(measured), and the test fails as well when one of them comes right.
"""

from pathlib import Path

import pytest

from amb_apps.evaluation import run_case, simulate_case, summarise
from amb_common.rig import load_rig

pytestmark = pytest.mark.slow

SUITE = Path(__file__).resolve().parents[2] / "config" / "scenarios" / "faults"
THESIS_SUBSET = (
    "mass_loss_67hz_430gcm_250.yaml",
    "contact_ab1_67hz_sync_force.yaml",
    "contact_ab2_29hz_unbalance.yaml",
    "contact_ab2_67hz_unbalance.yaml",
    "mass_loss_18hz_430gcm_000.yaml",
    "mass_loss_29hz_430gcm_000.yaml",
    "mass_loss_19hz_case1_fig5_27.yaml",
)


# Cases the monitor gets wrong on the calibrated rig (wrong class, missed, or a false alarm).
# (At 29 Hz with haar and db2 the bends of the bearing force at its limit, from 2.04 s, rang
# the rotating-frame finest level and opened a contact 1.8 revolutions before the first touch
# until the monitor was given the force limit: control_transients, "Limits".)
KNOWN: dict[str, set[str]] = {"haar": set(), "db2": set(), "db4": set()}
# The first touch after the 67 Hz loss with db4 is found 3.2 revolutions late (0.09 on the
# earlier model): the touch is half as hard there (1.5 kN against 3.0 kN) and its finest-level
# ratio (2.8) stays under confirm_ratio (3) in the episode's first revolution.
LATE_FIRST_TOUCH = {"db4"}


@pytest.fixture(scope="module")
def simulated():
    rig = load_rig()
    return [simulate_case(SUITE / name, rig) for name in THESIS_SUBSET]


@pytest.mark.parametrize("wavelet", ["haar", "db2", "db4"])
def test_thesis_cases_detected_and_classified_with_each_wavelet(simulated, wavelet):
    results = [run_case(case, wavelet) for case in simulated]
    wrong = {
        r.name
        for r in results
        if r.false_alarms or any(m["predicted"] != m["expected"] for m in r.matches)
    }
    assert wrong == KNOWN[wavelet], [(r.name, r.matches, r.false_alarms) for r in results]
    kept = [r for r in results if r.name not in KNOWN[wavelet]]
    expected = {"MASS_LOSS": 0, "AUX_BEARING_CONTACT": 0}
    for case in simulated:
        if case.name not in KNOWN[wavelet]:
            for e in case.expect:
                expected[e.fault.name] += 1
    summary = summarise(kept)
    conf = summary["confusion"]
    for cls, n in expected.items():
        assert conf[cls][cls] == n, (cls, conf[cls])
        assert sum(conf[cls].values()) == n
    assert summary["correct"] == summary["total"] == sum(expected.values())
    assert summary["false_alarms"] == 0, [r.false_alarms for r in results if r.false_alarms]
    assert summary["before_calibration"] == 0
    # mass loss: detected within one revolution of the true onset (issue 5)
    assert 0 <= summary["delays"]["MASS_LOSS"]["detection_revs_max"] < 1.0
    # and its onset within one finest-level support (issue 5; the back-dating to the support's
    # first sample narrowed by later crossings gave 1.12 supports with db4 at 67 Hz)
    assert summary["delays"]["MASS_LOSS"]["onset_error_abs_supports_max"] <= 1.0
    # the first touch of the 430 g cm loss, 0.5 revolution after it and inside its ring-down,
    # is found within a quarter revolution (issue 5 contact target; was 0.9 rev with haar,
    # missed with db2, 4.9 rev with db4)
    (ml,) = [r for r in results if r.name == "mass_loss_67hz_430gcm_250"]
    contact = next(m for m in ml.matches if m["expected"] == "AUX_BEARING_CONTACT")
    assert contact["predicted"] == "AUX_BEARING_CONTACT"
    if wavelet in LATE_FIRST_TOUCH:
        assert contact["detection_delay_revs"] >= 0.25  # known: see LATE_FIRST_TOUCH
    else:
        assert 0 <= contact["detection_delay_revs"] < 0.25
    # the first touch of the 430 g cm loss at 28.65 Hz, with the bearing force cycling to its
    # limit for 3 revolutions before it, found within a quarter revolution as well
    (ml,) = [r for r in results if r.name == "mass_loss_29hz_430gcm_000"]
    contact = next(m for m in ml.matches if m["expected"] == "AUX_BEARING_CONTACT")
    assert contact["predicted"] == "AUX_BEARING_CONTACT"
    assert 0 <= contact["detection_delay_revs"] < 0.25


def test_each_case_touches_exactly_when_its_file_expects_a_contact(simulated):
    # the scenario files' contact expectations against the simulator's truth on this rig model
    for case in simulated:
        timed = [e.time for e in case.expect if e.time is not None]
        after = max(timed) if timed else 0.0
        touches = bool((case.block.truth["contact"].any(axis=1) & (case.block.time >= after)).any())
        expects = any(e.source == "contact" for e in case.expect)
        assert touches == expects, case.name
