"""The snakebot controller (the CM-530 firmware as a Protocol 1.0 device) on its PC link:
the client that opens it (``client``), the upload of a gait table or program in its
steps (``upload_stream`` sends the chunks, ``upload`` checks, commits and reads back),
playback (``playback``), the on-board gait library (``library``), the robot's limits
(``limits``), telemetry (``monitor``, ``mcap_log``), live driving (``drive``), settings
by name (``config``), the controller's messages and errors (``messages``, ``errors``)
and the environment's settings (``settings``).

This module gives the control table (from :mod:`snakebot.facts.controller`) and its
value meanings as enums:

    from snakebot.link.controller import load, State, Command
    table = load()
    table.register("Speed Scale").address      # 16

May import: as the ``link`` layer (``link.transport``, ``model``, ``formats``,
``facts``, the package root); never ``sim``.
"""

from __future__ import annotations

from enum import IntEnum, IntFlag

from snakebot.facts.controller import Controller, ControllerTableError, Register, load
from snakebot.formats.upload_writes import chunk_writes, commit_write

_enums = load().enums
State = IntEnum("State", _enums["State"])
Command = IntEnum("Command", _enums["Command"])
SafeAction = IntEnum("SafeAction", _enums["Safe Action"])
UploadResult = IntEnum("UploadResult", _enums["Upload Result"])
ControllerErrors = IntFlag("ControllerErrors", _enums["Error Flags"])
UploadCommit = IntEnum("UploadCommit", _enums["Upload Commit"])
LimitsState = IntEnum("LimitsState", _enums["Limits State"])

__all__ = [
    "Command",
    "Controller",
    "ControllerErrors",
    "ControllerTableError",
    "LimitsState",
    "Register",
    "SafeAction",
    "State",
    "UploadCommit",
    "UploadResult",
    "chunk_writes",
    "commit_write",
    "load",
]
