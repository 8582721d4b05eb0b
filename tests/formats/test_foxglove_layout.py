"""The Foxglove layout shipped with the package (`snakebot foxglove-layout`): valid JSON
whose panels read only the topics the live server advertises and a recording holds."""

from __future__ import annotations

import json
import re

from click.testing import CliRunner

from snakebot.cli import main
from snakebot.formats.gaittable.layout import MAX_JOINTS
from snakebot.formats.live_topics import JOINT_STATES, ROBOT_DESCRIPTION, SCENE, TOPICS


def test_the_written_layout_reads_only_the_served_topics(tmp_path):
    path = tmp_path / "layout.json"
    result = CliRunner().invoke(main, ["foxglove-layout", "-o", str(path), "--json"])
    assert result.exit_code == 0, result.output
    assert json.loads(result.stdout)["layout"] == str(path)
    layout = json.loads(path.read_text())
    panels = layout["configById"]
    # every panel in the arrangement is configured, and every configured one is shown
    shown = set(re.findall(r'"([A-Za-z0-9]+![a-z]+)"', json.dumps(layout["layout"])))
    assert shown == set(panels)
    text = json.dumps(panels)
    topics = set(re.findall(r'"(/[a-z_/]+)(?:[.\[]|")', text))
    topics -= {"/move_base_simple/goal", "/clicked_point", "/initialpose"}  # 3-D panel's own
    assert topics and topics <= set(TOPICS)
    three_d = next(v for k, v in panels.items() if k.startswith("3D!"))
    urdf = [layer for layer in three_d["layers"].values() if layer["layerId"] == "foxglove.Urdf"]
    assert urdf[0]["topic"] == ROBOT_DESCRIPTION and SCENE in three_d["topics"]
    angles = [p["value"] for p in panels["Plot!angles"]["paths"]]
    assert angles == [f"{JOINT_STATES}.position[{i}]" for i in range(MAX_JOINTS)]
    assert any(
        p["value"].endswith(".state") for p in panels["StateTransitions!controller"]["paths"]
    )
