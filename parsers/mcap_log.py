"""ROS 2 MCAP files (``mcap`` + ``mcap-ros2-support``; JSON-encoded channels too) -> :class:`Flight`.

Topics are picked by schema name, one per role; ``topics={"pose": "/cub1/pose"}`` overrides:

=========  =========================================================  =========================
role       schemas                                                    signals
=========  =========================================================  =========================
pose       geometry_msgs/msg/PoseStamped, PoseWithCovarianceStamped   x y z, qw..qz, roll pitch yaw
twist      geometry_msgs/msg/TwistStamped                             vx vy vz (header frame = world)
odom       nav_msgs/msg/Odometry                                      pose as above; twist.linear is in
                                                                      child_frame_id (body) and is rotated
                                                                      to the world; twist.angular -> wx..
imu        sensor_msgs/msg/Imu                                        wx wy wz, ax ay az (body)
battery    sensor_msgs/msg/BatteryState                               battery_voltage, battery_current
rc         std_msgs/msg/UInt16MultiArray on a topic named *joy*/*rc*   rc1..rcN (PWM µs, not canonical)
=========  =========================================================  =========================

Frames: ROS data follow REP-103 (world ENU, body FLU), the internal convention, so nothing is
rotated, except a ``frame_id`` ending in ``ned`` (REP-105 ``*_ned`` frames: converted NED->ENU,
FRD->FLU). The frame_ids seen are listed in the provenance notes. With several candidate topics
for a role, the one with the most messages is used and the others named in a warning.
ROS ``BatteryState.current`` is negative while discharging; droneid's battery_current is positive
while discharging, so its sign is flipped.

Time: each message's ``header.stamp`` (the measurement time); the MCAP log time where the stamp
is zero or the message has no header. Seconds from the earliest time used.
"""
from __future__ import annotations

import json
import logging
import os
import re

import numpy as np

from droneid.errors import ConfigError, LogFormatError, did_you_mean
from droneid.frames import ned_to_enu, quat_flu_enu_from_frd_ned, quat_to_euler, quat_to_matrix

from ._build import FlightBuilder

log = logging.getLogger(__name__)

__all__ = ["read_mcap", "ROLES"]

ROLES = {
    "pose": ("geometry_msgs/msg/PoseStamped", "geometry_msgs/msg/PoseWithCovarianceStamped"),
    "twist": ("geometry_msgs/msg/TwistStamped",),
    "odom": ("nav_msgs/msg/Odometry",),
    "imu": ("sensor_msgs/msg/Imu",),
    "battery": ("sensor_msgs/msg/BatteryState",),
    "rc": ("std_msgs/msg/UInt16MultiArray",),
}
_RC_TOPIC = re.compile(r"joy|(^|[/_])rc|pwm|servo", re.I)


def _norm_schema(name: str) -> str:
    # "geometry_msgs/PoseStamped" (ROS 1 style / JSON schemas) -> "geometry_msgs/msg/PoseStamped"
    parts = name.split("/")
    return f"{parts[0]}/msg/{parts[-1]}" if len(parts) == 2 else name


def _get(obj, *path):
    for p in path:
        obj = obj[p] if isinstance(obj, dict) else getattr(obj, p)
    return obj


def _pick_topics(path, channels, schemas, counts, overrides, b):
    """role -> channel ids (one topic per role)."""
    by_topic = {}
    for cid, ch in channels.items():
        by_topic.setdefault(ch.topic, []).append(cid)
    chosen = {}
    for role, topic in (overrides or {}).items():
        if role not in ROLES:
            raise ConfigError(f"unknown MCAP topic role {role!r}; roles: {', '.join(ROLES)}"
                              + did_you_mean(role, ROLES))
        if topic not in by_topic:
            raise ConfigError(f"topic {topic!r} for role {role!r} is not in {path}; topics: "
                              f"{', '.join(sorted(by_topic))}" + did_you_mean(topic, by_topic))
        chosen[role] = topic
    for role, names in ROLES.items():
        if role in chosen:
            continue
        cands = sorted({ch.topic for cid, ch in channels.items()
                        if _norm_schema(schemas[ch.schema_id].name if ch.schema_id in schemas else "")
                        in names and (role != "rc" or _RC_TOPIC.search(ch.topic))},
                       key=lambda tp: -sum(counts.get(c, 0) for c in by_topic[tp]))
        if cands:
            chosen[role] = cands[0]
            if len(cands) > 1:
                b.warn(f"several {role} topics ({', '.join(cands)}): using {cands[0]} "
                       f"(choose with --topic {role}=TOPIC)")
    if "odom" in chosen and "pose" in chosen and overrides and "odom" in overrides and "pose" not in overrides:
        del chosen["pose"]
    return chosen


def read_mcap(path, topics=None):
    """Read a ROS 2 MCAP file into a :class:`Flight` (see the module doc)."""
    path = os.fspath(path)
    from mcap.exceptions import McapError
    from mcap.reader import make_reader
    b = FlightBuilder(path, "mcap")
    try:
        from mcap_ros2.decoder import DecoderFactory
        factories = [DecoderFactory()]
    except ImportError:  # pragma: no cover - a dependency; CDR channels then fail below
        factories = []
    with open(path, "rb") as f:
        try:
            reader = make_reader(f, decoder_factories=factories)
            summary = reader.get_summary()
        except (McapError, Exception) as exc:  # noqa: BLE001 - mcap raises several types
            summary = None
            b.warn(f"no usable MCAP summary ({type(exc).__name__}: {exc}); scanning the whole file")
        channels, schemas, counts = _channels(path, f, summary, factories)
        if not channels:
            raise LogFormatError(path, "the MCAP file holds no channels")
        chosen = _pick_topics(path, channels, schemas, counts, topics, b)
        if not chosen:
            names = ", ".join(sorted(f"{c.topic} ({schemas[c.schema_id].name if c.schema_id in schemas else '?'})"
                                     for c in channels.values()))
            raise LogFormatError(path, f"no topic with a known schema (PoseStamped, TwistStamped, "
                                       f"Odometry, Imu, BatteryState); topics: {names}")
        rows = _read_messages(path, f, factories, chosen, b)
    _convert(b, rows, chosen)
    return b.build()


def _channels(path, f, summary, factories):
    if summary is not None:
        counts = dict(summary.statistics.channel_message_counts) if summary.statistics else {}
        return dict(summary.channels), dict(summary.schemas), counts
    from mcap.stream_reader import StreamReader
    from mcap.records import Channel, Message, Schema
    channels, schemas, counts = {}, {}, {}
    f.seek(0)
    try:
        for rec in StreamReader(f, skip_magic=False).records:
            if isinstance(rec, Schema):
                schemas[rec.id] = rec
            elif isinstance(rec, Channel):
                channels[rec.id] = rec
            elif isinstance(rec, Message):
                counts[rec.channel_id] = counts.get(rec.channel_id, 0) + 1
    except Exception:  # noqa: BLE001 - a cut file: keep the channels seen so far
        pass
    return channels, schemas, counts


def _iter_decoded(path, f, factories, topic_list, b):
    """(channel, log_time_ns, decoded message) for the chosen topics, surviving a cut file."""
    from mcap.reader import make_reader
    f.seek(0)
    try:
        reader = make_reader(f, decoder_factories=factories)
        it = reader.iter_messages(topics=topic_list)
        for schema, channel, message in it:
            try:
                if channel.message_encoding == "json":
                    obj = json.loads(message.data)
                else:
                    obj = _decode(reader, factories, schema, channel, message)
            except Exception:  # noqa: BLE001 - one bad message: skip and count
                b.skip(f"{channel.topic}: undecodable messages", 1)
                continue
            yield channel, message.log_time, obj
    except Exception as exc:  # noqa: BLE001 - cut or corrupt file: keep what was read
        b.skip("MCAP read stopped at a corrupt or cut record", 1)
        b.warn(f"MCAP reading stopped early ({type(exc).__name__}: {exc})")


_DECODERS: dict = {}


def _decode(reader, factories, schema, channel, message):
    key = (id(factories[0]) if factories else 0, schema.id if schema else None, channel.message_encoding)
    dec = _DECODERS.get(key)
    if dec is None:
        for fac in factories:
            dec = fac.decoder_for(channel.message_encoding, schema)
            if dec is not None:
                break
        if dec is None:
            raise LogFormatError(reader, f"no decoder for encoding {channel.message_encoding!r}")
        _DECODERS[key] = dec
    return dec(message.data)


def _read_messages(path, f, factories, chosen, b):
    topic_role = {tp: role for role, tp in chosen.items()}
    rows = {role: {"t": [], "msgs": [], "frame": set()} for role in chosen}
    _DECODERS.clear()
    for channel, log_ns, obj in _iter_decoded(path, f, factories, list(topic_role), b):
        role = topic_role[channel.topic]
        r = rows[role]
        t_ns = log_ns
        try:
            hdr = _get(obj, "header")
            stamp = _get(hdr, "stamp")
            s = int(_get(stamp, "sec")) * 1_000_000_000 + int(_get(stamp, "nanosec"))
            if s > 0:
                t_ns = s
            r["frame"].add(str(_get(hdr, "frame_id")))
        except (KeyError, AttributeError, TypeError):
            pass
        r["t"].append(t_ns)
        r["msgs"].append(obj)
    return rows


def _xyz(msgs, *path):
    out = np.empty((len(msgs), 3))
    for i, m in enumerate(msgs):
        v = _get(m, *path)
        out[i] = (_get(v, "x"), _get(v, "y"), _get(v, "z"))
    return out


def _quat(msgs, *path):
    out = np.empty((len(msgs), 4))
    for i, m in enumerate(msgs):
        q = _get(m, *path)
        out[i] = (_get(q, "w"), _get(q, "x"), _get(q, "y"), _get(q, "z"))
    return out


def _convert(b: FlightBuilder, rows, chosen):
    t0 = min((min(r["t"]) for r in rows.values() if r["t"]), default=None)
    if t0 is None:
        return
    for role, r in rows.items():
        if not r["t"]:
            continue
        t = (np.asarray(r["t"], dtype=np.int64) - t0) * 1e-9
        msgs = r["msgs"]
        topic = chosen[role]
        ned = any(fr.lower().endswith("ned") for fr in r["frame"])
        if r["frame"]:
            b.notes.append(f"{topic}: frame_id {', '.join(sorted(r['frame']))}"
                           + (" (NED, converted to ENU)" if ned else " (taken as ENU/FLU, REP-103)"))
        if role in ("pose", "odom"):
            base = ("pose",) if role == "pose" else ("pose", "pose")
            if role == "pose" and msgs and _has(msgs[0], "pose", "pose"):
                base = ("pose", "pose")  # PoseWithCovarianceStamped
            p = _xyz(msgs, *base, "position")
            q = _quat(msgs, *base, "orientation")
            if ned:
                p = np.stack(ned_to_enu(p[:, 0], p[:, 1], p[:, 2]), axis=-1)
                q = quat_flu_enu_from_frd_ned(q)
            q = q / np.linalg.norm(q, axis=-1, keepdims=True)
            q = np.where(q[:, :1] < 0, -q, q)
            src = f"{topic} pose"
            b.add_many(t, {"x": p[:, 0], "y": p[:, 1], "z": p[:, 2]}, dict.fromkeys("xyz", "m"), src + ".position")
            b.add_many(t, {"qw": q[:, 0], "qx": q[:, 1], "qy": q[:, 2], "qz": q[:, 3]},
                       dict.fromkeys(("qw", "qx", "qy", "qz"), "1"), src + ".orientation")
            roll, pitch, yaw = quat_to_euler(q)
            b.add_many(t, {"roll": roll, "pitch": pitch, "yaw": yaw},
                       dict.fromkeys(("roll", "pitch", "yaw"), "rad"), src + ".orientation (to Euler)")
            if role == "odom":
                v_body = _xyz(msgs, "twist", "twist", "linear")
                w = _xyz(msgs, "twist", "twist", "angular")
                if ned:
                    v_body = v_body * np.array([1, -1, -1])
                    w = w * np.array([1, -1, -1])
                v = np.einsum("nij,nj->ni", quat_to_matrix(q), v_body)
                b.add_many(t, {"vx": v[:, 0], "vy": v[:, 1], "vz": v[:, 2]},
                           dict.fromkeys(("vx", "vy", "vz"), "m/s"), f"{topic} twist.linear (body -> world)")
                b.add_many(t, {"wx": w[:, 0], "wy": w[:, 1], "wz": w[:, 2]},
                           dict.fromkeys(("wx", "wy", "wz"), "rad/s"), f"{topic} twist.angular")
        elif role == "twist":
            v = _xyz(msgs, "twist", "linear")
            if ned:
                v = np.stack(ned_to_enu(v[:, 0], v[:, 1], v[:, 2]), axis=-1)
            b.add_many(t, {"vx": v[:, 0], "vy": v[:, 1], "vz": v[:, 2]},
                       dict.fromkeys(("vx", "vy", "vz"), "m/s"), f"{topic} twist.linear")
        elif role == "imu":
            w = _xyz(msgs, "angular_velocity")
            a = _xyz(msgs, "linear_acceleration")
            if ned:
                w, a = w * np.array([1, -1, -1]), a * np.array([1, -1, -1])
            if "wx" not in b.signals:
                b.add_many(t, {"wx": w[:, 0], "wy": w[:, 1], "wz": w[:, 2]},
                           dict.fromkeys(("wx", "wy", "wz"), "rad/s"), f"{topic} angular_velocity")
            b.add_many(t, {"ax": a[:, 0], "ay": a[:, 1], "az": a[:, 2]},
                       dict.fromkeys(("ax", "ay", "az"), "m/s^2"), f"{topic} linear_acceleration")
        elif role == "battery":
            v = np.array([float(_get(m, "voltage")) for m in msgs])
            c = np.array([float(_get(m, "current")) for m in msgs])
            b.add("battery_voltage", t, v, "V", f"{topic} voltage")
            b.add("battery_current", t, -c, "A", f"{topic} -current (ROS: negative discharging)")
        elif role == "rc":
            data = [list(_get(m, "data")) for m in msgs]
            n = min(len(d) for d in data) if data else 0
            arr = np.array([d[:n] for d in data], float)
            for i in range(n):
                b.add(f"rc{i + 1}", t, arr[:, i], "us", f"{topic} data[{i}]")
    b.in_flight_from_height()


def _has(obj, *path) -> bool:
    try:
        _get(obj, *path)
        return True
    except (KeyError, AttributeError, TypeError):
        return False
