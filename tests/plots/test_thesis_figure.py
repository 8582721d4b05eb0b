"""A thesis run's figure as a grid a laptop screen shows whole (issue #33): every state
in its own panel with its unit, both worlds in each, one legend below them."""

from __future__ import annotations

import re

import pytest

from snakebot.workflows.thesis import RUNS, run_thesis

pytest.importorskip("matplotlib")


def test_the_thesis_figure_is_a_readable_grid_with_units():
    from snakebot.plots.thesis import GRID_COLUMNS, thesis_figure

    run = next(r for r in RUNS if r.name == "g1")
    result = run_thesis(run, worlds=("kinematic",))
    fig = thesis_figure(result)
    fig.canvas.draw()
    width, height = fig.get_size_inches() * 90  # as saved
    assert width <= 1400 and height <= 900  # fits a laptop's screen (was 2160 x 324)
    shown = [ax for ax in fig.axes if ax.get_visible()]
    states = 3 + result.robot.n_joints
    assert len(shown) == states and len(fig.axes) % GRID_COLUMNS == 0
    for ax in shown:
        assert re.search(r"\((m|u|rad)\)$", ax.get_ylabel()), ax.get_ylabel()
        assert [line.get_label() for line in ax.get_lines()][0] == "kinematic"
    assert shown[0].get_ylabel() == f"x ({result.robot.length_unit})"
    assert sum(1 for ax in shown if ax.get_xlabel() == "t (s)") == min(states, GRID_COLUMNS)
    (legend,) = fig.legends
    assert all(not legend.get_window_extent().overlaps(ax.get_window_extent()) for ax in shown)
