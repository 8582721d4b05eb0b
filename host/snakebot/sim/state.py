"""Keeping the servos' EEPROM in a file, so an emulated robot remembers its settings
(IDs, baud rates, limits) from one run to the next, as real servos do.

The file is JSON, one entry per servo slot on the bus in order; it is rewritten
atomically (a temporary file, then a rename) whenever a servo's EEPROM changes, so a
crash never leaves half a file.
"""

from __future__ import annotations

import json
import os
import tempfile
from collections.abc import Sequence
from pathlib import Path

from snakebot.sim.errors import SimInputError
from snakebot.sim.servo.fast import VirtualServo
from snakebot.userfiles import new_file_mode

FORMAT = "snakebot.sim-eeprom/1"


class EepromStore:
    """The EEPROM images of a bus's servos, kept in ``path``."""

    def __init__(self, path: str | os.PathLike[str]) -> None:
        self.path = Path(path)
        self._servos: Sequence[VirtualServo] = ()

    def attach(self, servos: Sequence[VirtualServo]) -> bool:
        """Restore ``servos`` from the file if it exists (return True), then save every
        later EEPROM change. The file must describe the same servo models in order."""
        self._servos = servos
        restored = False
        if self.path.exists():
            self._restore(servos)
            restored = True
        for s in servos:
            s.on_eeprom_change = self._changed
        if not restored:
            self.save()
        return restored

    def _restore(self, servos: Sequence[VirtualServo]) -> None:
        try:
            doc = json.loads(self.path.read_text())
            if not isinstance(doc, dict) or doc.get("format") != FORMAT:
                raise ValueError(f"not a {FORMAT} file")
            saved = doc["servos"]
            images = [(entry["model"], bytes.fromhex(entry["eeprom"])) for entry in saved]
        except (OSError, ValueError, KeyError, TypeError) as exc:
            raise SimInputError(
                f"cannot use the servo state file {self.path}: {exc}; delete it to start "
                "from factory settings"
            ) from exc
        models = [s.model for s in servos]
        if [m for m, _ in images] != models:
            raise SimInputError(
                f"the servo state file {self.path} describes servos "
                f"{[m for m, _ in images]}, but this bus has {models}: use the same robot "
                "or servo list as when the file was made, or delete the file"
            )
        for servo, (_, image) in zip(servos, images, strict=True):
            try:
                servo.load_eeprom(image)
            except ValueError as exc:
                raise SimInputError(f"servo state file {self.path}: {exc}; delete it") from exc

    def _changed(self, _servo: VirtualServo) -> None:
        self.save()

    def save(self) -> None:
        """Write every servo's EEPROM to the file, atomically."""
        doc = {
            "format": FORMAT,
            "servos": [{"model": s.model, "eeprom": s.regs.eeprom().hex()} for s in self._servos],
        }
        self.path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=self.path.parent, prefix=self.path.name, suffix=".tmp")
        try:
            os.fchmod(fd, new_file_mode())  # as any file the user makes, not mkstemp's 0600
            with os.fdopen(fd, "w") as f:
                json.dump(doc, f, indent=1)
                f.write("\n")
            os.replace(tmp, self.path)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise
