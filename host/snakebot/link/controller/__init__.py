"""The host's view of the snakebot controller (the CM-530 firmware as a Protocol 1.0
device): register names, addresses and value meanings from its description
(``snakebot/facts/devices/data/controller.json``).

    from snakebot.link.controller import load, State, Command
    table = load()
    table.register("Speed Scale").address      # 16
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
