"""The commands that talk to the controller on its PC link: upload, play/stop/serpenoid,
library, limits, monitor, drive, config; ``link`` opens the controller for all of them.
The operations themselves are in :mod:`snakebot.link.controller`.

May import: as the ``cli`` layer (every layer below it)."""
