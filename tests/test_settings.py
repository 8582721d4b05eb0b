"""The one table of ``SNAKEBOT_*`` variables and its resolver (``snakebot.settings``):
each kind parses what it should, refuses what it should with the one-line message, and
the rows are consistent with themselves."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from snakebot.settings import (
    SETTINGS,
    SettingError,
    check_environment,
    lookup,
    resolve,
)


@pytest.fixture
def env(monkeypatch: pytest.MonkeyPatch) -> pytest.MonkeyPatch:
    for name in SETTINGS:
        monkeypatch.delenv(name, raising=False)
    return monkeypatch


def test_every_row_is_consistent():
    assert len(SETTINGS) >= 25
    for name, row in SETTINGS.items():
        assert name == row.name and name.startswith("SNAKEBOT_")
        assert row.meaning and row.group
        assert row.default is not None or row.default_note, name
        if row.kind in ("int", "float"):
            assert row.low is not None and row.high is not None and row.low <= row.high, name
            if row.default is not None:
                assert isinstance(row.default, (int, float)), name
                assert row.low <= row.default <= row.high, name
                assert row.parse(str(row.default)) == row.default, name
        if row.kind == "choice":
            assert row.default in row.choices.values(), name


@pytest.mark.parametrize(
    ("name", "text", "value"),
    [
        ("SNAKEBOT_RETRIES", "5", 5),
        ("SNAKEBOT_RETRIES", " 5 ", 5),
        ("SNAKEBOT_RETRIES", "2.0", 2),
        ("SNAKEBOT_RETRIES", "100", 100),
        ("SNAKEBOT_LATENCY_MS", "0.5", 0.5),
        ("SNAKEBOT_LATENCY_MS", "1e3", 1000.0),
        ("SNAKEBOT_ECHO", "ON", True),
        ("SNAKEBOT_ECHO", "no", False),
        ("SNAKEBOT_ECHO", "Auto", "auto"),
        ("SNAKEBOT_DEBUG", "0", True),
        ("SNAKEBOT_PORT", "/dev/ttyUSB0", "/dev/ttyUSB0"),
    ],
)
def test_good_values_parse(env, name, text, value):
    env.setenv(name, text)
    assert lookup(name) == value
    assert type(lookup(name)) is type(value)


@pytest.mark.parametrize(
    ("name", "text"),
    [
        ("SNAKEBOT_RETRIES", "many"),
        ("SNAKEBOT_RETRIES", "-1"),
        ("SNAKEBOT_RETRIES", "101"),
        ("SNAKEBOT_RETRIES", "2.5"),
        ("SNAKEBOT_LATENCY_MS", "nan"),
        ("SNAKEBOT_LATENCY_MS", "inf"),
        ("SNAKEBOT_LATENCY_MS", "10000.5"),
        ("SNAKEBOT_LATENCY_MS", "1j"),
        ("SNAKEBOT_ECHO", "sometimes"),
        ("SNAKEBOT_UPLOAD_WINDOW", "0"),
        ("SNAKEBOT_PROTOCOL_DIR", "/nonexistent"),
        ("SNAKEBOT_QEMU", "no-such-qemu-here"),
    ],
)
def test_bad_values_are_one_line_naming_variable_value_range_and_fix(env, name, text):
    env.setenv(name, text)
    with pytest.raises(SettingError) as caught:
        resolve(name)
    message = str(caught.value)
    assert "\n" not in message
    assert message.startswith(f"{name}={text!r} is not {SETTINGS[name].allowed()}")
    assert message.endswith("unset it") or message.endswith("unset it for the default")


def test_empty_counts_as_unset(env):
    env.setenv("SNAKEBOT_RETRIES", "  ")
    assert lookup("SNAKEBOT_RETRIES") is None
    assert resolve("SNAKEBOT_RETRIES") == SETTINGS["SNAKEBOT_RETRIES"].default


def test_paths(env, tmp_path: Path):
    env.setenv("SNAKEBOT_PROTOCOL_DIR", str(tmp_path))
    assert lookup("SNAKEBOT_PROTOCOL_DIR") == tmp_path
    env.setenv("SNAKEBOT_LIBRARY_BACKUP_DIR", str(tmp_path / "new" / "dir"))
    assert lookup("SNAKEBOT_LIBRARY_BACKUP_DIR") == tmp_path / "new" / "dir"
    (tmp_path / "file").write_text("")
    env.setenv("SNAKEBOT_LIBRARY_BACKUP_DIR", str(tmp_path / "file"))
    with pytest.raises(SettingError, match="something else is there"):
        lookup("SNAKEBOT_LIBRARY_BACKUP_DIR")
    env.setenv("SNAKEBOT_QEMU", "sh")
    assert lookup("SNAKEBOT_QEMU") == shutil.which("sh")


def test_check_environment_checks_all_but_the_tests_variables(env):
    check_environment()
    env.setenv("SNAKEBOT_CAMPAIGN_SEED", "x")
    check_environment()  # the package never reads it
    with pytest.raises(SettingError, match="SNAKEBOT_CAMPAIGN_SEED"):
        check_environment(skip_groups=())
    env.setenv("SNAKEBOT_FLASH_GO_TIMEOUT_S", "-1")
    with pytest.raises(SettingError, match="SNAKEBOT_FLASH_GO_TIMEOUT_S='-1'"):
        check_environment()
