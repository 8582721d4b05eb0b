"""The physics world wherever a world is chosen: `sim predict --world`, `sim://...&world=`,
and the errors for robots and options it cannot use."""

from __future__ import annotations

import dataclasses
import json

import pytest
from click.testing import CliRunner
from physics_support import snake5_serpenoid_file
from realtime import ordinary_priority

from snakebot.cli import main
from snakebot.link.transport import DxlClient
from snakebot.model.robots import load_robot

pytest.importorskip("mujoco")

SNAKE5 = load_robot("snake5")


@pytest.fixture(scope="module")
def gait_file(tmp_path_factory):
    return snake5_serpenoid_file(tmp_path_factory.mktemp("gait"))


def predict_json(*args):
    result = CliRunner().invoke(main, ["sim", "predict", *args, "--json"])
    assert result.exit_code == 0, result.output
    return json.loads(result.output)


def test_predict_json_keeps_its_keys_and_adds_the_world_and_the_physics(gait_file):
    kinematic = predict_json(str(gait_file), "--robot", "snake5")
    physics = predict_json(str(gait_file), "--robot", "snake5", "--world", "mujoco")
    assert kinematic["world"] == "kinematic" and physics["world"] == "mujoco"
    assert set(kinematic) <= set(physics)
    assert set(kinematic["emulated"]) <= set(physics["emulated"])
    em = physics["emulated"]
    assert len(em["wheel_slip_speed_max"]) == len(em["slip_distance"]) == SNAKE5.n_wheels
    assert len(em["work_j"]) == len(em["electrical_j"]) == len(em["peak_load"]) == SNAKE5.n_joints
    # both worlds take the robot file's one friction description
    assert em["mu"] == SNAKE5.friction.lateral
    same = dataclasses.asdict(SNAKE5.friction)
    assert em["friction"] == kinematic["predicted"]["friction"] == same
    # a different world, a different body path: the physics is not the model again
    assert physics["emulated"]["dx"] != pytest.approx(kinematic["emulated"]["dx"], rel=1e-3)


def test_predict_mu_changes_the_physics(gait_file):
    slippery = predict_json(str(gait_file), "--world", "mujoco", "--mu", "0.05")
    assert slippery["emulated"]["mu"] == 0.05
    assert sum(slippery["emulated"]["slip_distance"]) > 0.01


def test_ideal_servos_are_refused_in_the_physics_world(gait_file):
    result = CliRunner().invoke(
        main, ["sim", "predict", str(gait_file), "--world", "mujoco", "--ideal"]
    )
    assert result.exit_code == 2
    assert result.output.startswith("error: --ideal, --world: ideal servos have no torque")


def test_a_robot_file_without_physics_is_refused_naming_the_key(gait_file, tmp_path):
    from importlib import resources

    text = resources.files("snakebot.model.robots").joinpath("snake5.toml").read_text()
    bare = tmp_path / "bare.toml"
    bare.write_text(text.split("[physics]")[0])
    result = CliRunner().invoke(
        main, ["sim", "predict", str(gait_file), "--robot", str(bare), "--world", "mujoco"]
    )
    assert result.exit_code == 2
    assert "key 'physics' is missing" in result.output
    assert result.output.count("\n") == 1 and "Traceback" not in result.output


def test_sim_url_world_option_lets_the_physics_move_the_servos():
    with DxlClient("sim://?robot=snake5&world=mujoco", echo=False) as client:
        bus = client.port.bus
        client.write_u16(10, 30, 700)
        bus.run_until(bus.now + 0.1)
        assert 0 < client.read_u16(10, 38) & 1023  # Present Speed: on its way
        assert 0 < client.read_u16(10, 40) & 1023  # Present Load: it takes torque
        bus.run_until(bus.now + 1.5)
        assert abs(client.read_u16(10, 36) - 700) <= 2


@pytest.mark.parametrize(
    ("query", "message"),
    [
        ("ids=1&world=mujoco", "world=mujoco needs the robot's body"),
        ("robot=snake5&world=rigid", "unknown world 'rigid'"),
        ("robot=snake5&world=mujoco&ideal=1", "ideal servos have no torque"),
    ],
)
def test_sim_url_world_option_errors(query, message):
    with pytest.raises(Exception, match=message):
        DxlClient(f"sim://?{query}", echo=False)


SDK_TRIES = 3
"""How often the dynamixel-sdk test asks for a reading before it counts as unanswered."""


@pytest.mark.serial  # the SDK's reply deadline counts on the pty server keeping pace
def test_dynamixel_sdk_over_a_pty_reads_the_physics(tmp_path):
    """`sim bus --world mujoco` in real time: a third-party client sees the servo move
    with the physics (speed and load on the way, at the goal afterwards)."""
    import signal
    import subprocess
    import sys
    import time

    import dynamixel_sdk as sdk

    proc = subprocess.Popen(
        [sys.executable, "-m", "snakebot", "sim", "bus", "--robot", "snake5"]
        + ["--world", "mujoco", "--return-delay", "0", "--json"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        info = json.loads(proc.stdout.readline())
        assert "world=mujoco" in info["url"]
        port = sdk.PortHandler(info["device"])
        assert port.openPort() and port.setBaudRate(1_000_000)
        ph = sdk.PacketHandler(1.0)
        try:

            def read(address: int) -> int:
                # The SDK waits a few milliseconds for a reply; on a loaded host the
                # server's may come after that, and a client then asks again.
                for _ in range(SDK_TRIES):
                    value, result, error = ph.read2ByteTxRx(port, 10, address)
                    if result == sdk.COMM_SUCCESS:
                        assert error == 0
                        return value
                raise AssertionError(f"no reply to READ {address} in {SDK_TRIES} tries")

            with ordinary_priority():  # the SDK polls; the server keeps its class
                result, error = ph.write2ByteTxRx(port, 10, 30, 700)
                assert result == sdk.COMM_SUCCESS and error == 0
                time.sleep(0.1)
                speed, load = read(38), read(40)
                assert speed & 1023 > 100 and load & 1023 > 0
                time.sleep(1.5)
                assert abs(read(36) - 700) <= 2
        finally:
            port.closePort()
        proc.send_signal(signal.SIGINT)
        assert proc.wait(timeout=10) == 130
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        proc.stdout.close()
        proc.stderr.close()
