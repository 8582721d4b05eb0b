"""Start-up: commands load when they are run (``snakebot.cli.lazy``), so `snakebot --help`
imports about what a bare click application does, and a command imports what it needs
and not numpy's heavier neighbours (matplotlib, MuJoCo, the ELF reader, the emulator).
Counted in modules, not seconds: the speed itself is bench/bench_startup.py's."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest
from click.testing import CliRunner

from snakebot.cli import COMMANDS, main
from snakebot.cli.gait import SUBCOMMANDS
from snakebot.cli.lazy import LazyGroup, load, short_help

COUNT = """
import json, sys
{setup}
try:
    {run}
except SystemExit:
    pass
print(json.dumps(sorted(sys.modules)), file=sys.stderr)
"""

BARE_CLICK = COUNT.format(
    setup="import click\n@click.group()\ndef app() -> None:\n    pass",
    run='app(["--help"])',
)

EXTRA_MODULES_AT_HELP = 16
"""Modules that `snakebot --help` may load beyond a bare click application's: snakebot's
own six (the package, ``cli``, ``cli.errors``, ``cli.lazy``, ``errors``, ``settings``)
and the standard ones they need (``dataclasses``, ``pathlib``, ...); with every command
imported it was over 600."""

EXTRA_MODULES_AT_NUMPY_COMMAND = 20
"""Modules that `snakebot gait serpenoid --help` may load beyond `import numpy` and
`snakebot --help` together: the command's own module, the option and parameter modules,
the angle parser and the board facts (16 now); with every table, robot and kinematics
module imported up front it was 79."""

HEAVY = ("matplotlib", "mujoco", "elftools", "serial", "scipy", "sympy")


def modules(code: str) -> list[str]:
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    return json.loads(done.stderr.strip().splitlines()[-1])


def snakebot_modules(*args: str) -> list[str]:
    run = f"main({list(args)!r})"
    return modules(COUNT.format(setup="from snakebot.cli import main", run=run))


def test_help_loads_about_what_a_bare_click_app_does():
    bare, ours = modules(BARE_CLICK), snakebot_modules("--help")
    assert len(ours) <= len(bare) + EXTRA_MODULES_AT_HELP, sorted(set(ours) - set(bare))
    assert not [m for m in ours if m.split(".")[0] in (*HEAVY, "numpy")]


def test_a_numpy_command_loads_no_heavy_neighbour_and_no_other_command():
    loaded = snakebot_modules("gait", "serpenoid", "--help")
    assert "numpy" in loaded
    assert not [m for m in loaded if m.split(".")[0] in HEAVY]
    others = ("snakebot.cli.sim", "snakebot.cli.gait.search", "snakebot.workflows", "snakebot.sim")
    assert not [m for m in loaded if m.startswith(others)]


def test_a_numpy_command_loads_little_beyond_numpy_and_the_help():
    numpy = modules(COUNT.format(setup="import numpy", run="pass"))
    base = set(numpy) | set(snakebot_modules("--help"))
    extra = sorted(set(snakebot_modules("gait", "serpenoid", "--help")) - base)
    assert len(extra) <= EXTRA_MODULES_AT_NUMPY_COMMAND, extra


@pytest.mark.parametrize("table", [COMMANDS, SUBCOMMANDS], ids=["snakebot", "gait"])
def test_each_listed_line_is_the_commands_own(table):
    for name, entry in table.items():
        assert short_help(load(entry.where)) == entry.short_help, name
        for where in entry.subcommands:
            load(where)


def test_a_lazy_group_runs_its_commands_and_lists_them_all():
    assert isinstance(main, LazyGroup)
    result = CliRunner().invoke(main, ["gait", "search", "--help"])
    assert result.exit_code == 0 and "Search serpenoid gaits" in result.output
    listing = CliRunner().invoke(main, ["--help"]).output
    assert all(f"  {name} " in listing for name in COMMANDS)
