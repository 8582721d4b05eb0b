"""docs/wiring.svg draws the built-in snake5's servos and the links' rates as the code has
them, is a well-formed SVG with a text description, and the pages that send a teacher to
it do."""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET

from snakebot.facts.boards import PC_LINK_BAUD
from snakebot.link.transport.timing import DEFAULT_BAUDRATE
from snakebot.model.robots import load_robot
from snakebot.paths import REPO_ROOT

SVG = REPO_ROOT / "docs" / "wiring.svg"
NS = "{http://www.w3.org/2000/svg}"


def test_the_wiring_picture_matches_the_robot_and_the_links():
    root = ET.parse(SVG).getroot()
    texts = [t.text or "" for t in root.iter(f"{NS}text")]
    ids = [int(m.group(1)) for t in texts if (m := re.search(r"AX-12A\s+ID (\d+)", t))]
    robot = load_robot("snake5")
    assert ids == list(robot.servo_ids)
    joints = [m.group(1) for t in texts if (m := re.match(r"joint (\w+)", t))]
    assert joints == [j.name for j in robot.joints]
    assert f"{PC_LINK_BAUD} 8N1" in texts
    assert f"Dynamixel bus, {DEFAULT_BAUDRATE // 1_000_000} Mbps" in texts
    description = root.find(f"{NS}desc")
    assert description is not None and "IDs " + ", ".join(map(str, ids[:-1])) in description.text


def test_the_pages_show_it():
    for page in ("README.md", "docs/first-flash.md", "docs/hardware.md"):
        assert "wiring.svg" in (REPO_ROOT / page).read_text(encoding="utf-8"), page
