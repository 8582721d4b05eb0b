"""Port locks a hostile neighbour cannot turn against the user (issue #28): the lock
directory is private and checked (owner, mode, not a link), lock files are never
followed through a symbolic link, and a URL that reaches a device locks the device."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from other_user import OTHER as OTHER_USER
from other_user import as_other_user, needs_root, other_uid

from snakebot.link.transport.errors import PortError
from snakebot.link.transport.portlock import LOCK_DIR_NAME, lock_name, lock_path
from snakebot.link.transport.ports import open_port

PRECIOUS = b"the victim's data\n"


def _snakebot(args: list[str], tmpdir: Path, **env: str) -> subprocess.CompletedProcess[str]:
    environ = {k: v for k, v in os.environ.items() if k != "XDG_RUNTIME_DIR"}
    environ |= {"TMPDIR": str(tmpdir), "SNAKEBOT_RETRIES": "0", **env}
    return subprocess.run(
        [sys.executable, "-m", "snakebot", *args],
        capture_output=True,
        text=True,
        timeout=60,
        env=environ,
    )


@needs_root
def test_a_lock_directory_planted_by_another_user_is_refused(shared_tmp, pty_device):
    victim = shared_tmp / "victim.txt"
    victim.write_bytes(PRECIOUS)
    planted = shared_tmp / f"{LOCK_DIR_NAME}-{os.geteuid()}"
    as_other_user(f"mkdir -m 0777 {planted} && ln -s {victim} {planted}/{lock_name(pty_device)}")
    result = _snakebot(["stop", "--port", pty_device], shared_tmp)
    assert result.returncode == 2, result.stderr
    assert victim.read_bytes() == PRECIOUS
    line = result.stderr.strip()
    assert "\n" not in line and "Traceback" not in line
    assert f"{planted} belongs to uid {other_uid()}" in line
    assert f"rm -r {planted}" in line and "XDG_RUNTIME_DIR" in line


@needs_root
def test_a_lock_directory_linked_by_another_user_to_a_directory_of_ours_is_refused(
    shared_tmp, pty_device
):
    # The link points at a private directory of ours holding a file named as the lock:
    # followed, the lock would empty that file.
    ours = shared_tmp / "ours"
    ours.mkdir(mode=0o700)
    victim = ours / lock_name(pty_device)
    victim.write_bytes(PRECIOUS)
    planted = shared_tmp / f"{LOCK_DIR_NAME}-{os.geteuid()}"
    as_other_user(f"ln -s {ours} {planted}")
    result = _snakebot(["stop", "--port", pty_device], shared_tmp)
    assert result.returncode == 2, result.stderr
    line = result.stderr.strip()
    assert f"{planted} is a symbolic link (owner {OTHER_USER}" in line and "\n" not in line
    assert victim.read_bytes() == PRECIOUS and os.readlink(planted) == str(ours)


@needs_root
def test_a_runtime_dir_of_another_user_is_not_used(shared_tmp, pty_device):
    foreign = shared_tmp / "run-user"
    as_other_user(f"mkdir -m 0700 {foreign}")
    result = _snakebot(["stop", "--port", pty_device], shared_tmp, XDG_RUNTIME_DIR=str(foreign))
    assert "lock" not in result.stderr
    assert (shared_tmp / f"{LOCK_DIR_NAME}-{os.geteuid()}").is_dir()


def test_a_symlink_in_place_of_a_lock_file_is_never_followed(tmp_path, monkeypatch, pty_device):
    monkeypatch.setenv("XDG_RUNTIME_DIR", str(tmp_path))
    tmp_path.chmod(0o700)
    victim = tmp_path / "victim.txt"
    victim.write_bytes(PRECIOUS)
    path = lock_path(pty_device)
    assert path.parent == tmp_path / LOCK_DIR_NAME
    path.symlink_to(victim)
    with pytest.raises(PortError, match=rf"{path} .* is a symbolic link.*rm {path}"):
        open_port(pty_device, timeout=0)
    assert victim.read_bytes() == PRECIOUS
    path.unlink()
    os.link(victim, path)  # a hard link: the same file under the lock's name
    with pytest.raises(PortError, match="not a regular file of yours with one link"):
        open_port(pty_device, timeout=0)
    assert victim.read_bytes() == PRECIOUS
    path.unlink()
    open_port(pty_device, timeout=0).close()


def test_a_group_writable_lock_directory_is_refused(tmp_path, monkeypatch, pty_device):
    monkeypatch.setenv("XDG_RUNTIME_DIR", str(tmp_path))
    tmp_path.chmod(0o700)
    (tmp_path / LOCK_DIR_NAME).mkdir(mode=0o777)
    (tmp_path / LOCK_DIR_NAME).chmod(0o777)
    with pytest.raises(PortError, match=r"can be written by others \(mode 0777\)"):
        open_port(pty_device, timeout=0)


def test_the_lock_directory_is_made_private(tmp_path, monkeypatch, pty_device):
    monkeypatch.setenv("XDG_RUNTIME_DIR", str(tmp_path))
    tmp_path.chmod(0o700)
    open_port(pty_device, timeout=0).close()
    assert (tmp_path / LOCK_DIR_NAME).stat().st_mode & 0o777 == 0o700
    assert (tmp_path / LOCK_DIR_NAME / lock_name(pty_device)).stat().st_mode & 0o777 == 0o600


@pytest.mark.parametrize("scheme", ["spy://", "alt://"])
def test_a_url_that_wraps_a_device_takes_the_devices_lock(pty_device, scheme):
    with open_port(pty_device, timeout=0):
        with pytest.raises(PortError, match=f"{pty_device} is in use by pid {os.getpid()}"):
            open_port(scheme + pty_device, timeout=0)
    with open_port(scheme + pty_device, timeout=0):
        with pytest.raises(PortError, match="in use by pid"):
            open_port(pty_device, timeout=0)
