"""The documents: the API reference builds (`make docs`, pdoc) and its landing page's
example runs, nothing in the repository points outside it, and docs/settings.md lists
exactly the environment variables the code reads, with the code's defaults."""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from snakebot.link.bus import scan as bus_scan
from snakebot.link.controller import load as load_controller_table
from snakebot.link.controller import settings as upload_settings
from snakebot.link.flash import settings as flash_settings
from snakebot.link.transport import settings as transport_settings
from snakebot.link.transport import timing
from snakebot.paths import REPO_ROOT
from snakebot.settings import SETTINGS

SETTINGS_MD = REPO_ROOT / "docs" / "settings.md"

# Patterns are split so that this file does not match them itself.
OUTSIDE = {
    "a path into the shared folder beside the repository": re.compile(r"\.\./shared\b"),
    "an absolute path on one machine": re.compile(r"(?<![\w.:/])/(?:work|home)/\w"),
}
DOC_REFERENCE = re.compile(r"(?<![\w/.-])docs/([\w.-]+\.md)\b")
MD_LINK = re.compile(r"\]\(([^)#\s]+)(?:#[^)]*)?\)")
MD_CODE = re.compile(r"```.*?```|`[^`\n]*`", re.DOTALL)
ENV_NAME = re.compile(r"\bSNAKEBOT_[A-Z0-9_]+\b")


def tracked_text_files() -> dict[str, str]:
    """Every file git tracks (relative path -> text), binary files left out."""
    if shutil.which("git") is None or not (REPO_ROOT / ".git").exists():
        pytest.skip("needs a git checkout of the repository")
    names = subprocess.run(
        ["git", "ls-files", "-z"], cwd=REPO_ROOT, capture_output=True, check=True
    ).stdout.split(b"\0")
    files = {}
    for raw in filter(None, names):
        name = raw.decode()
        path = REPO_ROOT / name
        if not path.is_file():
            continue  # deleted in the work tree, not yet committed
        try:
            files[name] = path.read_text(encoding="utf-8")
        except UnicodeDecodeError:
            continue
    assert len(files) > 50, "git ls-files found too few files: is this the snakebot repository?"
    return files


@pytest.mark.late
def test_make_docs_builds_the_api_reference(tmp_path: Path):
    out = tmp_path / "api"
    # -o python-env: the environment running this test is already set up.
    result = subprocess.run(
        ["make", "-s", "-o", "python-env", "docs", f"DOCS_DIR={out}", f"PY={sys.executable}"],
        cwd=REPO_ROOT,
        capture_output=True,
        text=True,
        timeout=240,
    )
    assert result.returncode == 0, result.stderr
    # page -> a name it must document (pdoc gives each an anchor)
    expected = {
        "snakebot.html": 'href="snakebot/model.html"',
        "snakebot/link/transport.html": 'id="DxlClient"',
        "snakebot/facts/controller.html": 'id="Controller"',
        "snakebot/model/kinematics.html": 'id="body_velocity"',
        "snakebot/model/robots.html": 'id="Robot"',
        "snakebot/model/symbolic.html": 'id="lie_bracket"',
        "snakebot/model/gait.html": 'id="Gait"',
        "snakebot/link/flash.html": 'id="BoardLayout"',
        "snakebot/sim/world.html": "snakebot.sim.world",
        "snakebot/cli.html": "snakebot.cli",
    }
    landing = (out / "snakebot.html").read_text(encoding="utf-8")
    for layer in ("facts", "formats", "model", "link", "sim", "workflows", "plots", "cli"):
        assert f"snakebot.{layer}" in landing, f"the landing page does not name {layer}"
    for start in ("model/robots.html#load_robot", "link/transport.html#DxlClient"):
        assert f'href="snakebot/{start}"' in landing, f"the landing page does not link {start}"
    for page, word in expected.items():
        path = out / page
        assert path.is_file(), f"{page} missing from the API reference"
        assert word in path.read_text(encoding="utf-8"), f"{page} does not document {word}"
    assert not list(out.rglob("_core*.html")), "private modules leaked into the reference"


def test_the_landing_pages_example_runs():
    """The package docstring is the API reference's landing page; its example runs."""
    import doctest

    import snakebot

    parser = doctest.DocTestParser()
    test = parser.get_doctest(snakebot.__doc__, {}, "snakebot", "snakebot/__init__.py", 0)
    assert len(test.examples) >= 5, "the landing page has lost its example"
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS)
    runner.run(test)
    assert runner.summarize(verbose=False).failed == 0


def test_nothing_points_outside_the_repository():
    problems = []
    for name, text in tracked_text_files().items():
        for what, pattern in OUTSIDE.items():
            for m in pattern.finditer(text):
                line = text.count("\n", 0, m.start()) + 1
                problems.append(f"{name}:{line}: {what} ({m.group(0)!r})")
    assert not problems, "\n".join(problems)


def test_every_cited_document_exists():
    files = tracked_text_files()
    problems = []
    for name, text in files.items():
        for m in DOC_REFERENCE.finditer(text):
            if f"docs/{m.group(1)}" not in files:
                line = text.count("\n", 0, m.start()) + 1
                problems.append(f"{name}:{line}: docs/{m.group(1)} does not exist")
        if name.endswith(".md"):
            prose = MD_CODE.sub(lambda c: "\n" * c.group(0).count("\n"), text)
            for m in MD_LINK.finditer(prose):
                target = m.group(1)
                if "://" in target or target.startswith("mailto:"):
                    continue
                if not (REPO_ROOT / name).parent.joinpath(target).resolve().exists():
                    line = prose.count("\n", 0, m.start()) + 1
                    problems.append(f"{name}:{line}: link to {target} does not resolve")
    assert not problems, "\n".join(problems)


def test_the_documents_index_lists_every_document():
    readme = (REPO_ROOT / "README.md").read_text(encoding="utf-8")
    documents = sorted(p.name for p in (REPO_ROOT / "docs").glob("*.md"))
    assert {"models.md", "hardware.md", "settings.md"} <= set(documents)
    missing = [d for d in documents if f"docs/{d}" not in readme]
    assert not missing, f"README's Documents section does not list {missing}"


def variables_read_by_the_code() -> set[str]:
    """SNAKEBOT_* names in the Python sources (C header guards are not variables)."""
    names = set()
    for name, text in tracked_text_files().items():
        if name.endswith(".py") and name.startswith(("host/", "tests/", "bench/")):
            names |= set(ENV_NAME.findall(text))
    # A docstring's "SNAKEBOT_FLASH_*_S" wildcard is a family, not a variable.
    return {n for n in names if not n.endswith("_H") and not n.endswith("_")}


def documented_rows() -> dict[str, dict[str, str]]:
    """Variable -> its row in docs/settings.md (column name -> cell)."""
    rows: dict[str, dict[str, str]] = {}
    header: list[str] = []
    for line in SETTINGS_MD.read_text(encoding="utf-8").splitlines():
        if not line.startswith("|"):
            header = []
            continue
        cells = [cell.strip() for cell in line.strip().strip("|").split("|")]
        if cells[0] == "variable":
            header = cells
        m = re.fullmatch(r"`(SNAKEBOT_[A-Z0-9_]+)`", cells[0])
        if m:
            assert header, f"{m.group(1)}: a row outside a table with a header"
            assert m.group(1) not in rows, f"{m.group(1)} has two rows in docs/settings.md"
            rows[m.group(1)] = dict(zip(header, cells, strict=True))
    return rows


def test_settings_page_lists_exactly_the_variables_of_the_one_table():
    code = variables_read_by_the_code()
    documented = set(documented_rows())
    table = set(SETTINGS)
    assert len(code) >= 20  # the search works
    assert code - table == set(), "named in the code but not in snakebot.settings.SETTINGS"
    assert table - code == set(), "in the table but read nowhere"
    assert table - documented == set(), "in the table but not in docs/settings.md"
    assert documented - table == set(), "in docs/settings.md but not in the table"


def test_settings_page_rows_are_the_tables():
    for name, row in documented_rows().items():
        setting = SETTINGS[name]
        default = setting.default_text()
        if name == "SNAKEBOT_CONTROLLER_ID":  # a fact of the control table, above the root
            default = f"{load_controller_table().default_id} ({setting.default_note})"
        assert row["default"] == default, name
        assert row["unit"] == setting.unit, name
        assert row["range"] == setting.range_text(), name


def test_the_readers_defaults_are_the_tables(monkeypatch):
    for name in SETTINGS:
        monkeypatch.delenv(name, raising=False)
    expected: dict[str, object] = {
        transport_settings.ENV_RETRIES: transport_settings.resolve_retries(),
        transport_settings.ENV_LATENCY_MS: transport_settings.resolve_latency_s() * 1e3,
        transport_settings.ENV_MARGIN_MS: transport_settings.resolve_margin_s() * 1e3,
        transport_settings.ENV_RETURN_DELAY_US: transport_settings.resolve_return_delay_us(),
        transport_settings.ENV_ECHO_PROBE_MS: transport_settings.resolve_echo_probe_s() * 1e3,
        transport_settings.ENV_ECHO: transport_settings.resolve_echo(),
        upload_settings.ENV_UPLOAD_RETRIES: upload_settings.resolve_upload_retries(),
        upload_settings.ENV_UPLOAD_WINDOW: upload_settings.resolve_upload_window(),
    }
    resolved = flash_settings.FlashTimeouts.resolve()
    for field, env in flash_settings.ENV_NAMES.items():
        expected[env] = getattr(resolved, field)
    for env, value in expected.items():
        assert value == pytest.approx(SETTINGS[env].default), env
    pty_margin = (
        f"{timing.PROGRAM_MARGIN_S * 1e3:g} on a pseudo-terminal; "
        f"{bus_scan.SCAN_MARGIN_S * 1e3:g} for a scan's silent IDs"
    )
    assert SETTINGS[transport_settings.ENV_MARGIN_MS].default_note == pty_margin
