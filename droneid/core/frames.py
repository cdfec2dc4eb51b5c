"""Frames, Euler angles and quaternions: droneid's ONE internal convention.

* World frame: **ENU**, x east, y north, z up, metres, origin at the log's local origin.
* Body frame: **FLU**, x forward, y left, z up.
* Attitude quaternion ``(qw, qx, qy, qz)``: Hamilton, scalar first, rotates body FLU vectors
  into the world ENU frame.
* Euler angles ``roll, pitch, yaw`` (radians): intrinsic **Z-Y-X** (yaw about z, then pitch about
  the new y, then roll about the new x), so ``R = Rz(yaw) @ Ry(pitch) @ Rx(roll)``.
  With FLU axes, positive pitch is nose **down** and positive roll is right side **down**;
  yaw is measured counter-clockwise from east. This is ROS REP-103.
* Conversions from NED/FRD (ArduPilot, PX4, MAVLink) happen only in the parsers, through
  :func:`ned_to_enu`, :func:`frd_to_flu` and :func:`euler_frd_ned_to_flu_enu`.

The paper's tilt-drag model ``v̇x = g cosψ tanθ/cosφ + g sinψ tanφ − k_D vx`` uses these angles:
a positive pitch (nose down) accelerates the vehicle forward.
"""
from __future__ import annotations

import numpy as np

__all__ = [
    "wrap_angle", "unwrap_angle", "ned_to_enu", "frd_to_flu", "euler_frd_ned_to_flu_enu",
    "euler_to_quat", "quat_to_euler", "quat_to_matrix", "euler_to_matrix",
    "quat_flu_enu_from_frd_ned", "qmul", "body_rates_from_euler", "WORLD_FRAMES", "BODY_FRAMES",
]

#: the world and body frames a log may be in (``--world-frame``, ``--body-frame``): droneid's own
#: first; the others are converted once at the reader boundary (parsers/_convention.py)
WORLD_FRAMES = ("enu", "ned")
BODY_FRAMES = ("flu", "frd")


def wrap_angle(a):
    """Wrap angles (rad) into [-pi, pi)."""
    a = np.asarray(a, dtype=float)
    return (a + np.pi) % (2.0 * np.pi) - np.pi


def unwrap_angle(a):
    """Remove 2*pi jumps from an angle series (rad) so it can be interpolated."""
    return np.unwrap(np.asarray(a, dtype=float))


def ned_to_enu(n, e, d):
    """A NED vector (north, east, down) as ENU components ``(x=east, y=north, z=up)``."""
    return np.asarray(e, float), np.asarray(n, float), -np.asarray(d, float)


def frd_to_flu(x, y, z):
    """A body vector in FRD (forward, right, down: rates, accelerations) as FLU components:
    ``(x, -y, -z)``, a 180 deg rotation about x."""
    return np.asarray(x, float), -np.asarray(y, float), -np.asarray(z, float)


def euler_frd_ned_to_flu_enu(roll, pitch, yaw):
    """Z-Y-X Euler angles of an FRD body in NED (ArduPilot, PX4) as droneid's FLU/ENU angles.

    ``roll`` keeps its value, ``pitch`` changes sign (nose up is positive in FRD, negative in
    FLU), and ``yaw`` becomes ``pi/2 - yaw`` (north-clockwise to east-counter-clockwise), wrapped.
    """
    return (np.asarray(roll, float), -np.asarray(pitch, float),
            wrap_angle(np.pi / 2.0 - np.asarray(yaw, float)))


def euler_to_matrix(roll, pitch, yaw):
    """Rotation matrices ``R = Rz(yaw) Ry(pitch) Rx(roll)``, shape (..., 3, 3)."""
    roll, pitch, yaw = np.broadcast_arrays(*(np.asarray(v, float) for v in (roll, pitch, yaw)))
    cr, sr = np.cos(roll), np.sin(roll)
    cp, sp = np.cos(pitch), np.sin(pitch)
    cy, sy = np.cos(yaw), np.sin(yaw)
    R = np.empty(roll.shape + (3, 3))
    R[..., 0, 0] = cy * cp
    R[..., 0, 1] = cy * sp * sr - sy * cr
    R[..., 0, 2] = cy * sp * cr + sy * sr
    R[..., 1, 0] = sy * cp
    R[..., 1, 1] = sy * sp * sr + cy * cr
    R[..., 1, 2] = sy * sp * cr - cy * sr
    R[..., 2, 0] = -sp
    R[..., 2, 1] = cp * sr
    R[..., 2, 2] = cp * cr
    return R


def body_rates_from_euler(euler, euler_rates):
    """Body rates (n, 3) in rad/s (FLU: about forward, left, up) from Z-Y-X Euler angles (n, 3)
    ``(roll, pitch, yaw)`` in rad and their time derivatives (n, 3) in rad/s."""
    euler, euler_rates = np.asarray(euler, float), np.asarray(euler_rates, float)
    r, p = euler[:, 0], euler[:, 1]
    dr, dp, dy = euler_rates[:, 0], euler_rates[:, 1], euler_rates[:, 2]
    return np.column_stack([dr - np.sin(p) * dy,
                            np.cos(r) * dp + np.sin(r) * np.cos(p) * dy,
                            -np.sin(r) * dp + np.cos(r) * np.cos(p) * dy])


def euler_to_quat(roll, pitch, yaw):
    """Z-Y-X Euler angles (rad) to Hamilton quaternions ``(qw, qx, qy, qz)``, shape (..., 4)."""
    roll, pitch, yaw = np.broadcast_arrays(*(np.asarray(v, float) / 2.0 for v in (roll, pitch, yaw)))
    cr, sr = np.cos(roll), np.sin(roll)
    cp, sp = np.cos(pitch), np.sin(pitch)
    cy, sy = np.cos(yaw), np.sin(yaw)
    q = np.empty(roll.shape + (4,))
    q[..., 0] = cr * cp * cy + sr * sp * sy
    q[..., 1] = sr * cp * cy - cr * sp * sy
    q[..., 2] = cr * sp * cy + sr * cp * sy
    q[..., 3] = cr * cp * sy - sr * sp * cy
    return q


def quat_to_euler(q):
    """Hamilton quaternions ``(qw, qx, qy, qz)`` (..., 4) to Z-Y-X ``(roll, pitch, yaw)`` in rad.

    The quaternion is normalised first; pitch is clipped to [-pi/2, pi/2] at gimbal lock.
    """
    q = np.asarray(q, float)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    roll = np.arctan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    pitch = np.arcsin(np.clip(2.0 * (w * y - z * x), -1.0, 1.0))
    yaw = np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    return roll, pitch, yaw


def quat_to_matrix(q):
    """Hamilton quaternions (..., 4) to rotation matrices (..., 3, 3) (body to world)."""
    q = np.asarray(q, float)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    R = np.empty(q.shape[:-1] + (3, 3))
    R[..., 0, 0] = 1 - 2 * (y * y + z * z)
    R[..., 0, 1] = 2 * (x * y - w * z)
    R[..., 0, 2] = 2 * (x * z + w * y)
    R[..., 1, 0] = 2 * (x * y + w * z)
    R[..., 1, 1] = 1 - 2 * (x * x + z * z)
    R[..., 1, 2] = 2 * (y * z - w * x)
    R[..., 2, 0] = 2 * (x * z - w * y)
    R[..., 2, 1] = 2 * (y * z + w * x)
    R[..., 2, 2] = 1 - 2 * (x * x + y * y)
    return R


_Q_NED_TO_ENU = np.array([0.0, np.sqrt(0.5), np.sqrt(0.5), 0.0])  # rotation taking NED axes to ENU
_Q_FLU_TO_FRD = np.array([0.0, 1.0, 0.0, 0.0])                    # 180 deg about x


def qmul(a, b):
    """Hamilton product ``a ⊗ b`` of quaternions (..., 4), scalar first (broadcasts)."""
    a, b = np.broadcast_arrays(np.asarray(a, float), np.asarray(b, float))
    w1, x1, y1, z1 = np.moveaxis(a, -1, 0)
    w2, x2, y2, z2 = np.moveaxis(b, -1, 0)
    return np.stack([
        w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
        w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
        w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
        w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
    ], axis=-1)


def quat_flu_enu_from_frd_ned(q_frd_ned):
    """A quaternion rotating FRD body to NED world (PX4, MAVLink) as FLU body to ENU world.

    ``q_enu_flu = q_ned->enu * q_ned_frd * q_flu->frd``, all Hamilton, scalar first.
    """
    q = qmul(qmul(_Q_NED_TO_ENU, np.asarray(q_frd_ned, float)), _Q_FLU_TO_FRD)
    # keep the scalar part non-negative: same rotation, continuous sign
    return np.where(q[..., :1] < 0, -q, q)
