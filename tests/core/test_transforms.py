"""Transform buffer (odocal.core.transforms): chains against hand-computed 3D transforms,
interpolation, inverse chains, planar helpers and every bad input."""

from __future__ import annotations

import math

import numpy as np
import pytest

from odocal.core.transforms import (
    RigidTransforms,
    TransformBuffer,
    planar_pose,
    se2_compose,
    se2_conjugate,
    se2_inverse,
    se2_relative,
    tilt_rad,
    wrap_angle,
)
from odocal.errors import InputError, ModelError

S = math.sqrt(0.5)
IDENTITY_Q = [0.0, 0.0, 0.0, 1.0]
RZ90_Q = [0.0, 0.0, S, S]
RX180_Q = [1.0, 0.0, 0.0, 0.0]  # a laser mounted upside down
RY90_Q = [0.0, S, 0.0, S]  # an IMU on a vertical board
RZ90 = np.array([[0, -1, 0], [1, 0, 0], [0, 0, 1]], float)
RX180 = np.diag([1.0, -1.0, -1.0])
RY90 = np.array([[0, 0, 1], [0, 1, 0], [-1, 0, 0]], float)


def rz(deg: float) -> np.ndarray:
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def robot_tree() -> TransformBuffer:
    """map -> odom (dynamic, constant value), odom -> base_link (dynamic: at t = 2 s it has
    moved 2 m and turned 90 deg), and two static mounts below base_link."""
    buf = TransformBuffer()
    buf.add("map", "odom", [0.0, 2.0], [[1, 2, 0], [1, 2, 0]], [RZ90_Q, RZ90_Q])
    buf.add("odom", "base_link", [0.0, 2.0], [[0, 0, 0], [2, 0, 0]], [IDENTITY_Q, RZ90_Q])
    buf.add_static("base_link", "laser", [0.2, 0.0, 0.3], RX180_Q)
    buf.add_static("base_link", "imu", [0.0, 0.1, 0.05], RY90_Q)
    return buf


def check(transform: RigidTransforms, rotation, translation, atol=1e-12):
    m = transform.matrix()[0]
    np.testing.assert_allclose(m[:3, :3], rotation, atol=atol)
    np.testing.assert_allclose(m[:3, 3], translation, atol=atol)


# --------------------------------------------------------------------------- chains


def test_chain_down_through_a_static_mount_matches_the_hand_computation():
    buf = robot_tree()
    look = buf.lookup("map", "laser", 0.0)
    # T_map_laser = T_map_odom T_odom_base (identity at t = 0) T_base_laser:
    # t = (1, 2, 0) + Rz90 (0.2, 0, 0.3) = (1, 2.2, 0.3); R = Rz90 Rx180
    check(look.transform, [[0, 1, 0], [1, 0, 0], [0, 0, -1]], [1.0, 2.2, 0.3])
    assert look.chain == ("map", "odom", "base_link", "laser")
    assert [s.inverted for s in look.steps] == [False, False, False]
    assert [s.static for s in look.steps] == [False, False, True]
    assert (
        look.describe()
        == "map -> odom -> base_link -> laser (dynamic: map -> odom, odom -> base_link)"
    )


def test_chain_between_two_leaves_goes_up_to_the_common_parent():
    buf = robot_tree()
    look = buf.lookup("imu", "laser", 1.3)  # static only: any time inside the data
    # T_imu_laser = T_base_imu^-1 T_base_laser: t = Ry(-90) ((0.2, 0, 0.3) - (0, 0.1, 0.05))
    #   = Ry(-90) (0.2, -0.1, 0.25) = (-0.25, -0.1, 0.2); R = Ry(-90) Rx180
    check(look.transform, RY90.T @ RX180, [-0.25, -0.1, 0.2])
    assert look.chain == ("imu", "base_link", "laser")
    assert [s.inverted for s in look.steps] == [True, False]
    assert look.steps[0].edge == "base_link -> imu"
    assert look.describe().endswith("(all static)")


def test_midway_lookup_interpolates_translation_linearly_and_rotation_by_slerp():
    buf = robot_tree()
    look = buf.lookup("map", "laser", 1.0)
    # odom -> base_link halfway: (1, 0, 0), yaw 45 deg; T_map_base: (1, 2, 0) + Rz90 (1, 0, 0)
    # = (1, 3, 0), yaw 135 deg; the laser: (1, 3, 0) + Rz135 (0.2, 0, 0.3)
    r = rz(135)
    check(look.transform, r @ RX180, np.array([1.0, 3.0, 0.0]) + r @ [0.2, 0.0, 0.3])


def test_slerp_of_a_general_axis_and_the_shorter_arc():
    from scipy.spatial.transform import Rotation

    axis = np.array([1.0, 1.0, 1.0]) / math.sqrt(3.0)
    q0 = Rotation.identity().as_quat()
    q1 = Rotation.from_rotvec(axis * math.radians(120)).as_quat()
    buf = TransformBuffer()
    # the second sample is given as -q (the same rotation): slerp must still take the 120 deg arc
    buf.add("a", "b", [10.0, 11.0], [[0, 0, 0], [2, -4, 6]], [q0, -q1])
    look = buf.lookup("a", "b", 10.5)
    expected = Rotation.from_rotvec(axis * math.radians(60)).as_matrix()
    check(look.transform, expected, [1.0, -2.0, 3.0])
    # a quarter of the way
    look = buf.lookup("a", "b", 10.25)
    expected = Rotation.from_rotvec(axis * math.radians(30)).as_matrix()
    check(look.transform, expected, [0.5, -1.0, 1.5])


def test_inverse_chain_is_the_inverse_transform():
    buf = robot_tree()
    times = np.linspace(0.0, 2.0, 7)
    fwd = buf.lookup("map", "imu", times)
    back = buf.lookup("imu", "map", times)
    assert back.chain == tuple(reversed(fwd.chain))
    assert all(s.inverted for s in back.steps)
    np.testing.assert_allclose(
        back.transform.matrix(), np.linalg.inv(fwd.transform.matrix()), atol=1e-12
    )
    ident = (back.transform @ fwd.transform).matrix()
    np.testing.assert_allclose(ident, np.broadcast_to(np.eye(4), ident.shape), atol=1e-12)


def test_vectorised_lookup_equals_one_at_a_time():
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(1000)
    buf = TransformBuffer()
    t = np.sort(rng.uniform(0, 10, 40))
    buf.add("odom", "base_link", t, rng.normal(size=(40, 3)), Rotation.random(40, rng).as_quat())
    buf.add("map", "odom", [0, 5, 10], rng.normal(size=(3, 3)), Rotation.random(3, rng).as_quat())
    buf.add_static("base_link", "laser", [0.1, 0, 0.2], RX180_Q)
    q = rng.uniform(0, 10, 25)
    many = buf.lookup("map", "laser", q).transform.matrix()
    one = np.array([buf.lookup("map", "laser", x).transform.matrix()[0] for x in q])
    np.testing.assert_allclose(many, one, atol=1e-12)


def test_exact_sample_times_return_the_samples():
    buf = robot_tree()
    look = buf.lookup("odom", "base_link", [0.0, 2.0])
    np.testing.assert_allclose(look.transform.translation_m, [[0, 0, 0], [2, 0, 0]], atol=1e-15)
    check(look.transform[1], RZ90, [2, 0, 0])


def test_same_frame_is_identity_with_an_empty_chain():
    look = robot_tree().lookup("laser", "laser", [0.0, 1.0])
    assert look.chain == ("laser",)
    np.testing.assert_allclose(look.transform.matrix(), np.broadcast_to(np.eye(4), (2, 4, 4)))


def test_leading_slash_frames_are_the_same_frames():
    buf = TransformBuffer()
    buf.add("/odom", "/base_link", [0, 1], [[0, 0, 0], [1, 0, 0]], [IDENTITY_Q] * 2)
    assert buf.frames == ("base_link", "odom")
    assert buf.lookup("odom", "/base_link", 0.5).transform.translation_m[0, 0] == 0.5


def test_repeated_stamps_keep_the_first_sample_as_tf2():
    buf = TransformBuffer()
    buf.add("map", "odom", [0.0, 1.0], [[0, 0, 0], [1, 0, 0]], [IDENTITY_Q] * 2)
    buf.add("map", "odom", [1.0, 0.5], [[5, 0, 0], [0.25, 0, 0]], [IDENTITY_Q] * 2)
    (info,) = buf.edges()
    assert (info.count, info.repeated_stamps, info.first_s, info.last_s) == (3, 1, 0.0, 1.0)
    times, tr = buf.samples("map", "odom")
    np.testing.assert_array_equal(times, [0.0, 0.5, 1.0])
    np.testing.assert_array_equal(tr.translation_m[:, 0], [0.0, 0.25, 1.0])


def test_static_edge_is_replaced_by_a_later_value():
    buf = TransformBuffer()
    buf.add_static("base_link", "laser", [0, 0, 0], IDENTITY_Q)
    buf.add_static("base_link", "laser", [1, 0, 0], IDENTITY_Q)
    assert buf.lookup("base_link", "laser", 123.0).transform.translation_m[0, 0] == 1.0
    assert buf.parent_of("laser") == "base_link" and buf.parent_of("base_link") is None


# --------------------------------------------------------------------------- extrapolation


def test_queries_outside_an_edge_are_refused_and_name_the_edge():
    buf = robot_tree()
    with pytest.raises(InputError) as e:
        buf.lookup("map", "laser", [1.0, 2.5, 3.0])
    msg = str(e.value)
    assert "map -> laser" in msg and "'map -> odom'" in msg and "t = 2.500000" in msg
    assert "0.000000 to 2.000000" in msg and "2 of 3" in msg and "\n" not in msg
    with pytest.raises(InputError, match="t = -0.100000"):
        buf.lookup("odom", "base_link", -0.1)


def test_tolerance_holds_the_end_sample():
    buf = robot_tree()
    look = buf.lookup("odom", "base_link", [-0.05, 2.05], max_extrapolation_s=0.1)
    np.testing.assert_allclose(look.transform.translation_m, [[0, 0, 0], [2, 0, 0]], atol=1e-15)
    with pytest.raises(InputError):
        buf.lookup("odom", "base_link", 2.05)  # the buffer's default: no tolerance
    lenient = TransformBuffer(max_extrapolation_s=0.1)
    lenient.add("odom", "base_link", [0.0, 2.0], [[0, 0, 0], [2, 0, 0]], [IDENTITY_Q, RZ90_Q])
    check(lenient.lookup("odom", "base_link", 2.05).transform, RZ90, [2, 0, 0])
    with pytest.raises(InputError, match="tolerance 0.1 s"):
        lenient.lookup("odom", "base_link", 2.15)


def test_max_gap_refuses_interpolation_across_holes():
    buf = TransformBuffer()
    buf.add(
        "odom", "base_link", [0, 0.1, 3.0], [[0, 0, 0], [0.1, 0, 0], [3, 0, 0]], [IDENTITY_Q] * 3
    )
    buf.lookup("odom", "base_link", 1.0)  # no limit by default
    with pytest.raises(InputError, match=r"gap of 2\.900 s"):
        buf.lookup("odom", "base_link", [0.05, 1.0], max_gap_s=0.5)
    buf.lookup("odom", "base_link", [0.05, 0.1, 3.0], max_gap_s=0.5)  # at the samples: fine


def test_single_sample_edge_is_usable_only_at_its_time():
    buf = TransformBuffer()
    buf.add("map", "odom", 4.0, [1, 0, 0], IDENTITY_Q)
    assert buf.lookup("map", "odom", 4.0).transform.translation_m[0, 0] == 1.0
    with pytest.raises(InputError):
        buf.lookup("map", "odom", 4.01)
    assert buf.lookup("map", "odom", 4.01, max_extrapolation_s=0.02).transform.translation_m[0, 0]


# --------------------------------------------------------------------------- bad inputs


def test_unknown_frame_lists_the_known_ones():
    with pytest.raises(InputError) as e:
        robot_tree().lookup("map", "base_footprint", 0.0)
    assert str(e.value) == (
        "no frame 'base_footprint' in the transforms; frames: base_link, imu, laser, map, odom"
    )
    with pytest.raises(InputError, match="holds no transforms"):
        TransformBuffer().lookup("map", "odom", 0.0)


def test_disconnected_trees_are_both_named():
    buf = robot_tree()
    buf.add("world", "mocap_body", [0, 1], [[0, 0, 0], [1, 0, 0]], [IDENTITY_Q] * 2)
    with pytest.raises(InputError) as e:
        buf.lookup("mocap_body", "laser", 0.5)
    msg = str(e.value)
    assert "'mocap_body' and 'laser' are not connected" in msg
    assert "tree of 'world' (mocap_body, world)" in msg
    assert "tree of 'map' (base_link, imu, laser, map, odom)" in msg


def test_a_frame_with_two_parents_is_refused():
    buf = robot_tree()
    with pytest.raises(InputError, match="'base_link' has two parents, 'odom' and 'map'"):
        buf.add("map", "base_link", [0.0], [0, 0, 0], IDENTITY_Q)


def test_loops_and_self_edges_are_refused():
    buf = robot_tree()
    with pytest.raises(InputError, match="close a loop"):
        buf.add("laser", "map", [0.0], [0, 0, 0], IDENTITY_Q)
    with pytest.raises(InputError, match="to itself"):
        buf.add("map", "/map", [0.0], [0, 0, 0], IDENTITY_Q)


def test_static_and_dynamic_versions_of_one_edge_are_refused():
    buf = robot_tree()
    with pytest.raises(InputError, match="both as static and dynamic"):
        buf.add("base_link", "laser", [0.0], [0, 0, 0], IDENTITY_Q)


def test_bad_values_and_shapes():
    buf = TransformBuffer()
    with pytest.raises(InputError, match="not finite"):
        buf.add("a", "b", [0.0], [math.nan, 0, 0], IDENTITY_Q)
    with pytest.raises(InputError, match="zero quaternion"):
        buf.add("a", "b", [0.0], [0, 0, 0], [0, 0, 0, 0])
    with pytest.raises(InputError, match="sample time is not finite"):
        buf.add("a", "b", [math.inf], [0, 0, 0], IDENTITY_Q)
    with pytest.raises(ModelError, match=r"shape \(n, 3\)"):
        buf.add("a", "b", [0.0], [0, 0], IDENTITY_Q)
    with pytest.raises(ModelError, match="2 times for 1"):
        buf.add("a", "b", [0.0, 1.0], [0, 0, 0], IDENTITY_Q)
    with pytest.raises(ModelError, match="max_extrapolation_s"):
        TransformBuffer(max_extrapolation_s=-1.0)
    with pytest.raises(InputError, match="empty"):
        buf.add("", "b", [0.0], [0, 0, 0], IDENTITY_Q)
    with pytest.raises(InputError, match="no stored edge 'map -> laser'"):
        robot_tree().samples("map", "laser")


def test_quaternions_are_normalised():
    tr = RigidTransforms([[0, 0, 0]], [[0, 0, 2, 2]])
    np.testing.assert_allclose(tr.quaternion_xyzw, [RZ90_Q])
    with pytest.raises(ValueError):  # read-only: a result cannot be changed by accident
        tr.translation_m[0, 0] = 1.0


# --------------------------------------------------------------------------- planar


def test_planar_pose_of_a_tilted_robot_keeps_the_heading():
    from scipy.spatial.transform import Rotation

    r = Rotation.from_euler("ZYX", [30, 5, -3], degrees=True)  # yaw, then pitch and roll
    tr = RigidTransforms.from_rotation([[1.0, 2.0, 0.1]], r)
    np.testing.assert_allclose(planar_pose(tr), [[1.0, 2.0, math.radians(30)]], atol=1e-12)
    tilt = math.acos(math.cos(math.radians(5)) * math.cos(math.radians(3)))
    np.testing.assert_allclose(tilt_rad(tr), [tilt], atol=1e-12)


def test_se2_relative_compose_and_inverse():
    a = np.array([1.0, 2.0, math.pi / 2])
    b = np.array([1.0, 3.0, math.pi])
    # b is 1 m ahead of a (a faces +y) and turned 90 deg left
    np.testing.assert_allclose(se2_relative(a, b), [1.0, 0.0, math.pi / 2], atol=1e-15)
    np.testing.assert_allclose(se2_compose(a, se2_relative(a, b)), b, atol=1e-15)
    np.testing.assert_allclose(se2_compose(a, se2_inverse(a)), [0, 0, 0], atol=1e-15)
    # headings across +-pi: the wrapped difference is the short way unless asked otherwise
    c, d = np.array([0, 0, 3.1]), np.array([0, 0, -3.1])
    assert se2_relative(c, d)[2] == pytest.approx(2 * math.pi - 6.2)
    assert se2_relative(c, d, wrap=False)[2] == pytest.approx(-6.2)
    np.testing.assert_allclose(
        wrap_angle([math.pi, -math.pi, 7.0]), [-math.pi, -math.pi, 7 - 2 * math.pi]
    )


def test_se2_conjugate_is_the_motion_of_a_mounted_frame():
    """A sensor 0.3 m ahead of the axle, facing left: a spot turn of the robot by 90 deg CCW
    moves the sensor 0.3 m back-left along its arc; in the sensor's own start frame (x left of
    the robot, y backwards) that is (0.3, 0.3) and the same 90 deg turn."""
    mount = np.array([0.3, 0.0, math.pi / 2])
    spin = np.array([0.0, 0.0, math.pi / 2])
    np.testing.assert_allclose(se2_conjugate(spin, mount), [0.3, 0.3, math.pi / 2], atol=1e-15)
    # the definition, for many motions at once, and what a mounted frame sees of absolute poses
    rng = np.random.default_rng(1000)
    poses = rng.uniform(-3, 3, (20, 3))
    got = se2_conjugate(poses, mount)
    want = se2_compose(se2_inverse(mount), se2_compose(poses, mount))
    assert np.array_equal(got, want)
    sensor = se2_compose(poses, mount)  # the sensor's poses in the robot's start frame
    np.testing.assert_allclose(got, se2_relative(mount, sensor, wrap=False), atol=1e-14)
    # no mounting offset: the motion itself
    np.testing.assert_allclose(se2_conjugate(poses, np.zeros(3)), poses, atol=1e-15)


def test_planar_matches_se2_of_the_composed_chain():
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(1000)
    yaw = rng.uniform(-3, 3, (2, 5))
    xy = rng.normal(size=(2, 5, 2))
    buf = TransformBuffer()
    for (parent, child), k in ((("map", "odom"), 0), (("odom", "base_link"), 1)):
        q = Rotation.from_euler("z", yaw[k][:, None]).as_quat()
        buf.add(parent, child, np.arange(5.0), np.column_stack([xy[k], np.zeros(5)]), q)
    p_mo = np.column_stack([xy[0], yaw[0]])
    p_ob = np.column_stack([xy[1], yaw[1]])
    got = buf.lookup("map", "base_link", np.arange(5.0)).planar()
    want = se2_compose(p_mo, p_ob)
    np.testing.assert_allclose(got[:, :2], want[:, :2], atol=1e-12)
    np.testing.assert_allclose(wrap_angle(got[:, 2] - want[:, 2]), 0, atol=1e-12)
