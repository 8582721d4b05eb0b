"""`snakebot gait ...` from the command line: files written (or not), JSON, plots."""

import json
import math
from importlib import resources

import numpy as np
import pytest
from click.testing import CliRunner

from snakebot.cli import main
from snakebot.formats.gaittable import read_gait
from snakebot.model.robots import load_robot
from snakebot.model.robots.model import TICKS_PER_RAD


def run(*args):
    return CliRunner().invoke(main, [str(a) for a in args], catch_exceptions=False)


def test_serpenoid_writes_table_and_reports_both_predictions(tmp_path):
    out = tmp_path / "walk.gait"
    result = run(
        "gait",
        "serpenoid",
        "snake5",
        "--amplitude",
        "30deg",
        "--omega",
        "180deg",
        "--delta",
        "pi/2",
        "--cycles",
        "2",
        "--rate",
        "50",
        "-o",
        out,
        "--json",
    )
    assert result.exit_code == 0, result.output
    data = json.loads(result.output)
    assert set(data["predicted"]) == {"dx", "dy", "dtheta"}
    assert {"dx", "dy", "dtheta"} <= set(data["table"])
    assert data["parameters"]["amplitude_rad"] == math.radians(30)
    table = read_gait(out)
    assert table.frame_count == data["frames"] == 200 and table.loop
    assert table.metadata["gait"] == "serpenoid"
    assert (tmp_path / "walk.gait.json").is_file()


def test_field_bracket_gait_reports_the_second_order_prediction(tmp_path):
    out = tmp_path / "h1.gait"
    result = run(
        "gait",
        "field",
        "trident",
        "--field",
        "h1",
        "--periods",
        "2",
        "--amplitude",
        "0.05",
        "-o",
        out,
        "--json",
    )
    assert result.exit_code == 0, result.output
    data = json.loads(result.output)
    expected = 2 * math.pi * 0.05**2  # two loops of pi A^2 along h1 = (0, 0, 0, 1, 1, 1)
    assert data["second_order"]["q"][3] == pytest.approx(expected, rel=1e-12)
    assert abs(data["moved_q"][3] - expected) < 0.05 * expected


def test_limit_violation_writes_nothing(tmp_path):
    out = tmp_path / "fast.gait"
    result = run(
        "gait", "serpenoid", "snake5", "-A", "1", "-w", "10", "-d", "1", "--cycles", "1", "-o", out
    )
    assert result.exit_code == 2
    assert "error: the gait is outside snake5's limits: joint phi1 (servo 10)" in result.output
    assert "rad/s" in result.output and "no file was written" in result.output
    assert list(tmp_path.iterdir()) == []


def test_show_summarises_and_plots(tmp_path):
    out = tmp_path / "w.gait"
    run(
        "gait",
        "serpenoid",
        "snake3",
        "-A",
        "0.5",
        "-w",
        "2",
        "-d",
        "pi/2",
        "--cycles",
        "1",
        "-o",
        out,
    )
    result = run("gait", "show", out, "--plot", tmp_path / "w.png")
    assert result.exit_code == 0, result.output
    assert "serpenoid gait for snake3" in result.output and "continuous gait:" in result.output
    assert (tmp_path / "w.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    data = json.loads(run("gait", "show", out, "--json").output)
    assert data["robot"] == "snake3" and data["joint_ids"] == [1, 2]


def test_serpenoid_reproduces_the_thesis_example_with_its_own_phase(tmp_path):
    # phi1 = cos(-2 pi^2/3 t + pi^2), phi2 = cos(-2 pi^2/3 t - 2 pi^2), with cos x =
    # sin(x + pi/2). Its joints reach 6.6 rad/s, more than an AX-12's datasheet allows
    # (refused for an AX-12A): the robot is given a servo of its own with that speed.
    snake3 = resources.files("snakebot.model.robots").joinpath("snake3.toml").read_text()
    robot = tmp_path / "fast3.toml"
    robot.write_text(snake3.replace('model = "AX-12A"', 'model = "fast"\nmax_speed_rpm = 70'))
    out = tmp_path / "thesis.gait"
    result = run(
        "gait",
        "serpenoid",
        robot,
        *("-A", "1", "-w", "-2*pi**2/3", "-d", "-3*pi**2", "--phase", "pi**2+pi/2"),
        *("--cycles", "1", "-o", out, "--json"),
    )
    assert result.exit_code == 0, result.output
    data = json.loads(result.output)
    omega = data["parameters"]["omega_rad_s"]
    assert omega == pytest.approx(-2 * math.pi**2 / 3, rel=0.01)
    table = read_gait(out)
    t = np.arange(len(table.frames)) * table.frame_period_ms / 1000
    phi = np.c_[np.cos(omega * t + math.pi**2), np.cos(omega * t - 2 * math.pi**2)]
    angles = load_robot(robot).ticks_to_angles(table.frames)
    np.testing.assert_allclose(angles, phi, atol=1.0 / TICKS_PER_RAD)
    # The example moves the snake; the "pi" reading of its phase (antiphase) does not.
    assert math.hypot(data["predicted"]["dx"], data["predicted"]["dy"]) > 0.1


def test_near_singular_gaits_warn_in_text_and_json(tmp_path):
    # The trident driven by its joints is singular where its axles meet in a point,
    # e.g. near phi = (45, 60, -60) degrees.
    args = ("gait", "field", "trident", "--field", "g1", "--duration", "0.2")
    start = ("--start", "45deg,60deg,-60deg", "-o", tmp_path / "t.gait")
    data = json.loads(run(*args, *start, "--json").output)
    (warning,) = data["warnings"]
    assert warning["kind"] == "near_singular" and warning["trajectory"] == "table as written"
    assert warning["condition"] > 1 / warning["threshold_rcond"]
    text = CliRunner().invoke(main, [str(a) for a in (*args, *start)])
    assert text.exit_code == 0 and "warning: the table as written passes near a singular" in (
        text.stderr
    )
    # an ordinary 5-link serpenoid stays well clear
    far = run(
        *("gait", "serpenoid", "snake5", "-A", "30deg", "-w", "180deg", "-d", "90deg"),
        *("--cycles", "1", "-o", tmp_path / "s5.gait", "--json"),
    )
    assert json.loads(far.output)["warnings"] == []


def test_sim_predict_warns_on_the_singular_crossing(tmp_path):
    out = tmp_path / "s3.gait"
    run(*("gait", "serpenoid", "snake3", "-A", "40deg", "-w", "3", "-d", "90deg"),
        *("--cycles", "1", "-o", out))  # fmt: skip
    data = json.loads(run("sim", "predict", out, "--ideal", "--json").output)
    (warning,) = data["warnings"]
    # The quasi-static solve slides the middle wheel near phi1 = phi2, so the rows it
    # solves with are conditioned better than the no-slip rows (203 against over 1000),
    # still above the threshold's 100: the motion there hangs on friction and rounding.
    assert warning["condition"] > 1 / warning["threshold_rcond"]
    text = CliRunner().invoke(main, ["sim", "predict", str(out), "--ideal"])
    assert "warning: the prediction from the table passes near a singular" in text.stderr


def test_gait_plot_draws_time_series_beside_the_path(tmp_path):
    from matplotlib.image import imread

    png = tmp_path / "f.png"
    result = run(
        *("gait", "field", "trident", "--field", "g1", "--duration", "0.3"),
        *("-o", tmp_path / "f.gait", "--plot", png, "--json"),
    )
    assert result.exit_code == 0, result.output
    assert json.loads(result.output)["plot"] == str(png)
    # three panels (joints, x/y/theta against t, path) at 100 dpi
    assert imread(png).shape[:2] == (450, 1600)
    bare = read_gait(tmp_path / "f.gait")
    bare.metadata.clear()  # without the predicted motion only the joints are drawn
    from snakebot.plots.gait import plot_gait

    assert imread(plot_gait(bare, tmp_path / "bare.png")).shape[:2] == (450, 700)
