"""A MuJoCo blow-up leaves no MUJOCO_LOG.TXT in the working directory (issue #28): the
physics world keeps MuJoCo's warnings in memory instead."""

from __future__ import annotations

import os

import numpy as np
import pytest

from snakebot.sim.physics.world import MUJOCO_WARNINGS, _mujoco

pytest.importorskip("mujoco")


def test_a_blow_up_writes_no_log_file(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    mujoco = _mujoco()
    model = mujoco.MjModel.from_xml_string(
        '<mujoco><worldbody><body><freejoint/><geom size=".1"/></body></worldbody></mujoco>'
    )
    data = mujoco.MjData(model)
    data.qpos[:] = np.nan  # what a blow-up leaves
    mujoco.mj_step(model, data)
    assert data.warning[mujoco.mjtWarning.mjWARN_BADQPOS].number == 1
    assert not os.path.exists("MUJOCO_LOG.TXT")
    assert "Nan, Inf or huge value" in MUJOCO_WARNINGS[-1]
