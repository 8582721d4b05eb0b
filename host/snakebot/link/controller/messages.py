"""The controller's numbers in words: states, Error Flags, Upload Result, and the AX-12
direction-and-magnitude values it mirrors. Names come from the controller's description; the
sentences (what happened, and what to do) are written here once."""

from __future__ import annotations

from snakebot.facts.controller import Controller, load
from snakebot.formats.program.errors import RESULTS as PROGRAM_RESULTS
from snakebot.formats.protocol import ErrorFlags

FLAG_MEANINGS: dict[str, str] = {
    "UPLOAD_LENGTH": "the last upload's length was wrong or not all of it arrived",
    "UPLOAD_CRC": "the last upload arrived damaged: its CRC-32 did not match",
    "UPLOAD_LAYOUT": "the last uploaded table failed the controller's layout checks",
    "UPLOAD_TOO_BIG": "the last uploaded table was too big for the controller",
    "SERVO_ERROR": "a servo reported an error in Servo Error Mask (overload or overheating "
    "by default)",
    "BUS_LOSS": "a roster servo stopped answering telemetry reads",
    "LINK_LOSS": "the PC link went quiet for longer than Link Timeout while moving",
    "REFUSED": "a command could not run (no table, empty roster, the safe state, or the "
    "servos do not yet hold the robot's limits)",
    "PROGRAM": "the last uploaded program was refused: a joint, frame or segment outside "
    "what the controller can play (Upload Result says which)",
    "LIMITS": "a servo would not take the robot's limits as its CW/CCW Angle Limit (or did "
    "not answer while they were checked)",
    "LIBRARY": "a gait-library operation failed (Library Result on the Library page says why)",
}

SAFE_FIXES: dict[str, str] = {
    "SERVO_ERROR": "let the servos cool down or free the jammed joint (see `snakebot monitor`)",
    "BUS_LOSS": "check the servos' power (USB does not power them), cables and IDs",
    "LINK_LOSS": "keep the PC link open while the robot moves, or raise Link Timeout",
}

# What each Upload Result means, and what to do about it.
UPLOAD_RESULTS: dict[str, tuple[str, str]] = {
    "BAD_LENGTH": (
        "the commit gave a length the controller cannot hold",
        "regenerate the table with `snakebot gait` with fewer frames (`snakebot upload` "
        "names the controller's Table Capacity when a table does not fit)",
    ),
    "INCOMPLETE": (
        "fewer bytes reached the controller than the table holds (chunks were lost)",
        "check the USB cable and upload again",
    ),
    "TRANSFER_CRC": (
        "the bytes that reached the controller differ from the file (lost or damaged chunks)",
        "check the USB cable and upload again",
    ),
    "TRUNCATED": ("the table is shorter than its header says", ""),
    "BAD_MAGIC": ("the data does not start with SNKG", ""),
    "BAD_VERSION": ("the table's layout version is not one the firmware knows", ""),
    "BAD_JOINT_COUNT": ("the joint count is 0 or above 18", ""),
    "BAD_FLAGS": ("unknown flag bits or a reserved byte that is not 0", ""),
    "BAD_PERIOD": ("the frame period is 0", ""),
    "BAD_FRAME_COUNT": ("the table has no frames", ""),
    "TOO_BIG": ("the table needs more bytes than any controller holds", ""),
    "NO_ROOM_WHILE_PLAYING": (
        "the new table would land on the table playing (a table larger than half the "
        "controller's Table Capacity leaves no room beside it); the playing table is "
        "untouched",
        "stop playback (`snakebot stop`), then upload again",
    ),
    "TRAILING_BYTES": ("there are bytes after the last frame", ""),
    "STORE_BUSY": (
        "the controller is storing a gait-library slot, which reads the staged bytes "
        "until it ends (Store State on the Program page)",
        "wait a few seconds for the store to finish, then upload again",
    ),
    "CRC_MISMATCH": ("the table's own CRC does not match its bytes", ""),
    "BAD_JOINT_ID": ("a servo ID above 253 or used twice", ""),
    "BAD_LIMITS": ("a joint's min tick above its max", ""),
    "FRAME_OUT_OF_LIMITS": ("a frame value outside its joint's limits", ""),
    "OUTSIDE_ROBOT_LIMITS": (
        "the table lets a joint move beyond the robot's limits set on the controller (or "
        "names a servo they do not cover)",
        "regenerate the table with `snakebot gait` from the same robot file as "
        "`snakebot limits set`, or set that robot's limits first",
    ),
    "BAD_ROBOT_LIMITS": (
        "the robot's limits were malformed (count, a servo ID twice, or min not below max)",
        "",
    ),
    "NONE": ("no table has been committed since the controller started", ""),
}
UPLOAD_RESULTS.update({f"PROGRAM_{name}": text for name, text in PROGRAM_RESULTS.items()})

LAYOUT_FIX = (
    "the file passed snakebot's own checks, so the firmware and this snakebot disagree: "
    "flash the firmware built from this snakebot (`make firmware`, `snakebot flash`) and "
    "regenerate the table with `snakebot gait`"
)

RETRYABLE_RESULTS = frozenset({"INCOMPLETE", "TRANSFER_CRC"})
"""Commit failures that a clean resend can cure (the wire, not the table, was at fault)."""

RUNTIME_RESULTS = RETRYABLE_RESULTS | {
    "NO_ROOM_WHILE_PLAYING",
    "STORE_BUSY",
    "LIBRARY_STORING",
    "LIBRARY_FLASH",
    "LIBRARY_DAMAGED",
    "FIRMWARE_UNAVAILABLE",
}
"""The Upload Results (and library results) that are runtime failures: what was sent was
fine, the wire, the flash or the controller's state got in the way (exit 1). Every other
refusal is about what was sent or asked (a table outside the robot's limits, a malformed
table or program, no such slot): bad input (exit 2), whichever command met it."""


def is_runtime_result(name: str) -> bool:
    """Whether the refusal ``name`` (an Upload Result) is a runtime failure, not bad input."""
    return name in RUNTIME_RESULTS


def _name(enum: str, value: int, ctl: Controller | None = None) -> str:
    for name, code in (ctl or load()).enums[enum].items():
        if code == value:
            return name
    return f"UNKNOWN({value})"


def state_name(value: int, ctl: Controller | None = None) -> str:
    """IDLE, PLAYING, SERPENOID or SAFE."""
    return _name("State", value, ctl)


def upload_result_name(value: int, ctl: Controller | None = None) -> str:
    return _name("Upload Result", value, ctl)


def flag_names(value: int, ctl: Controller | None = None) -> list[str]:
    """The set Error Flags bits by name, lowest bit first."""
    flags = (ctl or load()).enums["Error Flags"]
    names = [name for name, bit in sorted(flags.items(), key=lambda kv: kv[1]) if value & bit]
    unknown = value & ~sum(flags.values())
    if unknown:
        names.append(f"UNKNOWN(0x{unknown:04X})")
    return names


def describe_flags(value: int, ctl: Controller | None = None) -> str:
    """Error Flags in words: "BUS_LOSS (a roster servo stopped answering ...)"; "none"."""
    names = flag_names(value, ctl)
    if not names:
        return "none"
    return "; ".join(f"{n} ({FLAG_MEANINGS[n]})" if n in FLAG_MEANINGS else n for n in names)


def safe_fix(value: int, ctl: Controller | None = None) -> str:
    """What to do about the safe-state causes among the flags."""
    fixes = [SAFE_FIXES[n] for n in flag_names(value, ctl) if n in SAFE_FIXES]
    return "; ".join(fixes) or "find what stopped the robot (see `snakebot monitor`)"


def upload_result_reason(value: int, ctl: Controller | None = None) -> tuple[str, str, str]:
    """(name, what happened, what to do) for an Upload Result code."""
    name = upload_result_name(value, ctl)
    what, fix = UPLOAD_RESULTS.get(name, (f"result code {value}", ""))
    return name, what, fix or LAYOUT_FIX


def servo_error_words(value: int) -> str:
    """An AX-12 error byte in words ("no error", "overheating, overload")."""
    return ErrorFlags(value).describe()


def servo_error_names(value: int) -> list[str]:
    return [flag.name or str(int(flag)) for flag in ErrorFlags if value & flag]
