"""A real X server for the tests of MuJoCo's viewer (`snakebot sim view`): Xvfb on a free
display number, drawn by Mesa's GL. Import the fixtures into a test module to use them."""

from __future__ import annotations

import atexit
import os
import shutil
import subprocess

import pytest


@pytest.fixture(scope="session")
def xvfb() -> str:
    """A fresh X server (Xvfb) on a free display number: its DISPLAY. It stops when the
    process exits, after GLFW lets go of it (atexit runs last what registered first; the
    viewer registers GLFW's end when it first opens): an X server that goes away under
    a connection makes Xlib end the process."""
    if shutil.which("Xvfb") is None:  # pragma: no cover - the dev setup installs it
        pytest.skip("Xvfb is not installed (apt-get install xvfb)")
    read, write = os.pipe()
    server = subprocess.Popen(
        ["Xvfb", "-displayfd", str(write), "-screen", "0", "1280x720x24", "-nolisten", "tcp"],
        pass_fds=(write,),
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    os.close(write)
    with os.fdopen(read) as announced:
        number = announced.readline().strip()  # written once the server accepts clients
    atexit.register(server.wait, 10)
    atexit.register(server.terminate)
    assert number, "Xvfb did not start"
    return f":{number}"


@pytest.fixture
def display(xvfb, monkeypatch) -> str:
    monkeypatch.setenv("DISPLAY", xvfb)
    return xvfb
