"""The robot for other tools (issue #33): the MJCF and the URDF that `snakebot robot
export` writes load in real MuJoCo and in a URDF parser from PyPI, carry the physics
world's masses, limits and wheels, and the URDF's model, put on a floor and driven by the
joint trajectory the physics world played, goes where the physics world went."""

from __future__ import annotations

import math

import numpy as np
import pytest
from physics_support import snake5_serpenoid

from snakebot.model.robots import load_robot
from snakebot.sim.physics.export import export_mjcf, export_urdf
from snakebot.sim.physics.mjcf import ROLLING_MODEL, build_mjcf, wheel_friction
from snakebot.workflows.predict import predict_gait

mujoco = pytest.importorskip("mujoco")

ROBOTS = ("snake3", "snake5", "trident")


def compiled(xml: str):
    return mujoco.MjModel.from_xml_string(xml)


def servo_ranges(model, robot):
    return np.array([model.joint(j.name).range for j in robot.joints])


@pytest.mark.parametrize("name", ROBOTS)
def test_mujoco_loads_both_with_the_worlds_masses_and_limits(name):
    robot = load_robot(name)
    xml, names = build_mjcf(robot)
    world = compiled(xml)
    mjcf, urdf = compiled(export_mjcf(robot)), compiled(export_urdf(robot))
    for model in (mjcf, urdf):
        assert model.body_mass.sum() == pytest.approx(world.body_mass.sum())
        np.testing.assert_allclose(servo_ranges(model, robot), servo_ranges(world, robot))
        for k in range(1, robot.n_wheels + 1):  # principal moments, in any order
            body = model.body(f"wheel{k}")
            assert body.mass == pytest.approx(world.body(f"wheel{k}").mass)
            np.testing.assert_allclose(
                np.sort(body.inertia), np.sort(world.body(f"wheel{k}").inertia)
            )
    # the URDF's root is the body (no joint to the world): the world's root joints go,
    # and so do a snake's links' slides in z on their parents (the world's, to give each
    # wheel its own link's weight; a URDF link has one joint)
    slides = len(names.heights) - 1
    assert urdf.njnt == world.njnt - 4 - slides
    np.testing.assert_allclose(
        np.sort(urdf.body("base").inertia), np.sort(world.body("base").inertia)
    )


def test_the_exported_mjcf_holds_a_joint_where_ctrl_says():
    robot = load_robot("snake3")
    model = compiled(export_mjcf(robot))
    data = mujoco.MjData(model)
    data.ctrl[:] = [0.5, -0.3]
    for _ in range(300):
        mujoco.mj_step(model, data)
    got = [data.qpos[model.joint(j.name).qposadr[0]] for j in robot.joints]
    np.testing.assert_allclose(got, [0.5, -0.3], atol=0.05)


@pytest.mark.parametrize("name", ROBOTS)
def test_the_urdf_validates_with_yourdfpy(name, tmp_path):
    yourdfpy = pytest.importorskip("yourdfpy")
    robot = load_robot(name)
    path = tmp_path / f"{name}.urdf"
    path.write_text(export_urdf(robot))
    urdf = yourdfpy.URDF.load(str(path), load_meshes=False)
    assert urdf.validate()
    joints = {j.name: j for j in urdf.robot.joints}
    for j in robot.joints:
        assert joints[j.name].type == "revolute"
        assert joints[j.name].limit.lower == pytest.approx(j.min_rad)
        assert joints[j.name].limit.upper == pytest.approx(j.max_rad)
        assert joints[j.name].limit.effort > 0
    wheels = [j for j in urdf.robot.joints if j.type == "continuous"]
    assert len(wheels) == robot.n_wheels
    assert urdf.base_link == "base"
    total = sum(link.inertial.mass for link in urdf.robot.links)
    assert total == pytest.approx(compiled(build_mjcf(robot)[0]).body_mass.sum())


def urdf_world(robot, timestep: float, kp: float):
    """The URDF in MuJoCo as a lab would set it up: the root free in the plane (x, y, z,
    heading), a floor with the robot's friction, position servos on the joints."""
    spec = mujoco.MjSpec.from_string(export_urdf(robot))
    spec.option.timestep = timestep
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    spec.option.cone = mujoco.mjtCone.mjCONE_ELLIPTIC
    base = spec.body("base")
    base.pos = [0, 0, robot.physics.wheel_radius_m]
    slide, hinge = mujoco.mjtJoint.mjJNT_SLIDE, mujoco.mjtJoint.mjJNT_HINGE
    for name, kind, axis in (
        ("x", slide, [1, 0, 0]),
        ("y", slide, [0, 1, 0]),
        ("z", slide, [0, 0, 1]),
        ("theta", hinge, [0, 0, 1]),
    ):
        base.add_joint(name=name, type=kind, axis=axis)
    # the physics world's own wheel friction (its default rolling model), which URDF
    # cannot carry: the contact's triple and condim, the axle's friction on the hinge
    wheel = wheel_friction(robot, robot.friction, float(robot.wheel_loads_n()[0]), ROLLING_MODEL)
    friction = list(wheel.contact)
    spec.worldbody.add_geom(
        type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0, 0, 1], friction=friction, conaffinity=1
    )
    for geom in spec.geoms:
        if geom.type == mujoco.mjtGeom.mjGEOM_SPHERE:  # the wheels' one collision shape
            geom.friction, geom.condim = friction, wheel.condim
            geom.contype, geom.conaffinity = 1, 0
    for joint in spec.joints:
        if "wheel" in joint.name:
            joint.frictionloss = wheel.axle_nm
    for j in robot.joints:
        spec.add_actuator(name=j.name, target=j.name, trntype=mujoco.mjtTrn.mjTRN_JOINT)
        spec.actuator(j.name).set_to_position(kp=kp)
    return spec.compile()


def test_the_urdf_driven_like_the_physics_world_goes_as_far():
    robot = load_robot("snake5")
    rec = predict_gait(snake5_serpenoid(), "snake5", world="mujoco").emulated
    model = urdf_world(robot, timestep=0.002, kp=20.0)
    data = mujoco.MjData(model)
    qadr = [model.joint(j.name).qposadr[0] for j in robot.joints]
    data.qpos[qadr] = rec.phi[0]
    mujoco.mj_forward(model, data)
    start = data.qpos[:2].copy()
    for _ in range(round(rec.t[-1] / model.opt.timestep)):
        data.ctrl[:] = [np.interp(data.time, rec.t, rec.phi[:, k]) for k in range(len(qadr))]
        mujoco.mj_step(model, data)
    moved = data.qpos[:2] - start
    expected = (rec.pose[-1, :2] - rec.pose[0, :2]) * robot.physics.unit_m
    assert np.hypot(*expected) > 0.2  # the gait goes somewhere
    # measured: 1.4 % shorter (the URDF has no armature; the drive follows the angles)
    assert np.hypot(*moved) == pytest.approx(np.hypot(*expected), rel=0.05)
    heading = math.atan2(moved[1], moved[0]) - math.atan2(expected[1], expected[0])
    assert abs(heading) < math.radians(3)
