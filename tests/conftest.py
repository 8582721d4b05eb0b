"""Shared pytest set-up."""

import os
import signal
import tty
from collections.abc import Iterator

import pytest
from hypothesis import HealthCheck, settings

# The commands the tests start get a Ctrl-C the way a terminal's would reach them. A
# suite started in the background (`make test &`, a CI job) runs with SIGINT ignored,
# which exec passes on to every child, and a Python started so never takes Ctrl-C: the
# Ctrl-C tests then wait for exits that never come. A handler here is reset to the
# default in each child instead.
if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)

# Every emulated CM-530 the tests start, in process or in a command they run, stops at the
# first access to a register no model knows, instead of reading it as zero (issue #30).
os.environ.setdefault("SNAKEBOT_MCU_STRICT", "1")

# CI machines are shared and slow: no deadlines, but a fixed, generous example budget.
settings.register_profile(
    "snakebot", deadline=None, suppress_health_check=[HealthCheck.too_slow], max_examples=200
)
settings.load_profile("snakebot")

# Fixtures shared by the CLI and link tests: an emulated controller on a pty, with or
# without a table already uploaded (defined in support/controller_cli_support.py).
import controller_cli_support  # noqa: E402
from controller_cli_support import controller, controller_with_table, old_table  # noqa: E402

# A directory like /tmp for the tests that play a second local user (support/other_user.py).
from other_user import shared_tmp  # noqa: E402

__all__ = ["controller", "controller_with_table", "old_table", "shared_tmp"]


@pytest.fixture(autouse=True)
def qemu_reply_margin(request: pytest.FixtureRequest, monkeypatch: pytest.MonkeyPatch) -> None:
    """The commands a ``qemu`` test runs in process wait longer for the firmware's replies
    (``controller_cli_support.QEMU_MARGIN_MS``)."""
    if request.node.get_closest_marker("qemu"):
        margin = controller_cli_support.QEMU_MARGIN_MS
        monkeypatch.setitem(controller_cli_support.BASE_ENV, "SNAKEBOT_MARGIN_MS", margin)


@pytest.fixture
def pty_device() -> Iterator[str]:
    """A pseudo-terminal's device path (raw mode), a port that nothing answers on."""
    master, slave = os.openpty()
    tty.setraw(slave)
    yield os.ttyname(slave)
    os.close(master)
    os.close(slave)


STAGE_FILES = "MAKE_TEST_STAGE_FILES"
"""A directory: a collection of the whole suite then writes there the test files each stage
of `make test` runs (``stage-parallel``, ``stage-qemu``, ``stage-serial``, one path a
line), so that each stage's workers import only those files, not all two hundred."""


def stage_of(item: pytest.Item) -> str:
    marks = {m.name for m in item.iter_markers()}
    if "serial" in marks or "qemu" in marks:
        return "serial" if "serial" in marks else "qemu"
    return "late" if "late" in marks else "parallel"


def pytest_collection_finish(session: pytest.Session) -> None:
    out = os.environ.get(STAGE_FILES)
    if not out:
        return
    root = session.config.rootpath
    stages: dict[str, set[str]] = {"parallel": set(), "late": set(), "qemu": set(), "serial": set()}
    for item in session.items:
        stages[stage_of(item)].add(str(item.path.relative_to(root)))
    os.makedirs(out, exist_ok=True)
    for name, files in stages.items():
        with open(os.path.join(out, f"stage-{name}"), "w", encoding="utf-8") as f:
            f.write("".join(f"{path}\n" for path in sorted(files)))
