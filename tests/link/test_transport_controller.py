"""DxlClient against the snakebot controller, whose Status Return Level is not where a
servo's is (its address 16 is Speed Scale): the client learns where from the device.

The controller's real C device logic (snakebot._core) runs behind a real pseudo-terminal.
"""

from snakebot.facts import devices
from snakebot.link.controller import load
from snakebot.link.controller.client import ControllerClient
from snakebot.link.transport import DxlClient
from snakebot.sim.controller_pty import ControllerPty

CONTROLLER_ID = 200


def test_a_controller_register_at_address_16_is_not_taken_for_status_return_level():
    speed_scale = load().register("Speed Scale")
    # the clash this test is about
    assert speed_scale.address == devices.ax12().status_return_level_address
    with (
        ControllerPty(robot="snake5") as server,
        DxlClient(server.device, 57600, echo=False, device=devices.controller()) as client,
    ):
        client.write_u16(CONTROLLER_ID, speed_scale.address, 1)  # 1/256 x: low byte 1
        # Still treated as answering everything: the READ is sent and answered.
        assert client.read_u16(CONTROLLER_ID, speed_scale.address) == 1
        assert client.status_return_level(CONTROLLER_ID) == 2


def test_the_controller_client_does_not_track_address_16():
    with ControllerPty(robot="snake5") as server, ControllerClient.open(server.device) as ctl:
        ctl.link.write_u16(CONTROLLER_ID, load().register("Speed Scale").address, 1)
        assert ctl.link.status_return_level(CONTROLLER_ID) == 2
        assert ctl.read_block(16, 2) == b"\x01\x00"


def test_the_controller_client_tracks_the_controllers_own_status_return_level():
    level = load().register("Status Return Level")
    with ControllerPty(robot="snake5") as server, ControllerClient.open(server.device) as ctl:
        ctl.link.write(CONTROLLER_ID, level.address, bytes([1]))  # answer PING and READ only
        assert ctl.link.status_return_level(CONTROLLER_ID) == 1
        assert ctl.link.read(CONTROLLER_ID, level.address, 1) == bytes([1])
        ctl.link.write(CONTROLLER_ID, level.address, bytes([2]))  # sent without a reply
        assert ctl.link.status_return_level(CONTROLLER_ID) == 2
        assert ctl.link.read(CONTROLLER_ID, level.address, 1) == bytes([2])
