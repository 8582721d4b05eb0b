"""The demo's figure: every path it cites drawn, in metres, with the legend outside the
data (issue #33), from a comparison built of real predictions."""

from __future__ import annotations

import numpy as np
import pytest

from snakebot.model.compare import JointTrack
from snakebot.model.gait.serpenoid import serpenoid
from snakebot.model.robots import load_robot
from snakebot.workflows.demo import Comparison, predicted_motion

pytest.importorskip("matplotlib")

SNAKE5 = load_robot("snake5")


def comparison(free: bool) -> Comparison:
    gait = serpenoid(SNAKE5, np.radians(30), np.pi, np.pi / 2, cycles=1, rate_hz=50)
    angles = SNAKE5.ticks_to_angles(gait.ticks.astype(float))
    path = predicted_motion(SNAKE5, angles, gait.period_ms / 1000, 1, samples=101)
    lagged = predicted_motion(SNAKE5, angles, gait.period_ms / 1000, 1, 0.05, samples=101)
    t = np.linspace(0, 2, len(angles))
    return Comparison(
        emulated={"dx": 0.0},
        predicted={"dx": 0.0},
        difference_m=0.01,
        lag_s=0.05,
        # what the figure does not show
        **dict.fromkeys(("residual_max_rad", "lag_effect_m", "sensitivity_m_per_rad"), 0.0),
        **{"tolerance_m": 0.0, "playback_rate": 1.0, "window_s": (0.0, 2.0)},
        emulated_path=lagged,
        predicted_path=path,
        joints=JointTrack(t, tuple(j.name for j in SNAKE5.joints), angles, angles),
        physics={"difference_free_wheels_m": 0.02, "wheel_slide_m": [0.0] * 5} if free else None,
        free_wheel_path=0.9 * path if free else None,
    )


@pytest.mark.parametrize("free", [True, False])
def test_every_cited_path_is_drawn_in_metres_and_the_legend_covers_none(free):
    from snakebot.plots.demo import demo_figure

    c = comparison(free)
    fig = demo_figure(SNAKE5, c)
    fig.canvas.draw()
    ax = fig.axes[0]
    lines = {line.get_label(): line for line in ax.get_lines()}
    cited = {
        "predicted (table)": c.predicted_path,
        "emulated (the firmware playing it)": c.emulated_path,
    }
    if free:
        cited["predicted, free-rolling wheels"] = c.free_wheel_path
    assert set(cited) <= set(lines) and len(lines) == len(cited) + 1  # and the start
    unit = SNAKE5.physics.unit_m
    for label, path in cited.items():
        assert np.allclose(lines[label].get_xydata(), unit * path[:, :2])
    assert "(m," in ax.get_xlabel() and "(m," in ax.get_ylabel()
    for axes in fig.axes:  # the paths' legend and the joints': outside the data
        assert not axes.get_legend().get_window_extent().overlaps(axes.get_window_extent())
    assert {t.get_text() for t in ax.get_legend().get_texts()} == set(cited) | {"start"}
