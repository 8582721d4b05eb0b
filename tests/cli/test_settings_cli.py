"""A bad ``SNAKEBOT_*`` value stops any command before it does anything, with one line
naming the variable, the value, what is allowed and the fix, and exit 2: one case per
kind of variable in the table (``snakebot.settings``), whichever command runs."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path
from typing import get_args

import pytest
from click.testing import CliRunner

from snakebot.cli import main
from snakebot.paths import REPO_ROOT
from snakebot.settings import SETTINGS, Kind

SERPENOID = ["gait", "serpenoid", "snake3", "-A", "20deg", "-w", "90deg", "-d", "90deg"]
"""A command that reads none of the variables below and writes its output file."""

NO_BAD_VALUE = {"flag", "text"}
"""Kinds that take any non-empty text (SNAKEBOT_DEBUG, the port names)."""

BAD = [
    (
        "SNAKEBOT_UPLOAD_WINDOW",
        "0",
        "SNAKEBOT_UPLOAD_WINDOW='0' is not a whole number of packets from 1 to 64; "
        "set it to e.g. 8 or unset it for the default",
    ),
    (
        "SNAKEBOT_RETRIES",
        "2.5",
        "SNAKEBOT_RETRIES='2.5' is not a whole number of attempts from 0 to 100; "
        "set it to e.g. 2 or unset it for the default",
    ),
    (
        "SNAKEBOT_LATENCY_MS",
        "fast",
        "SNAKEBOT_LATENCY_MS='fast' is not a number of ms from 0 to 10000; "
        "set it to e.g. 16 or unset it for the default",
    ),
    (
        "SNAKEBOT_FLASH_BOOT_TIMEOUT_S",
        "nan",
        "SNAKEBOT_FLASH_BOOT_TIMEOUT_S='nan' is not a number of seconds from 0 to 3600; "
        "set it to e.g. 10 or unset it for the default",
    ),
    (
        "SNAKEBOT_ECHO",
        "maybe",
        "SNAKEBOT_ECHO='maybe' is not one of auto, on, off, 1, 0, true, false, yes, no; "
        "set it to e.g. auto or unset it for the default",
    ),
    (
        "SNAKEBOT_PROTOCOL_DIR",
        "/nonexistent",
        "SNAKEBOT_PROTOCOL_DIR='/nonexistent' is not an existing directory; "
        "set it to the protocol/ folder of a snakebot checkout or unset it",
    ),
    (
        "SNAKEBOT_QEMU",
        "/nonexistent/qemu-system-arm",
        "SNAKEBOT_QEMU='/nonexistent/qemu-system-arm' is not an executable file, or a name "
        "on PATH; set it to the path of qemu-system-arm or unset it",
    ),
    (
        "SNAKEBOT_LIBRARY_BACKUP_DIR",
        str(REPO_ROOT / "README.md"),
        f"SNAKEBOT_LIBRARY_BACKUP_DIR={str(REPO_ROOT / 'README.md')!r} is not a directory, "
        "or a path where one can be made (something else is there); set it to a directory "
        "(it is made if missing) or unset it",
    ),
    (
        "SNAKEBOT_CONTROLLER_ID",
        "254",
        "SNAKEBOT_CONTROLLER_ID='254' is not a whole number from 0 to 253; "
        "set it to the controller's ID or unset it for the default",
    ),
]


def test_every_kind_with_a_bad_value_has_a_case():
    kinds = {SETTINGS[name].kind for name, _, _ in BAD}
    assert kinds | NO_BAD_VALUE == set(get_args(Kind))


@pytest.mark.parametrize(("name", "value", "message"), BAD, ids=[b[0] for b in BAD])
def test_a_bad_value_is_one_line_and_exit_2(tmp_path: Path, name: str, value: str, message: str):
    out = tmp_path / "walk.gait"
    result = CliRunner().invoke(main, [*SERPENOID, "-o", str(out)], env={name: value})
    assert result.exit_code == 2, result.output
    assert result.stderr.splitlines() == [f"error: {message}"]
    assert not out.exists()  # refused before any work


def test_the_same_command_runs_when_the_values_are_good(tmp_path: Path):
    out = tmp_path / "walk.gait"
    good = {
        "SNAKEBOT_UPLOAD_WINDOW": "1",
        "SNAKEBOT_RETRIES": "2.0",
        "SNAKEBOT_ECHO": "OFF",
        "SNAKEBOT_PROTOCOL_DIR": str(REPO_ROOT / "protocol"),
        "SNAKEBOT_LIBRARY_BACKUP_DIR": str(tmp_path / "not-yet"),
        "SNAKEBOT_QEMU": "sh",
        "SNAKEBOT_DEBUG": "0",
        "SNAKEBOT_LATENCY_MS": "",  # empty: unset
        "SNAKEBOT_CAMPAIGN_SEED": "not checked by the CLI: a tests-only variable",
    }
    result = CliRunner().invoke(main, [*SERPENOID, "--cycles", "1", "-o", str(out)], env=good)
    assert result.exit_code == 0, result.output
    assert out.exists()


def test_protocol_dir_that_is_not_there_exits_2_from_the_shell(tmp_path: Path):
    # issue #28: it was accepted silently although docs/settings.md promised exit 2.
    env = {**os.environ, "SNAKEBOT_PROTOCOL_DIR": "/nonexistent"}
    env["PYTHONPATH"] = str(REPO_ROOT / "host")
    result = subprocess.run(
        [sys.executable, "-m", "snakebot", *SERPENOID, "-o", str(tmp_path / "walk.gait")],
        env=env,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert result.returncode == 2, result.stderr
    assert result.stderr.splitlines() == [
        "error: SNAKEBOT_PROTOCOL_DIR='/nonexistent' is not an existing directory; "
        "set it to the protocol/ folder of a snakebot checkout or unset it"
    ]
