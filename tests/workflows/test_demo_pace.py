"""The demo's verdict when the host disturbs the emulator's pace (issue #29): the pace is
measured from the goals the firmware sent, and a difference beyond the tolerance on a
disturbed pace is INVALID, not a disagreement. The goal streams are a real serpenoid
table played as the firmware plays it: steadily, or stopped for 0.4 s and then leaping
ahead, as when the host deschedules QEMU."""

from __future__ import annotations

import math

import numpy as np
import pytest

from snakebot.model.compare import JointTrack
from snakebot.model.gait.serpenoid import serpenoid
from snakebot.model.robots import load_robot
from snakebot.workflows.demo import (
    LEAP_LIMIT_FRAMES,
    STILL_LIMIT_S,
    Comparison,
    Pacing,
    commanded,
    pacing,
    table_phase,
    verdict_line,
)

SNAKE5 = load_robot("snake5")
SAMPLE_S = 0.01  # the goal log's period
FRAME_S = 0.02


def goals_played(stall_s: float, leap_frames: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(table angles, sample times, goals) of two cycles played at the table's pace, with
    the goals standing still ``stall_s`` from 1.5 s on and then ``leap_frames`` ahead."""
    gait = serpenoid(SNAKE5, math.radians(30), math.pi, math.pi / 2, cycles=1, rate_hz=50)
    angles = SNAKE5.ticks_to_angles(gait.ticks.astype(float))
    t = np.arange(0.0, 4.0 + stall_s, SAMPLE_S)
    phase = np.where(t < 1.5, t, np.where(t < 1.5 + stall_s, 1.5, t - stall_s)) / FRAME_S
    phase[t >= 1.5 + stall_s] += leap_frames
    return angles, t, commanded(angles, phase)


@pytest.mark.parametrize(("stall_s", "leap"), [(0.0, 0.0), (0.4, 0.0), (0.0, 9.0), (0.4, 9.0)])
def test_the_pace_is_measured_from_the_goals_sent(stall_s, leap):
    angles, t, goals = goals_played(stall_s, leap)
    phase_t, phase = table_phase(angles, t, goals)
    pace = pacing(phase_t, phase, 0.5, 3.5)
    assert pace.still_s == pytest.approx(max(stall_s, SAMPLE_S), abs=0.015)
    assert leap <= pace.leap_frames <= leap + SAMPLE_S / FRAME_S + 0.01  # a sample: half a frame
    assert pace.steady == (stall_s <= STILL_LIMIT_S and leap <= LEAP_LIMIT_FRAMES)


def comparison(difference_m: float, pace: Pacing) -> Comparison:
    motion = {"dx": 1.0, "dy": 0.0, "distance": 1.0, "direction_deg": 0.0, "turn_deg": 0.0}
    t = np.zeros(1)
    return Comparison(
        emulated=motion,
        predicted=motion,
        predicted_lagged=motion,
        difference_m=difference_m,
        lag_s=0.02,
        residual_max_rad=0.01,
        lag_effect_m=0.01,
        sensitivity_m_per_rad=1.0,
        tolerance_m=0.03,
        playback_rate=1.0,
        window_s=(0.0, 1.0),
        emulated_path=np.zeros((1, 3)),
        predicted_path=np.zeros((1, 3)),
        joints=JointTrack(t, ("a",), t[:, None], t[:, None]),
        pace=pace,
    )


STEADY = Pacing(still_s=0.02, leap_frames=1.0)
DISTURBED = Pacing(still_s=0.4, leap_frames=9.0)


def test_beyond_the_tolerance_on_a_disturbed_pace_is_invalid_not_a_disagreement():
    c = comparison(0.05, DISTURBED)
    assert c.verdict == "INVALID" and c.as_dict()["verdict"] == "INVALID"
    line = verdict_line(c)
    assert line.startswith("5. verdict: INVALID (the host did not give the emulator steady time")
    assert "stood still 400 ms" in line and "leapt 9.0 frames" in line
    assert "rerun on an idle machine" in line and "AGREE" not in line
    assert comparison(0.05, STEADY).verdict == "DISAGREE"
    starved = comparison(0.05, Pacing(still_s=0.02, leap_frames=1.0, rate=0.55))
    assert starved.verdict == "INVALID" and "came at 0.55x wall-clock speed" in verdict_line(
        starved
    )


def test_within_the_tolerance_the_verdict_stands_and_the_pace_is_reported():
    c = comparison(0.01, DISTURBED)
    assert c.verdict == "AGREE"
    assert c.pace.line().startswith("   pace: disturbed by the host")
    assert comparison(0.01, STEADY).pace.line().startswith("   pace: steady")


@pytest.mark.parametrize(
    ("still_s", "steady"), [(STILL_LIMIT_S + 0.0004, True), (STILL_LIMIT_S + 0.0006, False)]
)
def test_the_pace_is_judged_on_the_figures_it_reports(still_s, steady):
    """A stand-still that the report rounds to the limit is within it: the verdict never
    contradicts the figures printed beside it (a busy run once reported 0.1 s still,
    limit 0.1 s, and called itself disturbed)."""
    pace = Pacing(still_s=still_s, leap_frames=1.004, rate=0.70004)
    shown = pace.as_dict()
    assert pace.steady == steady
    assert shown["steady"] == (
        shown["still_s"] <= shown["still_limit_s"]
        and shown["leap_frames"] <= shown["leap_limit_frames"]
        and shown["rate"] >= shown["rate_floor"]
    )
    assert (shown["leap_frames"], shown["rate"]) == (1.0, 0.7)
