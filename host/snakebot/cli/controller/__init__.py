"""The commands that talk to the controller on its PC link: upload, play/stop/serpenoid,
library, limits, monitor, drive, config; ``link`` opens the controller for all of them."""
