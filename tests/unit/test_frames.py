import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from droneid.core import frames

angle = st.floats(-3.0, 3.0)
small = st.floats(-1.4, 1.4)


@settings(max_examples=200, deadline=None)
@given(angle, small, angle)
def test_euler_quat_matrix_agree(roll, pitch, yaw):
    q = frames.euler_to_quat(roll, pitch, yaw)
    np.testing.assert_allclose(frames.quat_to_matrix(q), frames.euler_to_matrix(roll, pitch, yaw), atol=1e-12)
    r2, p2, y2 = frames.quat_to_euler(q)
    np.testing.assert_allclose([r2, p2], [roll, pitch], atol=1e-9)
    assert abs(frames.wrap_angle(y2 - yaw)) < 1e-9


def test_positive_pitch_is_nose_down_and_tilts_thrust_forward():
    R = frames.euler_to_matrix(0.0, 0.2, 0.0)
    nose = R @ np.array([1.0, 0, 0])
    thrust = R @ np.array([0, 0, 1.0])
    assert nose[2] < 0          # nose points down
    assert thrust[0] > 0        # thrust tilts towards +x (forward): accelerates forward


def test_positive_roll_is_right_side_down_and_thrust_to_the_right():
    R = frames.euler_to_matrix(0.2, 0.0, 0.0)
    left = R @ np.array([0, 1.0, 0])
    thrust = R @ np.array([0, 0, 1.0])
    assert left[2] > 0          # left side goes up
    assert thrust[1] < 0        # thrust towards -y (the right)


@settings(max_examples=200, deadline=None)
@given(angle, small, angle)
def test_frd_ned_euler_and_quaternion_conversions_agree(roll, pitch, yaw):
    """Converting NED/FRD Euler angles and the NED/FRD quaternion gives the same ENU/FLU attitude."""
    q_ned = frames.euler_to_quat(roll, pitch, yaw)  # same Z-Y-X formula, FRD in NED
    q_enu = frames.quat_flu_enu_from_frd_ned(q_ned)
    r, p, y = frames.euler_frd_ned_to_flu_enu(roll, pitch, yaw)
    np.testing.assert_allclose(frames.quat_to_matrix(q_enu), frames.euler_to_matrix(r, p, y), atol=1e-9)


def test_ned_nose_up_is_flu_nose_down_negative():
    # ArduPilot pitch +0.1 (nose up) facing north -> FLU pitch -0.1, yaw pi/2 (north)
    r, p, y = frames.euler_frd_ned_to_flu_enu(0.0, 0.1, 0.0)
    assert p == -0.1 and abs(y - np.pi / 2) < 1e-12
    x, yy, z = frames.ned_to_enu(1.0, 2.0, 3.0)
    assert (x, yy, z) == (2.0, 1.0, -3.0)


def test_wrap_angle_range():
    a = frames.wrap_angle(np.linspace(-20, 20, 1001))
    assert a.min() >= -np.pi and a.max() < np.pi
