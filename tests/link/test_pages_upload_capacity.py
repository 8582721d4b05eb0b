"""`snakebot upload` reads the controller's Table Capacity (Program page) and refuses a
table its board cannot hold before the commit (the READ travels with the first chunks):
exit 2, the capacity named, nothing committed. Against the controller's real C device
logic behind a pty, told a smaller board capacity."""

from __future__ import annotations

from controller_cli_support import cli, controller, save, wave_table  # noqa: F401

from snakebot.core import lib
from snakebot.sim.controller_pty import is_commit


def test_a_table_beyond_the_board_capacity_is_refused_before_the_commit(controller, tmp_path):  # noqa: F811
    path = save(wave_table(frames=200), tmp_path)
    size = path.stat().st_size
    capacity = size - 1
    lib.ctl_set_capacity(controller.device_logic.d, capacity)
    result = cli("upload", path, "--port", controller.device)
    assert result.exit_code == 2
    assert result.stderr.count("\n") == 1 and result.stderr.startswith("error: ")
    assert f"{size} bytes but the controller holds at most {capacity}" in result.stderr
    assert not [p for p in controller.host_packets if is_commit(p)]
    assert controller.active_table() == b""  # it had none, and still has none
    # at the size of the table it goes through
    lib.ctl_set_capacity(controller.device_logic.d, size)
    assert cli("upload", path, "--port", controller.device).exit_code == 0
    assert controller.active_table() == path.read_bytes()
