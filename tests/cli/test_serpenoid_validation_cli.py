"""`snakebot serpenoid` refuses what `gait serpenoid` refuses (the same check), before
anything is sent; without --robot the controller's own refusal is explained. Against the
controller's real C device logic on a pty (ControllerPty)."""

from __future__ import annotations

from controller_cli_support import cli, controller  # noqa: F401 - the fixture

from snakebot.link.controller.client import ControllerClient
from snakebot.link.controller.playback import roster_from_robot
from snakebot.model.robots import load_robot

ISSUE = ["-A", "80deg", "-w", "10", "-d", "60deg", "--offset", "30deg"]


def test_the_issue_reproduction_exits_2_and_sends_nothing(controller, tmp_path):  # noqa: F811
    result = cli("serpenoid", "--port", controller.device, "--robot", "snake5", *ISSUE)
    assert result.exit_code == 2
    line = result.output.strip()
    assert "\n" not in line and line.startswith("error: the serpenoid is outside snake5's")
    # A omega = 14 rad/s from t = 0, and A + offset = 110 deg past the 90 deg maximum
    assert "moves at 13.96 rad/s at t = 0.000 s" in line and "more violations" in line
    assert line.endswith("nothing was sent")
    assert controller.host_packets == []
    # the same wave is refused by `gait serpenoid`, by the same check
    gait = cli(
        "gait", "serpenoid", "snake5", *ISSUE, "--cycles", "1", "-o", str(tmp_path / "s.gait")
    )
    assert gait.exit_code == 2 and "is outside snake5's limits" in gait.output


def test_a_wave_too_fast_at_the_speed_factor_is_refused(controller):  # noqa: F811
    result = cli(
        "serpenoid", "--port", controller.device, "--robot", "snake5",
        "-A", "0.5", "-w", "10", "-d", "1", "--speed", "1.5",
    )  # fmt: skip
    assert result.exit_code == 2
    # 0.5 rad * 10 rad/s = 5 rad/s is within the servo's 6.18; 1.5x of it is not
    assert "moves at 7.50 rad/s" in result.output
    assert "above the AX-12A's maximum of 6.18 rad/s" in result.output
    assert controller.host_packets == []


def test_without_robot_the_controller_refusal_is_explained(controller):  # noqa: F811
    with ControllerClient.open(controller.device) as ctl:
        ctl.set_roster(roster_from_robot(load_robot("snake5")))
    result = cli("serpenoid", "--port", controller.device, *ISSUE)
    assert result.exit_code == 2
    assert "refused SERPENOID (Refusal Reason AMPLITUDE)" in result.output
    assert "lower the amplitude or the offset" in result.output
    assert result.output.startswith("error: --amplitude, --offset, --steer: ")
