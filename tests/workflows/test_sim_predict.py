"""`snakebot sim predict`: a gait table played onto the virtual servos with the host as
bus master, the world's body path beside the prediction from the same table."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from click.testing import CliRunner

from snakebot.cli import main
from snakebot.formats.gaittable import GaitTable, write_gait
from snakebot.model.gait import serpenoid
from snakebot.model.plan import PlanRequest, make_plan
from snakebot.model.robots import TICKS_PER_RAD, load_robot
from snakebot.workflows import predict as predict_module
from snakebot.workflows.predict import (
    REST_MAX_S,
    REST_TICKS,
    PredictError,
    player_writes,
    predict_gait,
)

FIVE_LINK = load_robot("snake5")


def run(*args):
    return CliRunner().invoke(main, [str(a) for a in args], catch_exceptions=False)


@pytest.fixture(scope="module")
def s5_gait():
    """A 5-link serpenoid: one cycle of 2 s, 50 frames a second, looping."""
    return serpenoid(FIVE_LINK, math.radians(30), math.pi, math.pi / 2, cycles=1, rate_hz=50)


@pytest.fixture()
def s5_file(tmp_path, s5_gait):
    path = tmp_path / "s5.gait"
    write_gait(path, s5_gait.gait_table())
    return path


@pytest.mark.parametrize("batch", [7, 256])
def test_ideal_servos_reproduce_the_table_prediction_on_a_five_link_serpenoid(s5_gait, batch):
    result = predict_gait(s5_gait.gait_table(), "snake5", ideal=True, batch=batch)
    em, pr = result.emulated, result.predicted
    assert len(em.t) == 101 and em.t[-1] == pytest.approx(2.0)
    # every sample of the emulated path is the prediction's, to 1e-6
    assert np.abs(em.pose - pr.q[:, :3]).max() < 1e-6
    assert np.abs(result.joint_error).max() < 1e-12
    # ... and the end matches the gait's own `table` figure (made when it was generated)
    summary = result.summary()
    for key in ("dx", "dy", "dtheta"):
        assert summary["emulated"][key] == pytest.approx(s5_gait.table[key], abs=1e-6)
    assert summary["difference"]["path_max"] < 1e-6
    assert summary["emulated"]["dx"] > 0.2  # and it is not the trivial match of a still snake


def test_a_five_link_serpenoid_advances_on_modelled_servos_that_lag(s5_gait):
    result = predict_gait(s5_gait.gait_table(), "snake5")
    summary = result.summary()
    em, diff = summary["emulated"], summary["difference"]
    predicted_dx = s5_gait.table["dx"]
    assert em["dx"] > 0.8 * predicted_dx > 0.2  # forward along the start heading
    assert abs(em["dy"]) < 0.5 * em["dx"]
    # modelled servos lag their goals under the body's load: their drive needs an error to
    # give the torque the wheels' friction asks of the joints (4.6 deg here; MuJoCo's 6.0)
    assert math.radians(2) < diff["joint_max_rad"] < math.radians(8)
    assert diff["joint_rms_rad"] > 0
    assert 0 < diff["path_max"] < 0.05 * predicted_dx
    assert em["samples"] == 201  # 100 Hz world for 50 Hz frames
    assert em["rest_s"] == 0  # a loop goes on into its next pass: no holding to rest
    assert em["slip_max"] > 0 and len(em["slip_distance"]) == 5


def test_a_table_played_once_ends_where_the_loaded_servos_come_to_rest():
    """A plan's table ends held at its last frame; the servos, lagging it under the
    body's load, still move the body after the last goal, by more than the plan's
    tolerance: the emulated end is where they stop, as a robot (or `sim serve`'s,
    tests/firmware/test_program_fil.py) stops."""
    plan = make_plan(PlanRequest(load_robot("trident"), (0.5, 0.2, math.radians(10))))
    table = plan.gait.gait_table()
    result = predict_gait(table, plan.robot)
    em, rest = result.emulated, result.rest_samples
    assert result.summary()["emulated"]["rest_s"] == pytest.approx(rest * result.world_period_s)
    assert 0 < rest * result.world_period_s < REST_MAX_S
    at_table_end = em.pose[-1 - rest]
    moved_after = np.hypot(*(em.pose[-1, :2] - at_table_end[:2]))
    assert moved_after > plan.tolerance.position
    # at rest: the last period moved the joints a hundredth of a tick at most, the body a
    # thousandth of the tolerance
    assert np.abs(em.phi[-1] - em.phi[-2]).max() * TICKS_PER_RAD <= REST_TICKS
    last = em.pose[-1] - em.pose[-2]
    assert np.hypot(*last[:2]) < 1e-3 * plan.tolerance.position
    assert abs(last[2]) < 1e-3 * plan.tolerance.heading
    # the prediction holds the table's last frame while they come to rest
    held = result.predicted.q[-1 - rest :]
    assert np.array_equal(held, np.repeat(held[:1], rest + 1, axis=0))
    # ideal servos are on the last frame at once
    assert predict_gait(table, plan.robot, ideal=True).rest_samples == 0


def test_a_play_the_rest_cap_ends_says_so(tmp_path, monkeypatch):
    """Where REST_MAX_S ends a play before the servos stop, the end is not where the robot
    stops: the prediction and `sim predict` say so (a cap of one world period here; the
    trident's loaded servos take some 0.1 s to come to rest)."""
    plan = make_plan(PlanRequest(load_robot("trident"), (0.5, 0.2, math.radians(10))))
    table = plan.gait.gait_table()
    assert predict_gait(table, plan.robot).summary()["warnings"] == []
    monkeypatch.setattr(predict_module, "REST_MAX_S", 0.01)
    result = predict_gait(table, plan.robot)
    assert result.rest_samples == 1 and not result.rest.reached
    assert result.rest.moving > REST_TICKS
    (warning,) = result.summary()["warnings"]
    assert warning["kind"] == "not_at_rest" and warning["moving_ticks"] == result.rest.moving
    path = tmp_path / "plan.gait"
    write_gait(path, table)
    out = run("sim", "predict", path, "--robot", "trident")
    assert out.exit_code == 0, out.output
    assert "warning: the servos had not come to rest 0.01 s after the last goal" in out.stderr


def test_writes_are_the_controllers_player_tick_by_tick():
    frames = np.array([[500, 600], [510, 600], [530, 590]], dtype=np.uint16)
    limits = ((0, 1023), (0, 1023))
    tick, blocks = player_writes(GaitTable((1, 2), 20, True, limits, frames))
    assert tick == 0.01 and len(blocks) == 7  # 60 ms pass, ticks at 0, 10, .., 60 ms

    def decoded(block):
        return {sid: (int.from_bytes(b[:2], "little"), int.from_bytes(b[2:], "little"))
                for sid, b in block.items()}  # fmt: skip

    # frame 0 at 0 ms, half way to frame 1 at 10 ms (rounded), frame 1 at 20 ms, ...
    goals = [[decoded(b)[sid][0] for sid in (1, 2)] for b in blocks]
    assert goals == [[500, 600], [505, 600], [510, 600], [520, 595], [530, 590], [515, 595],
                     [500, 600]]  # fmt: skip
    # 10 ticks in 20 ms = 500 ticks/s = 220.2 units of 0.111 rpm, rounded up; a joint
    # that holds still gets the controller's floor (16), never 0 (= full speed)
    assert decoded(blocks[0]) == {1: (500, 221), 2: (600, 16)}
    once = player_writes(GaitTable((1, 2), 20, False, limits, frames))[1]
    assert len(once) == 5 and decoded(once[-1])[1][0] == 530


def test_a_three_link_serpenoid_crosses_its_singular_line_and_stays_finite():
    robot = load_robot("snake3")
    g = serpenoid(robot, math.radians(40), math.pi / 2, math.pi / 2, cycles=1, rate_hz=50)
    for ideal in (True, False):
        result = predict_gait(g.gait_table(), robot, ideal=ideal)
        gap = result.emulated.phi[:, 0] - result.emulated.phi[:, 1]
        assert gap.min() < 0 < gap.max()  # phi1 - phi2 changes sign: the line is crossed
        assert np.isfinite(result.emulated.pose).all()
        summary = result.summary()
        assert summary["emulated"]["dx"] > 0.5 * g.table["dx"] > 0


def test_table_that_is_not_for_this_robot_is_refused(s5_gait):
    with pytest.raises(PredictError, match="drives servos .10, 11, 15, 16. but snake3"):
        predict_gait(s5_gait.gait_table(), "snake3")


def test_table_without_metadata_needs_a_robot():
    table = GaitTable(
        FIVE_LINK.servo_ids, 20, True, FIVE_LINK.tick_limits, np.full((4, 4), 512, dtype=np.uint16)
    )
    with pytest.raises(PredictError, match="no metadata .* naming its robot: name it"):
        predict_gait(table)
    result = predict_gait(table, "snake5")
    assert result.summary()["emulated"]["dx"] == 0.0  # a table that holds still


def test_a_robot_that_does_not_load_is_said_to_be_the_gaits_only_when_it_is(tmp_path):
    moved = str(tmp_path / "my.toml")  # the gait's robot file, since moved away
    frames = np.full((4, 4), 512, dtype=np.uint16)
    table = GaitTable(
        FIVE_LINK.servo_ids, 20, True, FIVE_LINK.tick_limits, frames, {"robot_source": moved}
    )
    with pytest.raises(PredictError, match=f"the gait was made for robot '{moved}'"):
        predict_gait(table)
    with pytest.raises(PredictError, match="no robot 'snake4'") as asked:
        predict_gait(table, "snake4")
    assert "made for" not in str(asked.value) and asked.value.params == ("robot",)


def test_cli_json_report(s5_file, s5_gait):
    out = CliRunner().invoke(main, ["sim", "predict", str(s5_file), "--ideal", "--json"])
    assert out.exit_code == 0, out.output
    report = json.loads(out.output)
    assert report["gait"] == str(s5_file)
    assert report["robot"] == "snake5" and report["servos"] == "ideal"
    for part in ("emulated", "predicted", "difference"):
        assert set(report[part]) >= {"dx", "dy", "dtheta"}
    assert report["emulated"]["dx"] == pytest.approx(report["predicted"]["dx"], abs=1e-6)
    assert report["metadata_table"]["dx"] == pytest.approx(s5_gait.table["dx"])
    assert report["realtime_factor"] > 0
    assert "slip_max" in report["emulated"]


def test_cli_text_report_and_plot(s5_file, tmp_path):
    png = tmp_path / "run.png"
    out = CliRunner().invoke(main, ["sim", "predict", str(s5_file), "--plot", str(png)])
    assert out.exit_code == 0, out.output
    assert "emulated:" in out.output and "predicted:" in out.output
    assert "joint tracking error" in out.output and "faster than real time" in out.output
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_cli_wrong_robot_is_a_one_line_error(s5_file):
    out = CliRunner().invoke(main, ["sim", "predict", str(s5_file), "--robot", "trident"])
    assert out.exit_code == 2
    assert out.output.startswith("error: ") and "--robot" in out.output


def test_singular_crossing_is_crossed_alike_in_prediction_and_emulation(tmp_path):
    # The rounded table crosses phi1 = phi2 inadmissibly on one frame interval. The
    # quasi-static model needs no special case there: near the line the middle wheel
    # slides (the lateral forces no-slip rolling would need exceed friction), the outer
    # two do not, and prediction, emulation and the table's own figure agree.
    out = tmp_path / "s.gait"
    made = run(
        *("gait", "serpenoid", "snake3", "-A", "40deg", "-w", "3", "-d", "90deg"),
        *("--cycles", "1", "-o", out, "--json"),
    )
    assert made.exit_code == 0, made.output
    made_data = json.loads(made.output)
    table_figure = made_data["table"]
    assert any(w["kind"] == "near_singular" for w in made_data["warnings"])
    result = run("sim", "predict", out, "--ideal", "--json")
    assert result.exit_code == 0, result.output
    data = json.loads(result.output)
    em, pr = data["emulated"], data["predicted"]
    for key in ("dx", "dy", "dtheta"):
        assert pr[key] == pytest.approx(em[key], abs=1e-6)
        assert table_figure[key] == pytest.approx(pr[key], abs=1e-6)
    outer, middle = em["slip_distance"][0] + em["slip_distance"][2], em["slip_distance"][1]
    assert outer < 1e-9 < 0.01 < middle
    # the table's rounding moves the end by under 1 % of the continuous gait's motion
    # (4.83, 1.51)
    cont = made_data["predicted"]
    assert math.hypot(pr["dx"] - cont["dx"], pr["dy"] - cont["dy"]) < 0.01 * math.hypot(
        cont["dx"], cont["dy"]
    )
