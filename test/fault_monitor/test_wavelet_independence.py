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
- a bearing contact at 67 Hz and one at 29 Hz (figures 5.4-5.6, 5.16-5.18);
- 430 g cm losses at 18 and 29 Hz (figures 5.7-5.12);
- the 516 g cm loss at 19 Hz, figure 5.27 case 1.
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
    "mass_loss_18hz_430gcm_000.yaml",
    "mass_loss_29hz_430gcm_000.yaml",
    "mass_loss_19hz_case1_fig5_27.yaml",
)
EXPECTED = {"MASS_LOSS": 4, "AUX_BEARING_CONTACT": 3}


@pytest.fixture(scope="module")
def simulated():
    rig = load_rig()
    return [simulate_case(SUITE / name, rig) for name in THESIS_SUBSET]


@pytest.mark.parametrize("wavelet", ["haar", "db2", "db4"])
def test_thesis_cases_detected_and_classified_with_each_wavelet(simulated, wavelet):
    results = [run_case(case, wavelet) for case in simulated]
    summary = summarise(results)
    conf = summary["confusion"]
    for cls, n in EXPECTED.items():
        assert conf[cls][cls] == n, (cls, conf[cls])
        assert sum(conf[cls].values()) == n
    assert summary["correct"] == summary["total"] == sum(EXPECTED.values())
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
    assert 0 <= contact["detection_delay_revs"] < 0.25
