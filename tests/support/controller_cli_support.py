"""Helpers for the controller command tests: gait tables on disk, the CLI run in
process, and the controller's real C device logic served on a pseudo-terminal."""

from __future__ import annotations

import json
import zlib
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner, Result

from snakebot.cli import main
from snakebot.formats.gaittable import GaitTable, write_gait
from snakebot.sim.controller_pty import ControllerPty, is_commit, is_upload_chunk

SNAKE5_IDS = (10, 11, 15, 16)
LIMITS = (200, 824)

# Replies come within milliseconds; the margin covers a loaded machine (the CLI and the
# device share one process here) so that no test counts on a retry it did not cause.
BASE_ENV = {"SNAKEBOT_MARGIN_MS": "200"}

QEMU_MARGIN_MS = "1000"
"""The margin instead for the tests marked ``qemu`` (tests/conftest.py): the firmware runs
in another process that QEMU paces in software, and one READ of a `limits set` went
unanswered past 200 ms, three tries in a row, while the package check built a wheel beside
the serial stage. None of those tests times a failure through :func:`cli`."""

# Quick retries: a cut-off line must fail in a second or two.
FAST_ENV = {"SNAKEBOT_UPLOAD_RETRIES": "1", "SNAKEBOT_RETRIES": "0"}


def constant_table(
    value: int, ids: tuple[int, ...] = SNAKE5_IDS, frames: int = 100, loop: bool = True
) -> GaitTable:
    """Every joint held at ``value`` ticks: whoever plays it sends ``value`` as every goal."""
    ticks = np.full((frames, len(ids)), value, dtype=np.uint16)
    return GaitTable(ids, 20, loop, (LIMITS,) * len(ids), ticks, {"test": "constant"})


def wave_table(ids: tuple[int, ...] = SNAKE5_IDS, frames: int = 200) -> GaitTable:
    """A table whose goals change from frame to frame (a sampled sine per joint)."""
    k = np.arange(frames)[:, None]
    j = np.arange(len(ids))[None, :]
    ticks = 512 + np.round(200 * np.sin(2 * np.pi * k / frames + j)).astype(np.int64)
    return GaitTable(ids, 20, True, (LIMITS,) * len(ids), ticks.astype(np.uint16), {})


def save(table: GaitTable, tmp_path: Path, name: str = "walk.gait") -> Path:
    path = tmp_path / name
    write_gait(path, table)
    return path


def cli(*args: str, env: dict[str, str] | None = None) -> Result:
    """Run `snakebot ARGS` in process (stdout and stderr kept apart)."""
    env = {**BASE_ENV, **(env or {})}
    return CliRunner().invoke(main, [str(a) for a in args], env=env, catch_exceptions=False)


def cli_json(*args: str, env: dict[str, str] | None = None) -> dict:
    result = cli(*args, "--json", env=env)
    assert result.exit_code == 0, result.output
    return json.loads(result.stdout)


def monitor_records(
    port: str, duration: float = 0.0, interval: float = 0.1, env: dict[str, str] | None = None
) -> list[dict]:
    result = cli(
        "monitor",
        "--port",
        port,
        "--json",
        "--duration",
        str(duration),
        "--interval",
        str(interval),
        env=env,
    )
    assert result.exit_code == 0, result.output
    return [json.loads(line) for line in result.stdout.splitlines()]


def crc_of(path: Path) -> int:
    return zlib.crc32(path.read_bytes())


def upload_packets(server: ControllerPty) -> list[bytes]:
    """The upload chunks and commits the host sent, in order."""
    return [p for p in server.host_packets if is_upload_chunk(p) or is_commit(p)]


@pytest.fixture
def controller():
    """The controller's C device logic on a pty, driving the snake5 robot's emulated
    servos; no table yet."""
    with ControllerPty(robot="snake5") as server:
        yield server
        assert server.error is None, server.error


@pytest.fixture
def old_table():
    return constant_table(300)


@pytest.fixture
def controller_with_table(old_table):
    """As ``controller``, started with ``old_table`` active (as if loaded from flash)."""
    with ControllerPty(robot="snake5", table=old_table.encode()) as server:
        yield server
        assert server.error is None, server.error
