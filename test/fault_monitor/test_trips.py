"""Trip levels: 1 x amplitude against closed-form orbits, hysteresis, clearance defaults."""

import numpy as np
import pytest

from amb_common.faults import FaultType
from amb_common.rig import load_rig
from amb_fault_monitor.errors import FaultMonitorError
from amb_fault_monitor.trips import PlaneTrips, SynchronousAmplitude, TripMonitor, clearance_levels

SPR = 32


def _feed(amp: SynchronousAmplitude, xy: np.ndarray, theta: np.ndarray) -> np.ndarray:
    out = np.zeros(4)
    for i in range(len(theta)):
        out = amp.step(xy[i], theta[i])
    return out


@pytest.mark.parametrize("phase", [0.0, 0.7, 2.5])
def test_one_x_amplitude_of_circle_line_and_ellipse(phase):
    n = 3 * SPR
    theta = 2 * np.pi * np.arange(n) / SPR
    xy = np.zeros((n, 8))
    xy[:, 0], xy[:, 1] = 30e-6 * np.cos(theta + phase), 30e-6 * np.sin(theta + phase)  # circle
    xy[:, 2] = 20e-6 * np.cos(theta + phase)  # line along x
    # ellipse 40 x 10 um tilted by 0.3 rad, plus a 2 x component and an offset (rejected)
    u, v = 40e-6 * np.cos(theta + phase), 10e-6 * np.sin(theta + phase)
    xy[:, 4] = np.cos(0.3) * u - np.sin(0.3) * v + 5e-6 * np.cos(2 * theta) + 50e-6
    xy[:, 5] = np.sin(0.3) * u + np.cos(0.3) * v - 80e-6
    # backward whirl of radius 7 um
    xy[:, 6], xy[:, 7] = 7e-6 * np.cos(theta + phase), -7e-6 * np.sin(theta + phase)
    a = _feed(SynchronousAmplitude(SPR), xy, theta % (2 * np.pi))
    np.testing.assert_allclose(a, [30e-6, 20e-6, 40e-6, 7e-6], rtol=1e-9, atol=1e-15)


@pytest.mark.parametrize("start", [0, 5, 13])
def test_one_x_window_slides_over_an_amplitude_step(start):
    """Forward circles of 30 um, then 10 um from sample ``3 * SPR + start``.

    With half a revolution of each in the window, ``X = (A1 + A2) / 2`` (the half-revolution
    sums of ``exp(-2 i theta)`` vanish), so the semi-major axis is 20 um; one revolution after
    the step it is 10 um. Starting mid-revolution exercises the running sum across the
    once-per-revolution recomputation.
    """
    step = 3 * SPR + start
    n = step + SPR
    theta = 2 * np.pi * np.arange(n) / SPR
    radius = np.where(np.arange(n) < step, 30e-6, 10e-6)
    xy = np.zeros((n, 8))
    xy[:, 0], xy[:, 1] = radius * np.cos(theta), radius * np.sin(theta)
    amp = SynchronousAmplitude(SPR)
    half = _feed(amp, xy[: step + SPR // 2], theta[: step + SPR // 2] % (2 * np.pi))
    np.testing.assert_allclose(half[0], 20e-6, rtol=1e-9)
    full = _feed(amp, xy[step + SPR // 2 :], theta[step + SPR // 2 :] % (2 * np.pi))
    np.testing.assert_allclose(full[0], 10e-6, rtol=1e-9)


def test_not_ready_before_one_revolution():
    amp = SynchronousAmplitude(SPR)
    assert not amp.ready
    out = amp.step(np.ones(8), 0.0)
    assert np.all(out == 0) and not amp.ready


def test_hysteresis_trips_and_clears():
    trip = TripMonitor([10.0, 10.0, 0.0, 5.0], hysteresis=0.2)
    assert list(trip.update([11.0, 9.0, 100.0, 4.0])[0]) == [0]  # plane 3 is off
    assert list(trip.update([8.5, 9.0, 0.0, 4.0])[1]) == []  # 8.5 > 10 * 0.8: still tripped
    assert trip.tripped[0]
    assert list(trip.update([7.9, 9.0, 0.0, 6.0])[1]) == [0]
    assert list(np.flatnonzero(trip.tripped)) == [3]
    assert trip.peak[0] == 11.0


def test_plane_trips_raise_one_event_per_trip_the_1x_only_after_a_revolution():
    # plane 2 whirls on a 30 um circle from the start: displacement 30 um every sample (closed
    # form), 1 x amplitude 30 um once a revolution is in the window
    omega = 2 * np.pi * 20.0
    trips = PlaneTrips([50e-6, 25e-6, 50e-6, 50e-6], 20e-6, 0.1, SPR)
    events = []
    for n in range(2 * SPR):
        theta = 2 * np.pi * n / SPR
        d = np.zeros(8)
        d[2], d[3] = 30e-6 * np.cos(theta), 30e-6 * np.sin(theta)
        events += [(n, ev) for ev in trips.step(n, d, theta, omega)]
    (n0, disp), (n1, one_x) = events  # one each: a tripped plane stays tripped, no repeat
    assert n0 == 0 and n1 == SPR - 1  # the window is full at the revolution's last sample
    for ev, quantity, level in ((disp, "displacement", 25e-6), (one_x, "1x", 20e-6)):
        assert ev.fault_type == FaultType.TRIP and ev.plane == 2
        assert ev.onset_sample_index == ev.detection_sample_index == ev.decision_sample_index
        assert ev.samples_per_rev == SPR and ev.omega == omega
        assert ev.severity == pytest.approx(30e-6, rel=1e-9)
        assert ev.evidence == {"quantity": quantity, "trip_level_m": level, "value_m": ev.severity}
    assert list(np.flatnonzero(trips.displacement.tripped)) == [1]
    assert list(np.flatnonzero(trips.amplitude.tripped)) == [1]
    trips.set_hysteresis(0.5)
    assert trips.displacement.hysteresis == trips.amplitude.hysteresis == 0.5
    with pytest.raises(FaultMonitorError, match="hysteresis"):
        trips.set_hysteresis(1.0)


def test_clearance_levels_from_rig_file():
    rig = load_rig()
    levels = clearance_levels(rig, 2.0 / 3.0)
    # nearest clearance bearing by axial position, read here independently of the function
    expected = []
    for p in rig.sensor_planes:
        c = min(rig.clearance_bearings, key=lambda c: abs(c.z - p.z))
        expected.append(2.0 / 3.0 * c.radial_clearance)
    np.testing.assert_allclose(levels, expected)
    assert np.all(levels > 0)


@pytest.mark.parametrize(
    ("call", "match"),
    [(lambda: TripMonitor(-1.0), ">= 0"), (lambda: TripMonitor(1.0, 1.0), "hysteresis"),
     (lambda: clearance_levels(load_rig(), 0.0), "fraction"),
     (lambda: SynchronousAmplitude(SPR).step(np.zeros(6), 0.0), "shape")],
)  # fmt: skip
def test_errors(call, match):
    with pytest.raises(FaultMonitorError, match=match):
        call()
