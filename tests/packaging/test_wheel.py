"""The package as a user gets it: `python -m build` makes the sdist and, from the sdist, the
wheel; the wheel goes into a fresh venv outside the checkout with only the `physics` and
`mcu` extras (the demo's default world is MuJoCo, its default board the emulated CM-530),
and the main commands run there from a directory outside the checkout: `sim predict` in
MuJoCo, the demo on the shipped CM-530 image (in the kinematic world: the emulated chip and
MuJoCo in one process need most of a core, which the rest of `make test` shares)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tarfile
import zipfile
from dataclasses import dataclass
from pathlib import Path

import pytest
from firmware_support import build_firmware

from snakebot.firmware import SHIPPED, built_image
from snakebot.paths import REPO_ROOT

pytestmark = [pytest.mark.slow, pytest.mark.qemu]

BUILD_TIMEOUT_S = 600.0  # sdist, then the wheel from it in an isolated environment
DEMO_TIMEOUT_S = 300.0


@dataclass(frozen=True)
class Installed:
    sdist: Path
    wheel: Path
    venv: Path
    work: Path  # an empty directory outside the checkout to run commands in

    def run(self, *args: str, timeout: float = 120.0) -> subprocess.CompletedProcess[str]:
        env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
        env["PATH"] = f"{self.venv / 'bin'}{os.pathsep}{env.get('PATH', '')}"
        return subprocess.run(
            [str(self.venv / "bin" / "snakebot"), *args],
            cwd=self.work,
            env=env,
            capture_output=True,
            text=True,
            timeout=timeout,
            check=False,
        )


def _run(*cmd: str | Path, timeout: float) -> None:
    # Without PYTHONPATH: a checkout's host/ on it (its snakebot.egg-info, which the sdist
    # build writes) made pip take snakebot as installed and leave it out of the venv.
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    done = subprocess.run(
        [str(c) for c in cmd], capture_output=True, text=True, timeout=timeout, check=False, env=env
    )
    assert done.returncode == 0, f"{cmd} failed:\n{done.stdout[-3000:]}\n{done.stderr[-3000:]}"


@pytest.fixture(scope="module")
def installed(tmp_path_factory: pytest.TempPathFactory) -> Installed:
    build_firmware()  # the images the sdist carries come from the checkout's build
    root = tmp_path_factory.mktemp("wheel")
    assert not root.resolve().is_relative_to(REPO_ROOT)
    dist = root / "dist"
    _run(sys.executable, "-m", "build", "--outdir", dist, REPO_ROOT, timeout=BUILD_TIMEOUT_S)
    (sdist,) = dist.glob("*.tar.gz")
    (wheel,) = dist.glob("*.whl")
    venv = root / "venv"
    # A venv as a user makes one, the wheel installed into it by pip (this venv's own pip,
    # pointed at it, rather than a copy bootstrapped into it; and no byte-compiling of
    # every dependency ahead of time, which Python does anyway for what it imports).
    _run(sys.executable, "-m", "venv", "--without-pip", venv, timeout=120)
    pip = (sys.executable, "-m", "pip", "--python", venv / "bin" / "python", "install", "-q")
    _run(*pip, "--no-compile", f"{wheel}[physics,mcu]", timeout=600)
    work = root / "work"
    work.mkdir()
    return Installed(sdist, wheel, venv, work)


def test_the_wheel_is_abi3_and_carries_the_firmware_and_the_license(installed):
    assert installed.wheel.name.endswith("-cp310-abi3-linux_x86_64.whl")
    with zipfile.ZipFile(installed.wheel) as whl:
        names = set(whl.namelist())
        for board, name in SHIPPED:
            data = whl.read(f"snakebot/firmware/images/{board}/{name}")
            assert data == built_image(board, name).read_bytes(), f"{board}/{name} differs"
        assert any(n.endswith(".dist-info/licenses/LICENSE") for n in names)
        devices = REPO_ROOT / "host" / "snakebot" / "facts" / "devices" / "data"
        for path in devices.glob("*.json"):  # the control tables the commands load
            assert whl.read(f"snakebot/facts/devices/data/{path.name}") == path.read_bytes()
        layout = REPO_ROOT / "host" / "snakebot" / "formats" / "foxglove_layout.json"
        assert whl.read("snakebot/formats/foxglove_layout.json") == layout.read_bytes()
        metadata = next(whl.read(n).decode() for n in names if n.endswith(".dist-info/METADATA"))
    assert "snakebot/_core_build.py" not in names  # a build script, not part of the package
    assert "License-Expression: Apache-2.0" in metadata
    assert "Requires-Python: >=3.10" in metadata
    assert 'Requires-Dist: tomli>=1.1; python_version < "3.11"' in metadata
    assert 'Requires-Dist: sympy>=1.12; extra == "symbolic"' in metadata


def test_the_sdist_carries_what_the_wheel_build_needs(installed):
    with tarfile.open(installed.sdist) as tar:
        names = {n.split("/", 1)[1] for n in tar.getnames() if "/" in n}
    core = REPO_ROOT / "firmware" / "core"
    for path in [*core.glob("*.c"), *core.glob("*.h"), *(REPO_ROOT / "protocol").glob("*.md")]:
        assert str(path.relative_to(REPO_ROOT)) in names
    assert "host/snakebot/_core_build.py" in names
    for board, name in SHIPPED:
        assert f"host/snakebot/firmware/images/{board}/{name}" in names


def test_help_runs_outside_the_checkout(installed):
    done = installed.run("--help")
    assert done.returncode == 0, done.stderr
    assert "demo" in done.stdout and "flash" in done.stdout


def test_model_fields_from_the_wheel(installed):
    done = installed.run("model", "fields", "snake3", "--at", "0,0,0,0.3,-0.3", "--json")
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout)["robot"] == "snake3"


def test_a_missing_extra_is_one_line_naming_the_install(installed):
    done = installed.run("model", "fields", "snake3", "--symbolic")
    assert done.returncode == 2
    assert done.stderr.strip() == (
        "error[E601]: --symbolic needs sympy, which is not installed: "
        "pip install 'snakebot[symbolic]'"
    )


def test_gait_then_predict_from_the_wheel(installed):
    gait = installed.work / "x.gait"
    done = installed.run(
        "gait", "serpenoid", "snake5", "-A", "30deg", "-w", "180deg", "-d", "90deg",
        "--cycles", "1", "-o", str(gait),
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    done = installed.run("sim", "predict", str(gait), "--world", "mujoco", "--json")
    assert done.returncode == 0, done.stderr
    summary = json.loads(done.stdout)
    assert summary["frames"] == 100 and summary["emulated"]["dx"] > 0.1  # 2 s at 50 Hz


def test_demo_runs_the_shipped_firmware(installed):
    out = installed.work / "out"
    done = installed.run(
        "demo",
        "--json",
        "--cycles",
        "1",
        "--world",
        "kinematic",
        "--out",
        str(out),
        timeout=DEMO_TIMEOUT_S,
    )
    assert done.returncode == 0, done.stderr
    result = json.loads(done.stdout)
    shipped = installed.venv.glob("lib/python3*/site-packages/snakebot/firmware/images/cm530")
    assert result["board"] == "cm530"  # the shipped CM-530 image on the emulated STM32F103RE
    assert Path(result["firmware"]) == next(shipped) / "firmware.bin"
    assert result["emulated"]["dx"] > 0.5 * result["predicted"]["dx"] > 0
    assert result["png"] is None  # no matplotlib without the `plot` extra
    assert (out / "demo.gait").is_file()
