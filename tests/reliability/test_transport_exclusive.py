"""One port, one program: every opener takes a device exclusively, and a second opener
is told who has it (issue #17: two clients on one port read each other's replies)."""

from __future__ import annotations

import fcntl
import os
import subprocess
import sys

import pytest

from snakebot.link.transport import DxlClient
from snakebot.link.transport.errors import PortError
from snakebot.link.transport.ports import open_port


def test_a_second_opener_in_the_same_process_is_refused(pty_device):
    with open_port(pty_device, timeout=0):
        with pytest.raises(PortError, match=rf"{pty_device} is in use by pid {os.getpid()}"):
            DxlClient(pty_device)
    with open_port(pty_device, timeout=0):  # closed: free again
        pass


def test_a_second_process_is_refused_and_named(pty_device, tmp_path):
    symlink = tmp_path / "ttyDXL"
    symlink.symlink_to(pty_device)
    holder = subprocess.Popen(
        [
            sys.executable,
            "-c",
            "import sys; from snakebot.link.transport.ports import open_port; "
            f"p = open_port({str(symlink)!r}, timeout=0); print('open', flush=True); "
            "sys.stdin.read()",
        ],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert holder.stdout is not None and holder.stdout.readline().strip() == "open"
        with pytest.raises(PortError, match=rf"in use by pid {holder.pid}"):
            open_port(pty_device, timeout=0)  # the link and its target are one port
    finally:
        holder.kill()  # no clean close: the kernel drops the lock with the process
        holder.wait(timeout=30)
    open_port(pty_device, timeout=0).close()


def test_another_programs_lock_is_reported_as_busy(pty_device):
    fd = os.open(pty_device, os.O_RDWR | os.O_NOCTTY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)  # what pyserial's exclusive open does
        with pytest.raises(PortError, match="in use by another program"):
            open_port(pty_device, timeout=0)
    finally:
        os.close(fd)
    open_port(pty_device, timeout=0).close()


def test_the_cli_names_the_holder(pty_device):
    from click.testing import CliRunner

    from snakebot.cli import main

    with open_port(pty_device, timeout=0):
        result = CliRunner().invoke(main, ["bus", "ping", "1", "--port", pty_device])
    assert result.exit_code == 2
    assert result.stderr.startswith(f"error: serial port {pty_device} is in use by pid")


def test_a_lock_belongs_to_the_device_file_not_only_its_name(tmp_path, monkeypatch):
    """Another file under a held device's name (an adapter plugged in again, a pty of the
    same number in another pty filesystem) is another device: its lock is free; the held
    one stays held, through a symlink too."""
    from snakebot.link.transport.portlock import PortLock

    monkeypatch.setenv("XDG_RUNTIME_DIR", str(tmp_path))
    tmp_path.chmod(0o700)
    device = tmp_path / "ttyUSB0"
    device.write_bytes(b"")
    held = PortLock(str(device))
    try:
        link = tmp_path / "ttyDXL"
        link.symlink_to(device)
        with pytest.raises(PortError, match="is in use by pid"):
            PortLock(str(link))
        moved = tmp_path / "ttyUSB0.old"
        device.rename(moved)  # the held file lives on under another name
        device.write_bytes(b"")
        PortLock(str(device)).release()
        with pytest.raises(PortError, match="is in use by pid"):
            PortLock(str(moved))
    finally:
        held.release()
