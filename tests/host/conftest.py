"""Fixtures shared by the host CLI tests: an emulated controller on a pty, with or
without a table already uploaded (defined in support/controller_cli_support.py)."""

from controller_cli_support import controller, controller_with_table, old_table

__all__ = ["controller", "controller_with_table", "old_table"]
