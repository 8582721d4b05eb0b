"""`snakebot upload` of tables larger than 2 KB against the controller's real C device
logic behind a pty, laid out as the CM-530 (Table Capacity 32 KB in a 48 KB arena): a
20 KB table uploads and plays; an upload while it plays would land on it and is refused
with one line saying to stop first, the table playing on untouched; stopped, it goes."""

from __future__ import annotations

from controller_cli_support import cli, controller, save, wave_table  # noqa: F401

from snakebot.sim.controller_pty import TABLE_ARENA, TABLE_CAPACITY


def test_an_upload_onto_the_playing_table_is_refused_until_playback_stops(controller, tmp_path):  # noqa: F811
    frames = 2500  # 4 joints: 20 040 bytes, past the 16 KB the arena leaves beside a table
    big = save(wave_table(frames=frames), tmp_path, "big.gait")
    assert TABLE_ARENA - TABLE_CAPACITY < big.stat().st_size <= TABLE_CAPACITY
    small = save(wave_table(frames=100), tmp_path, "small.gait")
    port = ("--port", controller.device)
    assert cli("upload", big, *port).exit_code == 0
    assert controller.active_table() == big.read_bytes()
    assert cli("play", *port).exit_code == 0

    result = cli("upload", small, *port)
    assert result.exit_code == 1
    assert result.stderr.count("\n") == 1 and result.stderr.startswith("error: ")
    assert "would land on the table playing" in result.stderr
    assert "stop playback (`snakebot stop`), then upload again" in result.stderr
    assert controller.active_table() == big.read_bytes()

    assert cli("stop", *port).exit_code == 0
    assert cli("upload", small, *port).exit_code == 0
    assert controller.active_table() == small.read_bytes()
