"""Fuzzing the command line: whatever the arguments, robot file or gait metadata, a command
ends in bounded time with exit 0, 1 or 2 and, when it fails, one line `error: ...`:
never a traceback, never snakebot's own "internal error" (a bug caught at the last
moment), never NaN in JSON.

The argument lists are drawn from the click command tree itself (every command, every
option and argument, values from a pool of hostile ones), so a new command or option is
fuzzed without touching this file. Budget: SNAKEBOT_CLI_FUZZ_EXAMPLES argument lists
(default 40), four times as many robot files and metadata files; about a minute in all
on a loaded machine.

Hostile files and numbers (issue #28) go to every file and number parameter in a process
of their own, under RLIMIT_AS 2 GB and a 10 s limit: a FIFO, /dev/zero, a directory, a
symbolic link to a file outside, a 5 GB file, TOML nested 5000 deep; NaN, infinities,
1e400, a complex number, negative counts. Each must be refused with exit 2 (a negative
number may be fine), write nothing, and never write through the link; a third as many
cases as argument lists (13 by default, about 15 s).

The serving commands (`sim serve`, `sim bus`, `sim bootloader`: they run until a signal)
get the same hostile files and numbers, and hostile paths for their --link, --unix and
--state and hostile fault specifications, each case a process under the same limits:
it refuses its input at once (exit 2, one line, nothing left: no link, no socket, no
claim record, no work directory) or serves and then stops on SIGTERM (exit 143, one line
`interrupted`, the same nothing left). A few cases per server kind by default (about
5 s), an eighth as many as argument lists in a longer run.

Every error line any of these prints is at most LINE_LIMIT characters (400), however long
the input it quotes back; huge values (10,000 numbers, 20,000 digits, a 20 KB path) go to
every parameter of every command to check it (as many cases as argument lists, in
process: a few seconds).
"""

from __future__ import annotations

import atexit
import json
import os
import re
import select
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from importlib import resources
from pathlib import Path

import click
import pytest
from click.testing import CliRunner
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from snakebot.cli import main
from snakebot.cli.errors import INTERNAL_ERROR
from snakebot.cli.params import AngleListType, AngleType, NumberType, OutputPathType
from snakebot.cli.troubleshooting import ERROR_LINE
from snakebot.errors import LINE_LIMIT
from snakebot.settings import resolve_int
from snakebot.sim.serve import default_firmware

EXAMPLES = resolve_int("SNAKEBOT_CLI_FUZZ_EXAMPLES")
FUZZ = settings(
    max_examples=EXAMPLES,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
FUZZ_FILES = settings(FUZZ, max_examples=4 * EXAMPLES)  # files: much faster per example
pytestmark = pytest.mark.timeout(max(300, 6 * EXAMPLES))

SERVING = {
    ("sim", "bus"),
    ("sim", "serve"),
    ("sim", "bootloader"),
    ("demo",),
    ("gait", "search"),
    ("bus", "play"),
    ("sim", "goto"),
    ("sim", "thesis"),
    ("sim", "friction"),
    ("sim", "view"),
}
"""Commands that serve until interrupted (`sim view` until its window closes), play in
real time (`bus play --loop` never ends), run the whole emulated robot or many physics
runs: not fuzzed here (their options are parsed by the same types; the serving ones run
in tests/cli/test_cli_resources.py, the others in their own tests)."""

SLOW_FLAGS = {"--symbolic"}  # sympy at full size: minutes on a loaded machine
ENV = {
    "SNAKEBOT_RETRIES": "0",
    "SNAKEBOT_FLASH_RESET_TIMEOUT_S": "0.2",
    "SNAKEBOT_PORT": None,
}

NUMBERS = [
    "0",
    "1",
    "-1",
    "2",
    "50",
    "0.5",
    "nan",
    "inf",
    "-inf",
    "1e308",
    "1e-320",
    "9" * 400,
    "-" * 300 + "1",
    "pi/0",
    "2**9999",
    "30deg",
    "pi/3",
    "",
    "x",
]
PORTS = ["/dev/nonexistent-port", "sim://?ids=1", "sim://?ids=1&brownout=1@5+1", "loop://", ""]
TEXTS = ["snake3", "snake5", "trident", "g1", "h1", "2*g1-h3", "AX-12W", "1,2,3", "Goal Position"]
PATHS = ["/dev/zero", "/dev/null", "/", "missing.gait", "out.gait", "x.xyz", "plot.png", ""]


@contextmanager
def _cwd(path: Path) -> Iterator[None]:
    old = os.getcwd()
    os.chdir(path)
    try:
        yield
    finally:
        os.chdir(old)


def _leaves(
    command: click.Command, path: tuple[str, ...] = ()
) -> list[tuple[tuple[str, ...], click.Command]]:
    if isinstance(command, click.Group):  # through get_command: the groups load lazily
        ctx = click.Context(command)
        return [
            leaf
            for name in command.list_commands(ctx)
            for leaf in _leaves(command.get_command(ctx, name), (*path, name))
        ]
    return [(path, command)]


COMMANDS = [(path, cmd) for path, cmd in _leaves(main) if path not in SERVING]


def _is_port(name: str) -> bool:
    """Whether the parameter ``name`` is a port (``--port``, ``--bootloader-port``), not
    an option that merely holds the letters (``--report``)."""
    return name.endswith("port") and not name.endswith("report")


def _hostile(param: click.Parameter, name: str) -> st.SearchStrategy[str]:
    if _is_port(name):
        return st.sampled_from(PORTS)
    if isinstance(param.type, click.Path) or name in ("--output", "--plot", "--out", "-o"):
        return st.sampled_from(PATHS)
    pool = st.sampled_from(NUMBERS + TEXTS + PATHS)
    return st.one_of(pool, st.text(max_size=20).filter(lambda s: "\x00" not in s))


def _usual(param: click.Parameter, name: str) -> st.SearchStrategy[str]:
    """Values the command takes, so that most runs get past parsing into the command."""
    kind = param.type
    if _is_port(name) and param.callback is None:  # a servo bus
        return st.sampled_from(["sim://?ids=1,2", "sim://?robot=snake3", "loop://"])
    if _is_port(name):  # a controller or its bootloader: nothing answers on these
        return st.sampled_from(["loop://", "/dev/nonexistent-port"])
    if isinstance(kind, click.Choice):
        return st.sampled_from([str(c) for c in kind.choices])
    if isinstance(kind, click.IntRange):
        low = kind.min if kind.min is not None else 0
        high = kind.max if kind.max is not None else low + 300
        return st.integers(low, min(high, low + 300)).map(str)
    if isinstance(kind, NumberType):
        low = kind.low if kind.low is not None else -10.0
        high = kind.high if kind.high is not None else low + 100.0
        return st.floats(low, high, exclude_min=kind.low_open, exclude_max=kind.high_open).map(repr)
    if isinstance(kind, AngleListType):
        return st.sampled_from(["0.3,-0.2", "pi/3,-pi/3", "0,0,0", "10deg"])
    if isinstance(kind, AngleType):
        return st.sampled_from(["0.3", "30deg", "-20deg", "pi/6", "1e-3", "3"])
    if isinstance(kind, OutputPathType):  # written: never the shared sample files
        return st.sampled_from(["plot.png", "plot.svg"] if "plot" in name else ["out.gait"])
    if isinstance(kind, click.Path):
        gait, firmware = _sample_files()
        return st.just(firmware if "firmware" in name else gait)
    by_name = {
        "robot": ["snake3", "snake5", "trident"],
        "--robot": ["snake3", "snake5", "trident"],
        "--field": ["g1", "h1", "2*g1-h3", "g3+2*h1"],
        "--ids": ["1", "1-3", "1,2"],
        "--bauds": ["1000000", "57600,1000000"],
        "registers": ["Goal Position", "Present Temperature", "LED"],
        "register": ["Goal Position", "LED", "Moving Speed"],
        "value": ["512", "1", "0", "2000"],
        "--model": ["AX-12A", "AX-12W"],
    }
    return st.sampled_from(by_name.get(name, ["1", "snake3"]))


_FILES: list[str] = []


def _sample_files() -> list[str]:
    """A gait table (with its metadata) and a firmware-sized blob, made once per run."""
    if not _FILES:
        where = Path(tempfile.mkdtemp(prefix="snakebot-cli-fuzz-"))
        atexit.register(shutil.rmtree, where, True)
        gait = where / "walk.gait"
        args = ["gait", "serpenoid", "snake3", "-A", "20deg", "-w", "90deg", "-d", "90deg"]
        assert invoke([*args, "--cycles", "1", "-o", str(gait)]).exit_code == 0
        blob = where / "fw.bin"
        blob.write_bytes(bytes(1024))
        _FILES.extend([str(gait), str(blob)])
    return _FILES


@st.composite
def invocations(draw: st.DrawFn) -> list[str]:
    path, command = draw(st.sampled_from(COMMANDS))
    args = list(path)
    # One parameter at most gets a hostile value, so most runs get into the command.
    hostile = draw(st.integers(-1, len(command.params) - 1))

    def value(param: click.Parameter, name: str) -> str:
        bad = command.params.index(param) == hostile
        return draw((_hostile if bad else _usual)(param, name))

    for param in command.params:
        if isinstance(param, click.Option):
            name = param.opts[0]
            given = draw(st.integers(0, 9)) < (9 if param.required else 4)
            if name == "--help" or name in SLOW_FLAGS or not given:
                continue
            if param.is_flag:
                args.append(draw(st.sampled_from(param.opts + param.secondary_opts)))
            else:
                args += [name, value(param, name)]
        elif draw(st.integers(0, 9)):  # arguments, usually given
            count = 1 if param.nargs == 1 else draw(st.integers(0, 3))
            args += [value(param, param.name or "") for _ in range(count)]
    return args


NOT_A_NUMBER = re.compile(r"\b(NaN|-?Infinity)\b")


def check(result: click.testing.Result, echoed: Iterable[str] = ()) -> None:
    """The oracle: exit 0, 1 or 2; a failure is one line `error: ...`; JSON is JSON.

    `echoed` are the input's own texts (a metadata key named "Infinity"), which the
    output may quote back: only numbers the tool printed as NaN or Infinity are errors.
    """
    exc = result.exception
    assert exc is None or isinstance(exc, SystemExit), repr(exc)
    assert "Traceback" not in result.output
    assert INTERNAL_ERROR not in result.stderr, result.stderr
    assert result.exit_code in (0, 1, 2), (result.exit_code, result.output)
    if result.exit_code:
        lines = [line for line in result.stderr.splitlines() if line.strip()]
        assert lines and ERROR_LINE.match(lines[-1]), result.stderr
        assert_bounded(lines)
    printed = result.stdout
    for text in sorted({t for t in echoed if NOT_A_NUMBER.search(t)}, key=len, reverse=True):
        printed = printed.replace(text, "")
    assert not NOT_A_NUMBER.search(printed), result.stdout


def assert_bounded(lines: list[str]) -> None:
    """No error line longer than LINE_LIMIT, whatever it quotes back."""
    long = [line for line in lines if ERROR_LINE.match(line) and len(line) > LINE_LIMIT]
    assert not long, f"{len(long[0])} characters: {long[0][:300]}..."


def invoke(args: list[str]) -> click.testing.Result:
    return CliRunner().invoke(main, args, env=ENV)


@FUZZ
@given(args=invocations())
def test_any_arguments_to_any_command(args: list[str]) -> None:
    with tempfile.TemporaryDirectory() as tmp, _cwd(Path(tmp)):
        check(invoke(args))


# -- robot files ---------------------------------------------------------------------------

TOML_VALUES = [
    "1",
    "0",
    "-1",
    "1e307",
    "-1e307",
    "nan",
    "inf",
    "10" + "0" * 400,
    '"text"',
    "[]",
    "[1, 2]",
    "{}",
    "true",
    '"AX-12W"',
    '"snake"',
    '"trident"',
    "70",
]


@st.composite
def robot_texts(draw: st.DrawFn) -> bytes:
    name = draw(st.sampled_from(["snake3", "snake5", "trident"]))
    lines = (
        resources.files("snakebot.model.robots").joinpath(f"{name}.toml").read_text().splitlines()
    )
    for _ in range(draw(st.integers(1, 4))):
        i = draw(st.integers(0, len(lines) - 1))
        how = draw(st.sampled_from(["value", "key", "drop", "copy", "table"]))
        key, eq, _ = lines[i].partition("=")
        if how == "value" and eq:
            lines[i] = f"{key}= {draw(st.sampled_from(TOML_VALUES))}"
        elif how == "key" and eq:
            mangled = draw(st.sampled_from([key.strip()[:-1], key.strip() + "s", "extra"]))
            lines[i] = f"{mangled} ={lines[i].partition('=')[2]}"
        elif how == "drop":
            del lines[i]
        elif how == "copy":
            lines.insert(i, lines[i])
        elif how == "table":
            lines.insert(i, draw(st.sampled_from(["[geometry]", "[[joints]]", "[servo]", "[x]"])))
        if not lines:
            lines = [""]
    data = "\n".join(lines).encode()
    if draw(st.booleans()):
        cut = draw(st.integers(0, len(data)))
        data = data[:cut] + draw(st.sampled_from([b"", b"\xff", b"\x00", b"\xc3"])) + data[cut:]
    return data


@FUZZ_FILES
@given(text=robot_texts(), command=st.sampled_from(["info", "serpenoid", "fields"]))
def test_any_robot_file(text: bytes, command: str) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        robot = Path(tmp) / "robot.toml"
        robot.write_bytes(text)
        if command == "info":
            args = ["model", "info", str(robot), "--json"]
        elif command == "fields":
            args = ["model", "fields", str(robot), "--json"]
        else:
            out = str(Path(tmp) / "g.gait")
            args = ["gait", "serpenoid", str(robot), "-A", "0.3", "-w", "3", "-d", "1"]
            args += ["--cycles", "1", "-o", out, "--json"]
        check(invoke(args))


# -- gait metadata -------------------------------------------------------------------------

json_values = st.recursive(
    st.none()
    | st.booleans()
    | st.integers(-(2**70), 2**70)
    | st.floats(allow_nan=True, allow_infinity=True)
    | st.text(max_size=8),
    lambda inner: (
        st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=8), inner, max_size=4)
    ),
    max_leaves=12,
)


@pytest.fixture(scope="module")
def gait_dir() -> Iterator[Path]:
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "walk.gait"
        args = ["gait", "serpenoid", "snake3", "-A", "20deg", "-w", "90deg", "-d", "90deg"]
        result = invoke([*args, "--cycles", "1", "-o", str(out)])
        assert result.exit_code == 0, result.output
        yield Path(tmp)


def _paths(node: object, here: tuple = ()) -> Iterator[tuple]:
    yield here
    if isinstance(node, dict):
        for k, v in node.items():
            yield from _paths(v, (*here, k))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            yield from _paths(v, (*here, i))


def _texts(node: object) -> Iterator[str]:
    """Every key and string value in a JSON document, as the output may quote them."""
    if isinstance(node, str):
        yield node
        yield json.dumps(node)
    elif isinstance(node, dict):
        for k, v in node.items():
            yield from _texts(k)
            yield from _texts(v)
    elif isinstance(node, list):
        for v in node:
            yield from _texts(v)


@FUZZ_FILES
@given(data=st.data())
def test_any_gait_metadata(gait_dir: Path, data: st.DataObject) -> None:
    gait = gait_dir / "walk.gait"
    original = json.loads((gait_dir / "walk.gait.json").read_text())
    doc = json.loads(json.dumps(original))
    for _ in range(data.draw(st.integers(1, 3))):
        where = data.draw(st.sampled_from(list(_paths(doc))[1:]))
        parent = doc
        for part in where[:-1]:
            parent = parent[part]
        parent[where[-1]] = data.draw(json_values)
    text = json.dumps(doc)
    if data.draw(st.booleans()):
        depth = data.draw(st.sampled_from([10, 1000, 100_000]))
        text = text[:-1] + ', "deep": ' + "[" * depth + "]" * depth + "}"
    with tempfile.TemporaryDirectory() as tmp:
        copy = Path(tmp) / "walk.gait"
        copy.write_bytes(gait.read_bytes())
        (Path(tmp) / "walk.gait.json").write_text(text)
        result = invoke(["gait", "show", str(copy), *data.draw(st.sampled_from([[], ["--json"]]))])
    check(result, echoed=_texts(doc))


# -- hostile files and numbers, each case in its own process under limits ----------------

HOSTILE_EXAMPLES = max(10, EXAMPLES // 3)
CASE_TIMEOUT_S = 10.0
CASE_MEMORY = 2 << 30  # RLIMIT_AS: 2 GB of address space
PRECIOUS = b"precious: not to be written\n"

HOSTILE_FILES = ["fifo", "/dev/zero", "dir", "outside-link", "huge.gait", "deep.toml"]
"""A FIFO (an open that blocks for ever), an endless device, a directory, a symlink to a
file outside the working directory, a 5 GB (sparse) file and a TOML nested 5000 deep."""
HOSTILE_OUTPUTS = ["fifo", "/dev/zero", "dir", "outside-link"]
HOSTILE_NUMBERS = ["nan", "inf", "-inf", "1e400", "(-8)**0.5", "-1", "-100000"]
NEVER_NUMBERS = {"nan", "inf", "-inf", "1e400", "(-8)**0.5"}
"""Refused (exit 2) by every number option; the negative ones may be fine for some."""

NUMBER_TYPES = (click.IntRange, NumberType, AngleType, AngleListType, type(click.INT))


def _kind(param: click.Parameter) -> str | None:
    """Which hostile values ``param`` takes: an input file, an output, a number."""
    name = param.opts[0] if isinstance(param, click.Option) else param.name or ""
    if _is_port(name):
        return None
    if isinstance(param.type, OutputPathType):
        return "output"
    if isinstance(param.type, click.Path) or name in ("robot", "--robot", "toml"):
        return "input"
    if isinstance(param.type, NUMBER_TYPES):
        return "number"
    return None


TARGETS = [
    (path, command, param, kind)
    for path, command in COMMANDS
    for param in command.params
    if (kind := _kind(param))
]


def _plant(where: Path, outside: Path) -> None:
    """The hostile files, in the case's working directory ``where``."""
    os.mkfifo(where / "fifo")
    (where / "dir").mkdir()
    (where / "outside-link").symlink_to(outside)
    with (where / "huge.gait").open("wb") as f:
        f.truncate(5 << 30)  # sparse: no disk used
    (where / "deep.toml").write_text("a = " + "[" * 5000 + "]" * 5000 + "\n")


def _limits() -> None:
    import resource

    resource.setrlimit(resource.RLIMIT_AS, (CASE_MEMORY, CASE_MEMORY))


def _run_limited(args: list[str], where: Path, env: dict[str, str]) -> subprocess.CompletedProcess:
    """``snakebot ARGS`` in ``where`` under the case's limits. One that has not ended in
    CASE_TIMEOUT_S is run again with three times as long before it counts as a hang: a
    machine loaded by other tests can stretch a second into ten, never a hang into an end.
    """
    for timeout in (CASE_TIMEOUT_S, 3 * CASE_TIMEOUT_S):
        try:
            return subprocess.run(
                [sys.executable, "-m", "snakebot", *args],
                cwd=where,
                env=env,
                stdin=subprocess.DEVNULL,
                capture_output=True,
                text=True,
                timeout=timeout,
                preexec_fn=_limits,
            )
        except subprocess.TimeoutExpired:
            pass
    pytest.fail(f"snakebot {' '.join(args)}: no end within {CASE_TIMEOUT_S:g} s, twice")


@st.composite
def hostile_cases(draw: st.DrawFn) -> tuple[list[str], str, str]:
    """(arguments, the hostile value, the kind of parameter it went to): the command's
    required parameters with usual values, one file or number parameter a hostile one."""
    path, command, target, kind = draw(st.sampled_from(TARGETS))
    pool = {"input": HOSTILE_FILES, "output": HOSTILE_OUTPUTS, "number": HOSTILE_NUMBERS}
    bad = draw(st.sampled_from(pool[kind]))
    return _with_one_bad(draw, path, command, target, bad), bad, kind


def _with_one_bad(
    draw: st.DrawFn,
    path: tuple[str, ...],
    command: click.Command,
    target: click.Parameter,
    bad: str,
) -> list[str]:
    """``path``'s arguments: its required parameters with usual values, ``target`` ``bad``."""
    args = list(path)
    for param in command.params:
        if param is not target and not param.required:
            continue
        if isinstance(param, click.Option):
            name = param.opts[0]
            args += [name, bad if param is target else draw(_usual(param, name))]
        else:
            args.append(bad if param is target else draw(_usual(param, param.name or "")))
    return args


@settings(FUZZ, max_examples=HOSTILE_EXAMPLES)
@given(case=hostile_cases())
def test_hostile_files_and_numbers_are_refused_in_bounded_time_and_memory(case) -> None:
    args, bad, kind = case
    with tempfile.TemporaryDirectory() as tmp, tempfile.TemporaryDirectory() as far:
        where, outside = Path(tmp), Path(far) / "target"
        outside.write_bytes(PRECIOUS)
        _plant(where, outside)
        planted = sorted(p.name for p in where.iterdir())
        env = {k: v for k, v in os.environ.items() if k != "SNAKEBOT_PORT"}
        env.update({k: v for k, v in ENV.items() if v is not None}, OPENBLAS_NUM_THREADS="1")
        run = _run_limited(args, where, env)
        err = run.stderr
        assert "Traceback" not in err and INTERNAL_ERROR not in err, (args, err)
        assert "MemoryError" not in err, (args, err)
        assert outside.read_bytes() == PRECIOUS, args  # never written through the link
        always_bad = kind != "number" or bad in NEVER_NUMBERS
        if kind == "input" and bad == "outside-link":
            always_bad = False  # reading through a link is allowed; it is not a valid file
        if always_bad:
            assert run.returncode == 2, (args, run.returncode, err)
        assert run.returncode in (0, 1, 2), (args, run.returncode, err)
        if run.returncode:
            assert ERROR_LINE.match(err.strip().splitlines()[-1]), (args, err)
            assert_bounded(err.splitlines())
            left = sorted(p.name for p in where.iterdir())
            assert left == planted, (args, left)  # a refusal writes nothing


# -- huge values: the error line stays short ----------------------------------------------

HUGE_VALUES = [
    ",".join(["0.5"] * 10_000),  # a list of 10,000 numbers
    "9" * 20_000,  # one number of 20,000 digits
    "x " * 10_000,  # words: no run to shorten, the line's middle goes
    "/tmp/" + "d" * 20_000,  # a path far beyond PATH_MAX
    "ab\n" * 5_000,  # many lines
]
VALUED = [
    (path, command, param)
    for path, command in COMMANDS
    for param in command.params
    if not (isinstance(param, click.Option) and (param.is_flag or param.opts[0] in SLOW_FLAGS))
    and param.name != "help"
]


@st.composite
def huge_cases(draw: st.DrawFn) -> list[str]:
    """A command's required parameters with usual values, one parameter a huge value."""
    path, command, target = draw(st.sampled_from(VALUED))
    return _with_one_bad(draw, path, command, target, draw(st.sampled_from(HUGE_VALUES)))


@FUZZ
@given(args=huge_cases())
def test_huge_values_give_one_bounded_error_line(args: list[str]) -> None:
    with tempfile.TemporaryDirectory() as tmp, _cwd(Path(tmp)):
        result = invoke(args)
    check(result)  # one line `error: ...` of at most LINE_LIMIT characters


# -- serving commands: hostile input, then SIGTERM ------------------------------------------

SERVER_ARGS = {
    ("sim", "bus"): ["--json"],
    ("sim", "bootloader"): ["--json"],
    ("sim", "serve"): ["--json", "--report", "0", "--robot", "snake3"],
}
"""The serving commands and what every case of each gives: --json, whose first line says
it serves; a small robot (`sim bus` serves one servo by default)."""
SERVED_LINK = "served-link"
"""The --link a case gives when it does not fuzz the path options: made, then removed."""
FRESH = "fresh"
"""A path nothing is at: a --link or --unix made there is removed on SIGTERM; a --state
file is written there."""
PATH_OPTIONS = {"--link", "--unix", "--state"}
HOSTILE_SPECS = {
    "--brownout": ["1@nan+1", "1@1e400+1", "1@0+inf", "x@0+1", "1@0+1" * 4000],
    "--sim-options": ["brownout=10@nan+1", "corrupt=nan", "seed=1e400", "ids=" + "1," * 9000],
}
"""Fault specifications no server takes (NaN, infinite or unreadable times, a huge list)."""
SERVABLE = {"number": ["0", "1"], "path": [FRESH], "--brownout": ["1@0.1+0.1"]}
SERVABLE["--sim-options"] = ["corrupt=0.01&seed=3"]
"""Values a server may take, so that some cases serve and are stopped by SIGTERM."""
SERVING_EXAMPLES = max(4, EXAMPLES // 8)


def _serving_kind(param: click.Parameter) -> str | None:
    name = param.opts[0] if isinstance(param, click.Option) else ""
    if name in PATH_OPTIONS:
        return "path"
    if name in HOSTILE_SPECS:
        return "spec"
    return _kind(param)


SERVING_TARGETS = {
    path: [(command, p, kind) for p in command.params if (kind := _serving_kind(p))]
    for path, command in _leaves(main)
    if path in SERVER_ARGS
}


@st.composite
def serving_cases(draw: st.DrawFn, servers: tuple[tuple[str, ...], ...]) -> tuple:
    """(arguments, the hostile value, whether no server may take it): one of ``servers``
    with one file, path, number or fault parameter given a hostile value."""
    path = draw(st.sampled_from(servers))
    command, target, kind = draw(st.sampled_from(SERVING_TARGETS[path]))
    name = target.opts[0]
    pool = {
        "input": HOSTILE_FILES,
        "output": HOSTILE_OUTPUTS,
        "number": HOSTILE_NUMBERS,
        "path": HOSTILE_FILES,
        "spec": HOSTILE_SPECS.get(name, []),
    }[kind]
    servable = SERVABLE.get(name if kind == "spec" else kind, [])
    bad = draw(st.sampled_from(pool + servable))
    args = _with_one_bad(draw, path, command, target, bad)
    args[len(path) : len(path)] = SERVER_ARGS[path]  # before it: the case's value wins
    linked = any(p.opts[0] == "--link" for p in command.params if isinstance(p, click.Option))
    if linked and name not in ("--link", "--unix"):
        args += ["--link", SERVED_LINK]  # a path it makes, to be removed when it stops
    always_bad = (
        bad not in servable
        and {
            "number": bad in NEVER_NUMBERS,
            "input": bad != "outside-link",  # reading through a link is allowed
            "output": True,
            "path": name != "--state" or bad != "outside-link",  # --link, --unix: never replaced
            "spec": True,
        }[kind]
    )
    return args, bad, always_bad


def _first_line(proc: subprocess.Popen[bytes], timeout: float) -> bool | None:
    """True once ``proc`` printed its first line (it serves), False if it ended first,
    None if neither within ``timeout`` s."""
    assert proc.stdout is not None
    fd, seen, deadline = proc.stdout.fileno(), b"", time.monotonic() + timeout
    while b"\n" not in seen:
        left = deadline - time.monotonic()
        if left <= 0:
            return None
        if select.select([fd], [], [], left)[0]:
            chunk = os.read(fd, 4096)
            if not chunk:
                return False
            seen += chunk
    return True


def _serve_limited(args: list[str], where: Path, env: dict[str, str]) -> tuple[int, str, bool]:
    """``snakebot ARGS`` in ``where`` under the case's limits, given SIGTERM once it serves:
    (its exit status, its stderr, whether it served). Like :func:`_run_limited`, a case
    that neither serves nor ends in CASE_TIMEOUT_S is tried again with three times as long
    before it counts as a hang; so is one that does not stop on SIGTERM."""
    for timeout in (CASE_TIMEOUT_S, 3 * CASE_TIMEOUT_S):
        proc = subprocess.Popen(
            [sys.executable, "-m", "snakebot", *args],
            cwd=where,
            env=env,
            stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            preexec_fn=_limits,
            start_new_session=True,  # its QEMU too, to kill all of it if it hangs
        )
        try:
            served = _first_line(proc, timeout)
            if served is None:
                continue
            if served:
                proc.send_signal(signal.SIGTERM)
            _, err = proc.communicate(timeout=timeout)
            return proc.returncode, err.decode(errors="replace"), served
        except subprocess.TimeoutExpired:
            continue
        finally:
            if proc.poll() is None:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.communicate()
    pytest.fail(f"snakebot {' '.join(args)}: neither served nor ended, or did not stop, twice")


def _check_serving_case(case: tuple) -> None:
    args, bad, always_bad = case
    with (
        tempfile.TemporaryDirectory() as tmp,
        tempfile.TemporaryDirectory() as far,
        tempfile.TemporaryDirectory() as scratch,
    ):
        where, outside = Path(tmp), Path(far) / "target"
        outside.write_bytes(PRECIOUS)
        _plant(where, outside)
        planted = sorted(p.name for p in where.iterdir())
        runtime, temp = Path(scratch) / "run", Path(scratch) / "tmp"
        runtime.mkdir(mode=0o700), temp.mkdir()
        env = {k: v for k, v in os.environ.items() if k != "SNAKEBOT_PORT"}
        env.update({k: v for k, v in ENV.items() if v is not None}, OPENBLAS_NUM_THREADS="1")
        env.update(XDG_RUNTIME_DIR=str(runtime), TMPDIR=str(temp))  # to see what is left
        status, err, served = _serve_limited(args, where, env)
        lines = err.strip().splitlines()
        assert "Traceback" not in err and INTERNAL_ERROR not in err, (args, err)
        assert "MemoryError" not in err, (args, err)
        assert outside.read_bytes() == PRECIOUS, args  # never written through the link
        if served:  # then SIGTERM: a clean stop
            assert not always_bad, (args, "served with a value it must refuse", err)
            assert status == 143 and lines[-1:] == ["interrupted"], (args, status, err)
        else:  # refused up front
            assert status == 2 if always_bad else status in (1, 2), (args, status, err)
            assert len(lines) == 1 and ERROR_LINE.match(lines[0]), (args, err)
            assert_bounded(lines)
        left = sorted(p.name for p in where.iterdir() if p.name != FRESH or "--state" not in args)
        assert left == planted, (args, left)  # no link or socket left, no other file written
        assert not list(temp.iterdir()), (args, list(temp.iterdir()))  # no work directory
        records = runtime / "snakebot-links"
        assert not records.exists() or not list(records.iterdir()), (args, "a claim is left")


@settings(FUZZ, max_examples=SERVING_EXAMPLES)
@given(case=serving_cases((("sim", "bus"), ("sim", "bootloader"))))
def test_hostile_input_to_a_server_is_refused_or_served_until_sigterm(case) -> None:
    _check_serving_case(case)


@pytest.mark.qemu
@pytest.mark.skipif(not default_firmware().is_file(), reason="needs `make firmware`")
@settings(FUZZ, max_examples=max(2, SERVING_EXAMPLES // 2))
@given(case=serving_cases((("sim", "serve"),)))
def test_hostile_input_to_sim_serve_is_refused_or_served_until_sigterm(case) -> None:
    _check_serving_case(case)
