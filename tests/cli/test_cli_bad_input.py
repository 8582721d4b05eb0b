"""Bad input on the command line ends in one line `error: ...` and exit 2, never in a
traceback or a hang (issue #17: every case below once did)."""

from __future__ import annotations

import json
import os
import pty
import re
import signal
import subprocess
import sys
import tty
import zlib
from pathlib import Path

import click
import pytest
from click.testing import CliRunner
from flash_support import make_image

from snakebot.cli import main
from snakebot.cli.params import RobotType
from snakebot.cli.troubleshooting import ERROR_LINE
from snakebot.errors import LINE_LIMIT
from snakebot.link.flash.image import identity_block
from snakebot.model.robots import load_robot

pytestmark = pytest.mark.timeout(60)

SERPENOID = ["gait", "serpenoid", "snake3", "-A", "20deg", "-w", "90deg", "-d", "90deg"]
EMULATED_CONTROLLER = "sim://?robot=snake3"  # no controller behind a bus: refused, exit 2


def run(*args: object, input: str | None = None):
    return CliRunner().invoke(main, [str(a) for a in args], input=input)


def assert_one_line_error(result, code: int = 2, mentions: str = "") -> str:
    """The run ended in exit ``code`` with exactly one line `error: ...` on stderr."""
    assert result.exception is None or isinstance(result.exception, SystemExit), repr(
        result.exception
    )
    assert "Traceback" not in result.output
    assert result.exit_code == code, (result.exit_code, result.output)
    lines = [line for line in result.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and ERROR_LINE.match(lines[0]), result.stderr
    assert mentions.lower() in lines[0].lower(), lines[0]
    return lines[0]


@pytest.fixture
def gait_file(tmp_path: Path) -> Path:
    out = tmp_path / "walk.gait"
    result = run(*SERPENOID, "--cycles", "1", "-o", out)
    assert result.exit_code == 0, result.output
    return out


def _sidecar(gait: Path) -> Path:
    return gait.with_name(gait.name + ".json")


# -- gait sidecars -------------------------------------------------------------------------


def test_sidecar_crc_as_a_string(gait_file: Path) -> None:
    doc = json.loads(_sidecar(gait_file).read_text())
    doc["table"]["crc32"] = "0x1234"
    _sidecar(gait_file).write_text(json.dumps(doc))
    assert_one_line_error(run("gait", "show", gait_file), mentions="crc32")


def test_sidecar_nested_100000_deep(gait_file: Path) -> None:
    _sidecar(gait_file).write_text("[" * 100_000 + "]" * 100_000)
    assert_one_line_error(run("gait", "show", gait_file), mentions=str(_sidecar(gait_file)))


@pytest.mark.parametrize(
    "key, value",
    [("parameters", 5), ("predicted", "far"), ("table", [1, 2]), ("gait", {"x": 1})],
)
def test_sidecar_metadata_of_the_wrong_type(gait_file: Path, key: str, value: object) -> None:
    doc = json.loads(_sidecar(gait_file).read_text())
    doc["metadata"][key] = value
    _sidecar(gait_file).write_text(json.dumps(doc))
    assert_one_line_error(run("gait", "show", gait_file), mentions=key)


def test_sidecar_never_overrides_what_the_table_says(gait_file: Path) -> None:
    truth = json.loads(run("gait", "show", gait_file, "--json").stdout)
    doc = json.loads(_sidecar(gait_file).read_text())
    doc["metadata"].update(
        {"header_crc": "0x0", "file_crc32": "0xDEADBEEF", "bytes": 1, "frames": 7, "loop": False}
    )
    _sidecar(gait_file).write_text(json.dumps(doc))
    result = run("gait", "show", gait_file, "--json")
    assert result.exit_code == 0, result.output
    shown = json.loads(result.stdout)
    for key in ("header_crc", "file_crc32", "bytes", "frames", "loop"):
        assert shown[key] == truth[key]


def test_show_labels_the_header_crc_and_the_file_crc(gait_file: Path) -> None:
    result = run("gait", "show", gait_file)
    assert result.exit_code == 0, result.output
    first = result.stdout.splitlines()[0]
    data = gait_file.read_bytes()
    assert f"file CRC-32 0x{zlib.crc32(data):08X}" in first, first
    header_crc = int.from_bytes(data[12:16], "little")
    assert f"header CRC 0x{header_crc:08X}" in first, first


# -- unbounded reads -----------------------------------------------------------------------


@pytest.mark.parametrize(
    "args",
    [
        ["gait", "show", "/dev/zero"],
        ["upload", "/dev/zero", "--port", "loop://"],
        ["flash", "/dev/zero", "--port", "loop://", "--force"],
    ],
    ids=["gait-show", "upload", "flash"],
)
def test_dev_zero_is_refused_without_reading_it_all(args: list[str]) -> None:
    # Not read at all since issue #28: a device is not a file (it may never end).
    assert_one_line_error(run(*args), mentions="'/dev/zero' is a FIFO, a device or a socket")


# -- output paths --------------------------------------------------------------------------


def test_plot_with_an_unknown_extension(gait_file: Path, tmp_path: Path) -> None:
    assert_one_line_error(
        run("gait", "show", gait_file, "--plot", tmp_path / "x.xyz"), mentions="xyz"
    )
    assert not (tmp_path / "x.xyz").exists()


def test_empty_output_path(tmp_path: Path) -> None:
    assert_one_line_error(run(*SERPENOID, "--cycles", "1", "-o", ""), mentions="output")


def test_output_files_follow_the_umask(tmp_path: Path) -> None:
    old = os.umask(0o022)
    try:
        out = tmp_path / "u.gait"
        assert run(*SERPENOID, "--cycles", "1", "-o", out).exit_code == 0
        state = tmp_path / "eeprom.json"  # the emulator's servo state file
        assert run("bus", "ping", "1", "--port", f"sim://?ids=1&state={state}").exit_code == 0
    finally:
        os.umask(old)
    for written in (out, _sidecar(out), state):
        assert written.stat().st_mode & 0o777 == 0o644, written


# -- robot TOML ----------------------------------------------------------------------------


def _robot_text(**replace: str) -> str:
    from importlib import resources

    text = resources.files("snakebot.model.robots").joinpath("snake3.toml").read_text()
    for old, new in replace.items():
        assert old in text
        text = text.replace(old, new, 1)
    return text


def _show_robot(tmp_path: Path, data: bytes):
    path = tmp_path / "r.toml"
    path.write_bytes(data)
    return run("model", "info", path)


def test_robot_toml_not_utf8(tmp_path: Path) -> None:
    assert_one_line_error(_show_robot(tmp_path, b'name = "\xff\xfe"\n'), mentions="UTF-8")


def test_robot_toml_geometry_as_an_array(tmp_path: Path) -> None:
    text = re.sub(r"\[geometry\][^\[]*", "geometry = [1, 2]\n", _robot_text(), count=1)
    assert_one_line_error(_show_robot(tmp_path, text.encode()), mentions="geometry")


def test_robot_toml_absurd_limits(tmp_path: Path) -> None:
    text = re.sub(r"min_deg\s*=\s*[-0-9.]+", "min_deg = -1e307", _robot_text(), count=1)
    text = re.sub(r"max_deg\s*=\s*[-0-9.]+", "max_deg = 1e307", text, count=1)
    assert_one_line_error(_show_robot(tmp_path, text.encode()), mentions="min_deg")


def test_robot_toml_unknown_key_says_did_you_mean(tmp_path: Path) -> None:
    text = _robot_text(**{"half_link": "half_lenk"})
    line = assert_one_line_error(_show_robot(tmp_path, text.encode()), mentions="half_lenk")
    assert "did you mean 'half_link'" in line


def test_robot_toml_servo_faster_than_its_datasheet(tmp_path: Path) -> None:
    text = _robot_text() + "\n"
    if "[servo]" in text:
        text = re.sub(r"\[servo\]", "[servo]\nmax_speed_rpm = 70", text, count=1)
    else:
        text += '[servo]\nmodel = "AX-12A"\nmax_speed_rpm = 70\n'
    line = assert_one_line_error(_show_robot(tmp_path, text.encode()), mentions="max_speed_rpm")
    assert "59" in line  # the AX-12A's datasheet figure it exceeds


def commands_with_a_robot_option() -> list[tuple[list[str], list[str]]]:
    """The command path of every command with --robot, -r (``robot_option``), and a
    --port if it has one (a port that opens: the robot must be refused before it)."""
    found = []

    def walk(cmd: click.Command, path: list[str]) -> None:
        if isinstance(cmd, click.Group):
            ctx = click.Context(cmd)
            for name in cmd.list_commands(ctx):
                walk(cmd.get_command(ctx, name), [*path, name])  # type: ignore[arg-type]
        elif any(isinstance(p.type, RobotType) for p in cmd.params):
            port = [p for p in cmd.params if p.name == "port"]
            found.append((path, ["--port", "loop://"] if port else []))

    walk(main, [])
    return found


def test_every_robot_option_refuses_a_bad_robot_while_parsing(tmp_path: Path) -> None:
    """Also `bus play` and `monitor`, which use --robot only with another option: the
    robot is checked before the port, the files or the arguments."""
    commands = commands_with_a_robot_option()
    paths = [path for path, _ in commands]
    assert ["monitor"] in paths and ["bus", "play"] in paths and len(paths) >= 8
    fifo = tmp_path / "robot.toml"
    os.mkfifo(fifo)  # not a file: refused without being opened (a FIFO would block)
    for command, port in commands:
        for robot in ("snake4", str(fifo)):
            result = run(*command, "--robot", robot, *port)
            line = assert_one_line_error(result, mentions=f"no robot {robot!r}")
            assert "--robot" in line, line


# -- numbers -------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "extra",
    [
        ["--cycles", "1e308"],
        ["--cycles", "nan"],
        ["--cycles", "1", "--rate", "inf"],
    ],
)
def test_serpenoid_absurd_numbers(tmp_path: Path, extra: list[str]) -> None:
    args = [*SERPENOID, *extra, "-o", tmp_path / "x.gait"]
    assert_one_line_error(run(*args))
    assert not (tmp_path / "x.gait").exists()


@pytest.mark.parametrize(
    "option, value",
    [("-w", "1e-320"), ("-A", "9" * 400), ("-A", "-" * 5000 + "1")],
    ids=["tiny-omega", "400-digits", "5000-minus"],
)
def test_serpenoid_absurd_angles(tmp_path: Path, option: str, value: str) -> None:
    args = [
        "gait",
        "serpenoid",
        "snake3",
        "-A",
        "20deg",
        "-w",
        "90deg",
        "-d",
        "90deg",
        "--cycles",
        "1",
        option,
        value,
        "-o",
        tmp_path / "x.gait",
    ]
    assert_one_line_error(run(*args))
    assert not (tmp_path / "x.gait").exists()


@pytest.mark.parametrize(
    "args",
    [
        ["play", "--speed", "nan"],
        ["monitor", "--duration", "nan"],
        ["monitor", "--interval", "nan"],
        ["serpenoid", "-A", "1", "-w", "1", "-d", "1", "--speed", "inf"],
    ],
)
def test_controller_commands_refuse_non_finite_numbers(args: list[str]) -> None:
    # Refused while parsing: the port (nothing behind it) is never opened.
    assert_one_line_error(run(*args, "--port", "/dev/nonexistent-port"), mentions="finite")


@pytest.mark.parametrize("command", [["library", "play", "0"], ["stop"], ["monitor"]])
def test_a_pc_link_slower_than_any_dynamixel_rate_is_refused_at_once(command: list[str]) -> None:
    # The CLI fuzz found `library play 0 --port loop:// --baud 1`: a reply's timeout scales
    # with the byte time, so it waited 200 s for an answer that could never come.
    result = run(*command, "--port", "loop://", "--baud", "1")
    assert_one_line_error(result, mentions="slower than any Dynamixel")
    assert run("stop", "--port", "loop://", "--baud", "9600").exit_code == 1  # nominal 9600 ok


@pytest.mark.parametrize("baud", ["2147483648", "9" * 300])
def test_a_baud_beyond_any_dynamixel_rate_is_refused_at_once(pty_device: str, baud: str) -> None:
    # The CLI fuzz found `bus ping --baud 99...9` (300 digits) ending in an internal error
    # (OverflowError: the rate compared as a float); on a real port the PC link's --baud
    # reached the operating system, which refused the number in the same way.
    assert_one_line_error(run("bus", "ping", "1", "--port", pty_device, "--baud", baud))
    result = run("monitor", "--port", pty_device, "--baud", baud, "--duration", "0.1")
    assert_one_line_error(result, mentions="faster than any Dynamixel")


@pytest.mark.parametrize(
    "args",
    [
        ["bus", "scan", "--port", "sim://?ids=1", "--bauds", "1,2,3"],
        ["doctor", "--port", "sim://?ids=1,2", "--ids", "1-3", "--bauds", "1,2,3"],
        ["bus", "scan", "--port", "sim://?ids=1", "--bauds", "1e400"],
    ],
)
def test_scan_rates_no_servo_runs_at_are_refused_at_once(args: list[str]) -> None:
    # The CLI fuzz found `doctor --bauds 1,2,3` waiting two minutes per unanswered PING.
    assert_one_line_error(run(*args))


def test_an_output_that_is_a_pipe_or_device_is_refused_and_left_alone(tmp_path: Path) -> None:
    # `-o /dev/zero` once replaced the device with a regular file (written beside it and
    # moved over it).
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    assert_one_line_error(run(*SERPENOID, "--cycles", "1", "-o", fifo), mentions="not a file")
    assert fifo.is_fifo() and not (tmp_path / "pipe.json").exists()


def test_monitor_without_a_controller_removes_only_files_it_created(tmp_path: Path) -> None:
    # `monitor --csv /dev/zero` with no controller once unlinked /dev/zero.
    mine, new = tmp_path / "mine.csv", tmp_path / "new.mcap"
    mine.write_text("the user's\n")
    result = run("monitor", "--port", "loop://", "--csv", mine, "--mcap", new)
    assert result.exit_code == 1, result.output
    assert mine.exists() and not new.exists()


# -- the emulator's options -----------------------------------------------------------------


def test_sim_state_file_holding_a_list(tmp_path: Path) -> None:
    state = tmp_path / "state.json"
    state.write_text("[]")
    result = run("bus", "scan", "--port", f"sim://?ids=1&state={state}", "--ids", "1")
    assert_one_line_error(result, mentions=str(state))


def test_documented_brownout_in_a_sim_url_with_a_plus() -> None:
    from snakebot.sim.options import SimOptions

    options = SimOptions.from_query("ids=10&brownout=10@5+1")
    (brownout,) = options.faults.brownouts
    assert (brownout.servo_id, brownout.start_s, brownout.duration_s) == (10, 5.0, 1.0)


def test_sim_url_brownout_is_accepted_by_a_command() -> None:
    result = run("bus", "ping", "1", "--port", "sim://?ids=1&brownout=1@50+1", "--json")
    assert result.exit_code == 0, result.output


# -- JSON ----------------------------------------------------------------------------------


def test_json_output_never_holds_nan(gait_file: Path) -> None:
    doc = json.loads(_sidecar(gait_file).read_text())
    doc["metadata"]["note"] = 1e308 * 10  # json.dumps writes Infinity
    _sidecar(gait_file).write_text(json.dumps(doc))
    result = run("gait", "show", gait_file, "--json")
    text = result.stdout
    assert "Infinity" not in text and "NaN" not in text
    if result.exit_code == 0:
        json.loads(text, parse_constant=lambda c: pytest.fail(f"{c} in JSON output"))
    else:
        assert_one_line_error(result)


# -- exit codes, pipes ---------------------------------------------------------------------


def _cli(*args: str, timeout: float = 60, **kwargs) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "snakebot", *args],
        capture_output=True,
        text=True,
        timeout=timeout,
        **kwargs,
    )


def test_runtime_failure_exits_1_usage_error_exits_2() -> None:
    usage = _cli("gait", "serpenoid", "snake3", "--bogus")
    assert usage.returncode == 2 and "Traceback" not in usage.stderr
    # A controller that does not answer is a runtime failure, not bad input.
    master, slave = pty.openpty()  # a port with nobody behind it
    tty.setraw(slave)
    try:
        env = {**os.environ, "SNAKEBOT_RETRIES": "0"}
        runtime = _cli("stop", "--port", os.ttyname(slave), timeout=120, env=env)
    finally:
        os.close(master)
        os.close(slave)
    assert runtime.returncode == 1, runtime.stderr
    assert runtime.stderr.startswith("error[E301]: ") and "Traceback" not in runtime.stderr


@pytest.mark.parametrize(
    "args, server",
    [
        (["monitor"], "snakebot sim serve"),
        (["upload", "x.gait"], "snakebot sim serve"),
        (["flash", "x.bin"], "snakebot sim bootloader"),
    ],
)
def test_controller_commands_on_a_servo_bus_say_what_to_run(args: list[str], server: str) -> None:
    line = assert_one_line_error(run(*args, "--port", "sim://?robot=snake5"))
    assert f"run `{server}`" in line


def test_broken_pipe_is_quiet() -> None:
    # The reader is gone before the command prints anything (as `snakebot ... | head`
    # once head has had its lines).
    proc = subprocess.Popen(
        [sys.executable, "-m", "snakebot", "bus", "read", "1", "--port", "sim://?ids=1"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    assert proc.stdout is not None and proc.stderr is not None
    proc.stdout.close()
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=60) == 141
    assert err == "", err


def test_the_builtin_robots_still_load() -> None:
    for name in ("snake3", "snake5", "trident"):
        assert load_robot(name).joints


def test_ctrl_c_exits_130(tmp_path: Path) -> None:
    image = tmp_path / "fw.bin"
    image.write_bytes(bytes(1024))
    master, slave = pty.openpty()  # a board that never answers: flash waits for RESET
    tty.setraw(slave)
    try:
        proc = subprocess.Popen(
            [sys.executable, "-m", "snakebot", "flash", str(image), "--force"]
            + ["--port", os.ttyname(slave), "--reset-timeout", "60"],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        assert proc.stdout is not None and proc.stdout.readline().startswith("Flashing")
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=60)
    finally:
        os.close(master)
        os.close(slave)
    assert proc.returncode == 130, err
    assert err.strip().splitlines()[-1] == "interrupted" and "Traceback" not in err


# -- issue #28: inputs that hung or were "internal errors" ---------------------------------


@pytest.mark.parametrize(
    ("args", "mentions"),
    [
        ([*SERPENOID, "-A", "(-8)**0.5", "--cycles", "1", "-o", "x.gait"], "not a real number"),
        (["gait", "field", "trident", "--field", "2*g1-h3", "--tolerance", "1e-300"], "0.001"),
        (["config", "--port", "loop://", "set", "link-timeout", "1e400s"], "out of range"),
        (["bus", "ping", "1", "--port", "sim://?robot=snake5&brownout=10@nan+1"], "brownout"),
        (["gait", "search", "snake3", "--param", "A=0.1:0.5:1000000"], "COUNT must be at most"),
        (
            ["gait", "search", "snake3", "--param", "A=0.1:0.5:1000", "--param", "d=0.1:1:1000"]
            + ["--param", "w=3"],
            "1,000,000 runs",
        ),
        (["gait", "search", "snake3", "--samples", "100000000000"], "--samples"),
        (["gait", "search", "snake3", "--workers", "100000"], "--workers"),
        (["sim", "predict", "x.gait", "--world-rate", "1e9"], "--world-rate"),
    ],
    ids=[
        "complex",
        "tolerance",
        "link-timeout",
        "brownout-nan",
        "count",
        "grid",
        "samples",
        "workers",
        "world-rate",
    ],
)
def test_hostile_numbers_are_one_line_exit_2(args, mentions, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert_one_line_error(run(*args), mentions=mentions)


def test_too_many_friction_values_are_refused_in_one_short_line(gait_file: Path) -> None:
    mu = ",".join(str(0.01 * (i + 1)) for i in range(10_000))  # 68 KB of values
    line = assert_one_line_error(run("sim", "friction", gait_file, "--mu", mu), mentions="--mu")
    assert "10,000 friction coefficients, at most 50" in line, line
    assert len(line) <= LINE_LIMIT, len(line)  # it quoted all 68 KB back
    assert f"({len(mu):,} characters)" in line and line.count("0.01") == 1, line


@pytest.mark.parametrize("nest", ["[", "{b = "])
def test_a_toml_nested_5000_deep_is_exit_2(tmp_path: Path, nest: str) -> None:
    close = "]" if nest == "[" else "}"
    deep = tmp_path / "deep.toml"
    deep.write_text("a = " + nest * 5000 + ("" if nest == "[" else "1") + close * 5000 + "\n")
    assert_one_line_error(run("model", "info", deep), mentions="5000 deep")
    assert_one_line_error(
        run("program", "build", deep, "-o", tmp_path / "p.prog"), mentions="5000 deep"
    )


@pytest.mark.parametrize(("board", "says"), [("cm530", "is empty"), ("qemu", "neither an ELF")])
def test_an_empty_firmware_for_the_emulator_is_one_line(tmp_path: Path, board, says) -> None:
    empty = tmp_path / "empty.bin"
    empty.write_bytes(b"")
    assert_one_line_error(run("sim", "serve", "--board", board, "--firmware", empty), mentions=says)


@pytest.mark.parametrize(("board", "built_for"), [("cm530", "qemu"), ("qemu", "cm530")])
def test_an_image_for_the_other_board_is_refused_before_it_runs(
    tmp_path: Path, board: str, built_for: str
) -> None:
    image = tmp_path / "app.bin"
    make_image(image, 4096)  # a plausible application image, its identity block the CM-530's
    if built_for != "cm530":
        data = bytearray(image.read_bytes())
        block = identity_block("cm530", 1, len(data))
        at = data.index(block)
        data[at : at + len(block)] = identity_block(built_for, 1, len(data))
        image.write_bytes(bytes(data))
    for command in (["sim", "serve"], ["demo", "--out", tmp_path / "out"]):
        result = run(*command, "--board", board, "--firmware", image)
        line = assert_one_line_error(result, mentions=f"built for the {built_for} board")
        assert line.startswith("error: --firmware: ")
    assert not (tmp_path / "out").exists()  # the demo wrote no gait table


@pytest.mark.parametrize(
    "args",
    [
        ["bus", "play", "{fifo}", "--port", "loop://"],
        ["library", "restore", "{fifo}", "--port", "loop://"],
        ["drive", "--script", "{fifo}", "--port", "loop://"],
        ["flash", "{fifo}", "--port", "loop://", "--force"],
        ["upload", "{fifo}", "--port", "loop://"],
        ["gait", "show", "{fifo}"],
    ],
    ids=["bus-play", "library-restore", "drive-script", "flash", "upload", "gait-show"],
)
def test_a_fifo_as_input_is_refused_without_blocking(tmp_path: Path, args: list[str]) -> None:
    fifo = tmp_path / "in.fifo"
    os.mkfifo(fifo)
    result = run(*[a.format(fifo=fifo) for a in args])  # the module's timeout catches a hang
    assert_one_line_error(result, mentions="not a file")


def test_a_state_file_that_is_a_fifo_is_refused(tmp_path: Path) -> None:
    fifo = tmp_path / "state.json"
    os.mkfifo(fifo)
    result = run("bus", "ping", "1", "--port", f"sim://?ids=1&state={fifo}")
    assert_one_line_error(result, mentions="not a file")


def test_library_restore_of_dev_zero_reads_nothing(tmp_path: Path) -> None:
    assert_one_line_error(run("library", "restore", "/dev/zero", "--port", "loop://"))


def test_demo_with_a_missing_firmware_leaves_no_gait(tmp_path: Path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    assert_one_line_error(run("demo", "--firmware", "/nonexistent"), mentions="not found")
    assert not (tmp_path / "out").exists()


# -- a QEMU that does not run (issue #28) --------------------------------------------------

QEMU_COMMANDS = {
    "sim serve": ["sim", "serve", "--board", "qemu", "--robot", "snake3", "--report", "0"],
    "demo": ["demo", "--board", "qemu", "--world", "kinematic", "--cycles", "1"],
}


def _with_qemu(qemu: str, command: str, out: Path) -> tuple[int, str]:
    args = QEMU_COMMANDS[command] + (["--out", str(out)] if command == "demo" else [])
    result = CliRunner().invoke(main, args, env={"SNAKEBOT_QEMU": qemu})
    return result.exit_code, result.stderr


@pytest.mark.skipif(not Path("/bin/false").exists(), reason="needs /bin/false")
@pytest.mark.parametrize("command", QEMU_COMMANDS)
def test_a_qemu_that_starts_and_dies_is_a_runtime_failure_in_one_line(tmp_path, command):
    from snakebot.sim.qemu import DEFAULT_IMAGE

    if not DEFAULT_IMAGE.is_file():
        pytest.skip("needs `make firmware`")
    status, err = _with_qemu("/bin/false", command, tmp_path / "out")
    assert status == 1, err
    assert err.count("\n") == 1 and err.startswith(
        "error[E502]: QEMU (/bin/false) exited at start-up"
    )
    assert "point SNAKEBOT_QEMU at one that does" in err and "internal error" not in err


@pytest.mark.parametrize("command", QEMU_COMMANDS)
@pytest.mark.parametrize("qemu", ["missing", "not executable"])
def test_a_qemu_setting_that_is_no_program_is_bad_input(tmp_path, command, qemu):
    path = tmp_path / "qemu-system-arm"
    if qemu == "not executable":
        path.write_text("#!/bin/sh\n")
        path.chmod(0o644)
    status, err = _with_qemu(str(path), command, tmp_path / "out")
    assert status == 2, err
    assert err == (
        f"error: SNAKEBOT_QEMU={str(path)!r} is not an executable file, or a name on PATH; "
        "set it to the path of qemu-system-arm or unset it\n"
    )
    assert not (tmp_path / "out").exists()  # refused before any work


@pytest.mark.parametrize("planted", ["fifo", "/dev/zero"])
def test_bus_write_reads_its_robot_file_even_for_a_register_that_is_no_position(tmp_path, planted):
    # Found by the hostile-file fuzz case: `bus write 1 LED 1 --robot FIFO` wrote and
    # exited 0, the robot file never looked at.
    robot = tmp_path / "robot.toml" if planted == "fifo" else Path(planted)
    if planted == "fifo":
        os.mkfifo(robot)
    args = ["bus", "write", "1", "LED", "1", "--robot", str(robot), "--port", "sim://?ids=1"]
    result = CliRunner().invoke(main, args)
    assert result.exit_code == 2, result.output
    assert result.stderr.startswith("error: ") and result.stderr.count("\n") == 1


@pytest.mark.parametrize("register", ["007", "9" * 5000])
def test_a_register_address_int_cannot_read_is_bad_input(register: str) -> None:
    # both were "internal error": int(text, 0) refuses leading zeros and 4300 digits
    line = assert_one_line_error(
        run("bus", "write", "--port", "sim://?ids=1", "1", register, "1"),
        mentions="register starts at address",
    )
    assert len(line) <= LINE_LIMIT


@pytest.mark.parametrize("board", ["cm530", "qemu"])
def test_serve_refuses_servos_named_twice_as_bad_input(board: str) -> None:
    """The robot names the servos: `ids=` in the emulator options is bad input (exit 2)
    on either board, before anything starts (the CM-530 board said it with exit 1)."""
    result = run("sim", "serve", "--board", board, "--robot", "snake3", "--sim-options", "ids=1,1")
    assert_one_line_error(result, mentions="leave robot= and ids= out")
