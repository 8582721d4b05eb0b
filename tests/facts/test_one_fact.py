"""One fact, one place: no register address and no unit factor is typed in the Python or C
sources outside the device descriptions (host/snakebot/facts/devices), their generator
(protocol/gen_headers.py) and the headers it writes. Everything else reads them.

The facts looked for come from the descriptions themselves (every servo's scales, its
position and speed units in other units, the baud clock, the fixed-point constants the
generator emits), so a new device widens the net by itself. Only code is read: comments,
docstrings and message strings may explain a fact in words. The tests' support modules
are scanned; the tests themselves are not: they pin facts on purpose, as an
independent check of the data.
"""

from __future__ import annotations

import ast
import io
import math
import re
import tokenize
from functools import cache
from pathlib import Path

import pytest
from protocol_support import gen_headers

from snakebot.facts import devices
from snakebot.paths import REPO_ROOT

PYTHON_ROOTS = ("host", "bench", "tests/support", "tests/reliability/rig")
C_ROOTS = ("firmware", "fuzz")
EXCLUDED = (
    "host/snakebot/facts/devices/",
    "protocol/gen_headers.py",
    "firmware/core/ax12_table.h",
    "firmware/core/ctl_table.h",
)
REL_TOL = 1e-3
# Calls whose argument at this index is a control-table address (Protocol 1.0
# instructions in Python and in the firmware's packet builders), when given this many
# positional arguments (None: any).
PY_ADDRESS_ARGS = {
    "read": (1, 3),
    "write": (1, 3),
    "reg_write": (1, 3),
    "read_u8": (1, None),
    "read_u16": (1, None),
    "write_u8": (1, None),
    "write_u16": (1, None),
    "sync_write": (0, 3),
    # dynamixel-sdk's PacketHandler: (port, id, address, ...)
    **{f"{verb}{n}ByteTxRx": (2, None) for verb in ("read", "write") for n in (1, 2, 4)},
    **{f"{verb}{n}ByteTxOnly": (2, None) for verb in ("read", "write") for n in (1, 2, 4)},
}
C_ADDRESS_ARGS = {"dxl_read": 3, "dxl_write": 3, "dxl_reg_write": 3, "dxl_sync_write": 2}
MAX_ADDRESS = 255  # Protocol 1.0 addresses are one byte


def _macro(name: str) -> str:
    return re.sub(r"[^A-Z0-9]+", "_", name.upper()).strip("_")


@cache
def facts() -> dict[str, object]:
    """What to look for, derived from the descriptions."""
    servos = [devices.load(n) for n in devices.names("servo")]
    floats: dict[float, str] = {}
    for dev in servos:
        for key, scale in dev.scales.items():
            f = float(scale.factor)
            if len(f"{f:.6g}".replace(".", "").strip("0")) <= 2:
                continue  # 0.1 V, 2 us, 4.5 mA: too round to tell from any other number
            floats.setdefault(f, f"{dev.name} {key} factor")
            floats.setdefault(1 / f, f"{dev.name} per-{key} factor")
        pos = dev.require_position()
        for unit in ("deg", "rad"):
            floats.setdefault(pos.scale.factor_in(unit), f"{dev.name} {unit} per tick")
            floats.setdefault(pos.scale.per_unit(unit), f"{dev.name} ticks per {unit}")
        speed_ticks = dev.scale("speed").factor_in("deg/s") * pos.scale.per_unit("deg")
        floats.setdefault(speed_ticks, f"{dev.name} ticks/s per speed unit")
        rpm_ticks = devices.conversion("rpm", "deg/s") * pos.scale.per_unit("deg")
        floats.setdefault(rpm_ticks, f"{dev.name} ticks/s per rpm")
    ax = devices.ax12()
    low, high = ax.require_position().range
    ints = {high: "the AX-12 position/speed full scale"}
    ints |= {
        value: name for name, (value, _) in gen_headers().fixed_point(ax).items() if value > high
    }
    clocks = {dev.require_baud().clock_hz for dev in servos}
    registers: dict[str, set[int]] = {}
    for name in devices.names():
        for reg in devices.load(name):
            registers.setdefault(_macro(reg.name), set()).add(reg.address)
    return {
        "floats": floats,
        "ints": ints,
        "clocks": clocks,
        "direction": 1 << ax.register("Present Speed").encoding.direction_bit,
        "span": (high, round(ax.require_position().span_deg)),
        "registers": registers,
    }


def _float_fact(value: float) -> str | None:
    for fact, what in facts()["floats"].items():
        if math.isclose(value, fact, rel_tol=REL_TOL):
            return what
        for digits in (2, 3):  # the rounded figures manuals print: 0.29 deg, 0.111 rpm
            if value == float(f"{fact:.{digits}g}") and value != round(value):
                return what
    return None


def _number_problem(text: str) -> str | None:
    """Why the numeric literal ``text`` is a typed fact, or None."""
    clean = text.replace("_", "").rstrip("uUlL")
    try:
        value = int(clean, 0)
    except ValueError:
        try:
            value = float(clean)
        except ValueError:
            return None
        what = _float_fact(value)
        return f"{text} is the {what}" if what else None
    f = facts()
    if value in f["ints"]:
        return f"{text} is {f['ints'][value]}"
    if clean.lower().startswith("0x") and value in (f["direction"], f["direction"] - 1):
        return f"{text} is the direction bit or its magnitude mask"
    return None


def _pattern_problems(code: str) -> list[str]:
    """Facts written as expressions: the baud formula, ticks over degrees, bit 10."""
    f = facts()
    problems = []
    for clock in f["clocks"]:
        digits = "_?".join(re.findall(r"\d{1,3}", f"{clock:,}".replace(",", " ")))
        if re.search(rf"\b{digits}(?:\.0*)?[uUlL]*\s*/", code):
            problems.append(f"the baud formula's clock {clock}")
    ticks, degrees = f["span"]
    wrap = r"(?:\w+\.)?(?:radians|deg2rad)\(\s*"
    over = rf"\b(?:{ticks}|{ticks + 1})(?:\.0*)?\s*/\s*(?:{wrap})?{degrees}\b"
    under = rf"\b{degrees}(?:\.0*)?\s*/\s*(?:{ticks}|{ticks + 1})\b"
    if re.search(over, code) or re.search(under, code):
        problems.append(f"a ratio of {ticks} ticks to {degrees} degrees")
    bit = facts()["direction"].bit_length() - 1
    if re.search(rf"\b1\s*<<\s*{bit}\b", code):
        problems.append(f"the direction bit 1 << {bit}")
    return problems


def _register_problem(name: str, value: object) -> str | None:
    """Why ``name = value`` types a register address, or None."""
    if not isinstance(value, int) or isinstance(value, bool) or not 0 <= value <= MAX_ADDRESS:
        return None
    upper = name.upper()
    if re.search(r"_ADDR(ESS)?$", upper):
        return f"{name} = {value} types an address"
    for macro, addresses in facts()["registers"].items():
        if value in addresses and (upper == macro or upper.endswith("_" + macro)):
            return f"{name} = {value} types the address of {macro}"
    return None


def python_problems(source: str) -> list[tuple[int, str]]:
    """(line, problem) for every fact typed in Python ``source``."""
    problems: list[tuple[int, str]] = []
    lines = source.splitlines()
    for tok in tokenize.generate_tokens(io.StringIO(source).readline):
        if tok.type == tokenize.NUMBER:
            problem = _number_problem(tok.string)
            if problem:
                problems.append((tok.start[0], problem))
        elif tok.type in (tokenize.STRING, tokenize.COMMENT):  # words may state a fact
            (row, col), (end_row, end_col) = tok.start, tok.end
            for r in range(row, end_row + 1):
                text = lines[r - 1]
                a = col if r == row else 0
                b = end_col if r == end_row else len(text)
                lines[r - 1] = text[:a] + " " * (b - a) + text[b:]
    for number, line in enumerate(lines, 1):
        problems += [(number, p) for p in _pattern_problems(line)]
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Call):
            func = node.func
            name = func.attr if isinstance(func, ast.Attribute) else getattr(func, "id", "")
            if name in PY_ADDRESS_ARGS:
                index, count = PY_ADDRESS_ARGS[name]
                args = node.args
                if (count is None or len(args) == count) and len(args) > index:
                    arg = args[index]
                    if isinstance(arg, ast.Constant) and isinstance(arg.value, int):
                        problems.append((node.lineno, f"{name}() at literal address {arg.value}"))
            for kw in node.keywords:
                if kw.arg == "address" and isinstance(kw.value, ast.Constant):
                    problems.append((node.lineno, f"address={kw.value.value} typed"))
        elif isinstance(node, ast.Assign | ast.AnnAssign):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            value = node.value
            if isinstance(value, ast.Constant):
                for target in targets:
                    if isinstance(target, ast.Name):
                        problem = _register_problem(target.id, value.value)
                        if problem:
                            problems.append((node.lineno, problem))
    return problems


_C_NOISE = re.compile(r"/\*.*?\*/|//[^\n]*|\"(?:\\.|[^\"\\])*\"|'(?:\\.|[^'\\])*'", re.S)


def _blank(match: re.Match[str]) -> str:
    return re.sub(r"[^\n]", " ", match.group(0))  # keep the line numbers


def c_problems(source: str) -> list[tuple[int, str]]:
    """(line, problem) for every fact typed in C ``source``."""
    code = _C_NOISE.sub(_blank, source)
    problems: list[tuple[int, str]] = []
    for number, line in enumerate(code.splitlines(), 1):
        for literal in re.findall(r"(?<![\w.])(?:0[xX][0-9a-fA-F]+|\d+\.\d*|\d+)[uUlL]*", line):
            problem = _number_problem(literal)
            if problem:
                problems.append((number, problem))
        problems += [(number, p) for p in _pattern_problems(line)]
        define = re.match(
            r"\s*#\s*define\s+(\w+)\s+\(?\s*(0[xX][0-9a-fA-F]+|\d+)[uUlL]*\s*\)?\s*$", line
        )
        if define:
            problem = _register_problem(define.group(1), int(define.group(2), 0))
            if problem:
                problems.append((number, problem))
    for call in re.finditer(r"\b(dxl_\w+)\s*\(", code):
        if call.group(1) not in C_ADDRESS_ARGS:
            continue
        depth, args, start = 1, [], call.end()
        i = start
        while i < len(code) and depth:
            ch = code[i]
            if ch in "([{":
                depth += 1
            elif ch in ")]}":
                depth -= 1
            if (ch == "," and depth == 1) or depth == 0:
                args.append(code[start:i].strip())
                start = i + 1
            i += 1
        index = C_ADDRESS_ARGS[call.group(1)]
        if len(args) > index and re.fullmatch(r"(0[xX][0-9a-fA-F]+|\d+)[uU]?", args[index]):
            line = code.count("\n", 0, call.start()) + 1
            problems.append((line, f"{call.group(1)}() at literal address {args[index]}"))
    return problems


def _sources() -> list[Path]:
    files = []
    for root in PYTHON_ROOTS:
        files += sorted((REPO_ROOT / root).rglob("*.py"))
    for root in C_ROOTS:
        files += sorted((REPO_ROOT / root).rglob("*.[ch]"))
    return [
        f
        for f in files
        if not str(f.relative_to(REPO_ROOT)).startswith(EXCLUDED) and "build" not in f.parts
    ]


def test_no_register_address_or_unit_factor_is_typed_outside_the_descriptions():
    found = []
    sources = _sources()
    assert len(sources) > 100  # the scan reaches the tree
    for path in sources:
        text = path.read_text()
        scan = python_problems if path.suffix == ".py" else c_problems
        found += [f"{path.relative_to(REPO_ROOT)}:{line}: {p}" for line, p in scan(text)]
    assert not found, "facts typed outside host/snakebot/facts/devices:\n" + "\n".join(found)


@pytest.mark.parametrize(
    "planted",
    [
        "TICKS_PER_RAD = 1023.0 / math.radians(300.0)\n",
        "TICKS_PER_DEG = 1023 / 300\n",
        "deg = tick * 0.29\n",
        "rpm = units * 0.111\n",
        "rpm = units * 0.114\n",
        "k = 195.3786\n",
        "rate = 2_000_000 / (value + 1)\n",
        "DIRECTION_BIT = 1 << 10\n",
        "cw = value & 0x400\n",
        "magnitude = min(1023, value)\n",
        "STATUS_RETURN_LEVEL_ADDR = 16\n",
        "GOAL_POSITION = 30\n",
        "level = client.read_u8(servo, 16)\n",
        "data = client.read(servo, 36, 8)\n",
        "_, value, _ = handler.read2ByteTxRx(port, 10, 36)\n",
        "packet = protocol.sync_write(30, 4, blocks)\n",
        "client.write(servo, address=24, data=b'\\x01')\n",
    ],
)
def test_the_python_scan_catches_planted_facts(planted):
    assert python_problems("import math\n" + planted), planted


@pytest.mark.parametrize(
    "clean",
    [
        "x = 0.5 * 300\n",
        "data = os.read(fd, 36)\n",
        "SIZE = 1024\n",
        "timeout = 0.3\n",
        'message = "2000000 / (n + 1) with 0.111 rpm units at address 16"\n',
        "MAX_ID = 253\n",
        "# ticks per radian: 1023 / radians(300)\n",
        "goal = client.read_u16(servo, GOAL.address)\n",
    ],
)
def test_the_python_scan_leaves_other_numbers_alone(clean):
    assert python_problems(clean) == []


@pytest.mark.parametrize(
    "planted",
    [
        "#define TICKS_PER_MRAD_Q24 3277909LL\n",
        "#define UNITS_PER_TICK_S_Q18 115428ULL\n",
        "#define BUS_TELEMETRY_ADDRESS 36\n",
        "#define MY_TORQUE_ENABLE 24u\n",
        "n = dxl_write(out, cap, id, 24, &off, 1);\n",
        "n = dxl_sync_write(out, cap, 30, 4, ids, data, count);\n",
        "if (units > 1023) return 1023;\n",
        "bool cw = (v & 0x400u) != 0;\n",
    ],
)
def test_the_c_scan_catches_planted_facts(planted):
    assert c_problems(planted), planted


@pytest.mark.parametrize(
    "clean",
    [
        "#define HAL_FLASH_BUSY_POLLS 2000000UL\n",
        "#define BOARD_PC_RX_RING 512\n",
        "/* telemetry: addresses 36..43, 0.111 rpm, 1023 / radians(300) */\n",
        'return "joint limits not min <= max <= 1023";\n',
        "n = dxl_read(out, cap, id, BUS_TELEMETRY_ADDRESS, BUS_TELEMETRY_LENGTH);\n",
        "#define GT_MAX_ID 253\n",
    ],
)
def test_the_c_scan_leaves_other_numbers_alone(clean):
    assert c_problems(clean) == []
