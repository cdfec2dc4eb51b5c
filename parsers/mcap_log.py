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
(scalar)   std_msgs/msg/Float32 or Float64 on a topic whose last name  that canonical signal
           is a canonical signal (``/drone/throttle``, ``/x/battery_voltage``)
motors     std_msgs/msg/Float32MultiArray / Float64MultiArray on a     motor1..motorN (0..1)
           topic whose last name is ``motors``
=========  =========================================================  =========================

``topics=`` also maps a canonical signal to a std_msgs topic: ``{"rpm1": "/esc/rpm1"}`` (a
Float32/Float64), or to one element of an array topic: ``{"throttle": "/cub1/joy_serial_status[2]"}``
(``--topic throttle=/cub1/joy_serial_status[2]``). Dimensionless commands (throttle, motorN) in
PWM µs or percent are normalised to 0..1 by their range (:func:`parsers._build.command_to_unit`).

Frames: ROS data follow REP-103 (world ENU, body FLU), the internal convention, so nothing is
rotated, except a ``frame_id`` ending in ``ned`` or ``frd`` (REP-105 ``*_ned`` world and ``*_frd``
body frames: converted NED->ENU, FRD->FLU). The frame_ids seen are listed in the provenance notes. With several candidate topics
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
import struct

import numpy as np

from droneid.errors import ConfigError, LogFormatError, did_you_mean
from droneid.logs.flight import Flight, canonical_unit, is_canonical
from droneid.core.frames import ned_to_enu, quat_flu_enu_from_frd_ned, quat_to_euler, quat_to_matrix

from ._build import FlightBuilder, command_to_unit
from ._registry import Reader

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
_ELEMENT = re.compile(r"(.+)\[(\d+)\]")      # "/cub1/joy_serial_status[2]": element 2 of data
_RC_TOPIC = re.compile(r"joy|(^|[/_])rc|pwm|servo", re.I)
_SCALAR_SCHEMAS = ("std_msgs/msg/Float32", "std_msgs/msg/Float64")
_ARRAY_SCHEMAS = ("std_msgs/msg/Float32MultiArray", "std_msgs/msg/Float64MultiArray")


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
        if is_canonical(role) and role not in ROLES:    # a signal from a topic (and array element)
            m = _ELEMENT.fullmatch(topic)
            topic, role = (m.group(1), f"scalar:{role}[{m.group(2)}]") if m else (topic, f"scalar:{role}")
        elif role not in ROLES:
            raise ConfigError(f"unknown MCAP topic role {role!r}; roles: {', '.join(ROLES)}, or a "
                              f"canonical signal (throttle=/rc[2], rpm1=/esc/rpm1)"
                              + did_you_mean(role, ROLES))
        if topic not in by_topic:
            raise ConfigError(f"topic {topic!r} for role {role!r} is not in {path}; topics: "
                              f"{', '.join(sorted(by_topic))}" + did_you_mean(topic, by_topic))
        chosen[role] = topic
    for cid, ch in channels.items():  # plain std_msgs numbers named after a canonical signal
        sname = _norm_schema(schemas[ch.schema_id].name) if ch.schema_id in schemas else ""
        base = ch.topic.rstrip("/").rsplit("/", 1)[-1]
        if sname in _SCALAR_SCHEMAS and is_canonical(base) and not any(
                k == f"scalar:{base}" or k.startswith(f"scalar:{base}[") for k in chosen):
            chosen[f"scalar:{base}"] = ch.topic
        elif sname in _ARRAY_SCHEMAS and base == "motors" and "motors" not in chosen:
            chosen["motors"] = ch.topic
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
    return chosen


def read_mcap(path, topics=None, *, _fast: bool = True) -> Flight:
    """Read a ROS 2 MCAP file into a :class:`Flight` (see the module doc).

    Header-first geometry messages in CDR are decoded straight into numpy (``_fast``; falls back
    to mcap-ros2's decoder for anything else, and tests compare both)."""
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
            b.warn(f"no MCAP summary ({type(exc).__name__}); the file is probably cut: "
                   f"scanning it record by record")
        channels, schemas, counts = _channels(path, f, summary, factories)
        if not channels:
            raise LogFormatError(path, "the MCAP file holds no channels")
        chosen = _pick_topics(path, channels, schemas, counts, topics, b)
        if not chosen:
            names = ", ".join(sorted(f"{c.topic} ({schemas[c.schema_id].name if c.schema_id in schemas else '?'})"
                                     for c in channels.values()))
            raise LogFormatError(path, f"no topic with a known schema (PoseStamped, TwistStamped, "
                                       f"Odometry, Imu, BatteryState); topics: {names}")
        rows = _read_messages(path, f, factories, chosen, b, fast=_fast)
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


_P, _Q = ("position",), ("orientation",)
_XYZ, _XYZW = ("x", "y", "z"), ("x", "y", "z", "w")


def _paths(prefix, names):
    return [prefix + (n,) for n in names]


#: schema -> field paths giving one float vector per message (role order, see _convert)
_FIELDS = {
    "geometry_msgs/msg/PoseStamped": _paths(("pose", "position"), _XYZ) + _paths(("pose", "orientation"), _XYZW),
    "geometry_msgs/msg/PoseWithCovarianceStamped": _paths(("pose", "pose", "position"), _XYZ)
    + _paths(("pose", "pose", "orientation"), _XYZW),
    "geometry_msgs/msg/TwistStamped": _paths(("twist", "linear"), _XYZ) + _paths(("twist", "angular"), _XYZ),
    "nav_msgs/msg/Odometry": _paths(("pose", "pose", "position"), _XYZ)
    + _paths(("pose", "pose", "orientation"), _XYZW) + _paths(("twist", "twist", "linear"), _XYZ)
    + _paths(("twist", "twist", "angular"), _XYZ),
    "sensor_msgs/msg/Imu": _paths(("angular_velocity",), _XYZ) + _paths(("linear_acceleration",), _XYZ),
    "sensor_msgs/msg/BatteryState": [("voltage",), ("current",)],
}
#: schema -> (has a child_frame_id string after the header, float64 indices after the header)
#: for decoding CDR directly into numpy (the layout is fixed by the message definitions)
_FAST_CDR = {
    "geometry_msgs/msg/PoseStamped": (False, list(range(7))),
    "geometry_msgs/msg/PoseWithCovarianceStamped": (False, list(range(7))),
    "geometry_msgs/msg/TwistStamped": (False, list(range(6))),
    "nav_msgs/msg/Odometry": (True, list(range(7)) + list(range(43, 49))),
    "sensor_msgs/msg/Imu": (False, [13, 14, 15, 25, 26, 27]),
}


def _cdr_fast(data: bytes, child: bool, idx: list):
    """(stamp_ns, frame_id, float vector) from a CDR message with a std_msgs/Header first."""
    if len(data) < 16 or data[0] != 0:
        raise ValueError("not plain CDR")
    e = "<" if data[1] & 1 else ">"
    sec, nsec, slen = struct.unpack_from(e + "iII", data, 4)
    pos = 16 + slen
    frame = data[16:16 + max(slen - 1, 0)].decode("utf-8", "replace")
    if child:
        pos = 4 + ((pos - 4 + 3) & ~3)
        (clen,) = struct.unpack_from(e + "I", data, pos)
        pos += 4 + clen
    pos = 4 + ((pos - 4 + 7) & ~7)
    n = max(idx) + 1
    if pos + 8 * n > len(data):
        raise ValueError("CDR message too short")
    vec = np.frombuffer(data, dtype=e + "f8", count=n, offset=pos)[idx]
    return sec * 1_000_000_000 + nsec, frame, vec


def _iter_records(f, topic_list, b):
    """(channel, schema, Message record) for the chosen topics, in file order.

    Streams the records (no index needed), so a file cut anywhere yields everything before
    the cut; the cut is counted.
    """
    from mcap.records import Channel, Message, Schema
    from mcap.stream_reader import StreamReader
    wanted = set(topic_list)
    schemas, channels = {}, {}
    f.seek(0)
    try:
        for rec in StreamReader(f, skip_magic=False).records:
            if isinstance(rec, Message):
                ch = channels.get(rec.channel_id)
                if ch is not None and ch.topic in wanted:
                    yield ch, schemas.get(ch.schema_id), rec
            elif isinstance(rec, Schema):
                schemas[rec.id] = rec
            elif isinstance(rec, Channel):
                channels[rec.id] = rec
    except Exception as exc:  # noqa: BLE001 - cut or corrupt file: keep what was read
        b.skip("MCAP read stopped at a corrupt or cut record", 1)
        b.warn(f"MCAP reading stopped early ({type(exc).__name__}: {str(exc)[:120]})")


def _decoder(path, factories, schema, channel, cache):
    key = (schema.id if schema else None, channel.message_encoding)
    dec = cache.get(key)
    if dec is None:
        if channel.message_encoding == "json":
            dec = json.loads
        else:
            for fac in factories:
                dec = fac.decoder_for(channel.message_encoding, schema)
                if dec is not None:
                    break
        if dec is None:
            raise LogFormatError(path, f"no decoder for message encoding {channel.message_encoding!r} "
                                       f"(topic {channel.topic})")
        cache[key] = dec
    return dec


def _generic(obj, schema_name):
    """(stamp_ns or 0, frame_id or None, vector) from a decoded message (object or JSON dict)."""
    stamp, frame = 0, None
    if _has(obj, "header"):
        hdr = _get(obj, "header")
        st = _get(hdr, "stamp")
        stamp = int(_get(st, "sec")) * 1_000_000_000 + int(_get(st, "nanosec"))
        frame = str(_get(hdr, "frame_id"))
    if schema_name == "std_msgs/msg/UInt16MultiArray" or schema_name in _ARRAY_SCHEMAS:
        return stamp, frame, np.asarray(list(_get(obj, "data")), float)
    if schema_name in _SCALAR_SCHEMAS:
        return stamp, frame, np.array([float(_get(obj, "data"))])
    return stamp, frame, np.array([float(_get(obj, *p)) for p in _FIELDS[schema_name]])


def _read_messages(path, f, factories, chosen, b, fast: bool = True):
    """role -> {"t": log/stamp ns, "vec": float vectors, "frame": frame_ids} (numbers only)."""
    topic_roles: dict[str, list[str]] = {}
    for role, tp in chosen.items():
        topic_roles.setdefault(tp, []).append(role)
    rows = {role: {"t": [], "vec": [], "frame": set(), "schema": None} for role in chosen}
    cache: dict = {}
    for ch, schema, rec in _iter_records(f, list(topic_roles), b):
        name = _norm_schema(schema.name) if schema else ""
        try:
            spec = _FAST_CDR.get(name) if fast and ch.message_encoding == "cdr" else None
            try:
                stamp, frame, vec = _cdr_fast(rec.data, *spec) if spec else (None, None, None)
            except (ValueError, struct.error):
                stamp = None
            if stamp is None:
                obj = _decoder(path, factories, schema, ch, cache)(rec.data)
                stamp, frame, vec = _generic(obj, name)
        except LogFormatError:
            raise
        except Exception:  # noqa: BLE001 - one bad message: skip and count
            b.skip(f"{ch.topic}: undecodable messages", 1)
            continue
        for role in topic_roles[ch.topic]:
            r = rows[role]
            r["schema"] = name
            if frame is not None:
                r["frame"].add(frame)
            r["t"].append(stamp if stamp > 0 else rec.log_time)
            r["vec"].append(vec)
    return rows


def _convert(b: FlightBuilder, rows, chosen):
    t0 = min((min(r["t"]) for r in rows.values() if r["t"]), default=None)
    if t0 is None:
        return
    # odom first: a dedicated pose / twist / imu topic then replaces what odom gave
    for role in sorted(rows, key=lambda k: k != "odom"):
        r = rows[role]
        if not r["t"]:
            continue
        t = (np.asarray(r["t"], dtype=np.int64) - t0) * 1e-9
        topic = chosen[role]
        ned = any(fr.lower().endswith(("ned", "frd")) for fr in r["frame"])
        if r["frame"] - {""} and role != "battery":
            b.notes.append(f"{topic}: frame_id {', '.join(sorted(r['frame'] - {''}))}"
                           + (" (NED/FRD, converted to ENU/FLU)" if ned else " (taken as ENU/FLU, REP-103)"))
        if role in ("rc", "motors"):
            n = min(v.size for v in r["vec"])
            arr = np.array([v[:n] for v in r["vec"]], float)
            for i in range(n):
                if role == "rc":
                    b.add(f"rc{i + 1}", t, arr[:, i], "us", f"{topic} data[{i}]")
                else:
                    v, how = command_to_unit(arr[:, i])
                    b.add(f"motor{i + 1}", t, v, "1", f"{topic} data[{i}] ({how})")
            continue
        if role.startswith("scalar:"):
            m = _ELEMENT.fullmatch(role.split(":", 1)[1])
            name, k = (m.group(1), int(m.group(2))) if m else (role.split(":", 1)[1], 0)
            ok = np.array([v.size > k for v in r["vec"]])
            b.skip(f"{topic}: messages without element {k}", int((~ok).sum()))
            v = np.array([v[k] for v in r["vec"] if v.size > k], float)
            src = f"{topic} data" + (f"[{k}]" if m else "")
            if canonical_unit(name) == "1" and name != "qw" and not name.startswith("q"):
                v, how = command_to_unit(v)          # throttle / motorN given as PWM or %
                src += f" ({how})"
            b.add(name, t[ok], v, canonical_unit(name), src)
            continue
        V = np.vstack(r["vec"])
        if role in ("pose", "odom"):
            p, q = V[:, 0:3], V[:, [6, 3, 4, 5]]          # (w, x, y, z)
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
                v_body, w = V[:, 7:10], V[:, 10:13]
                if ned:   # FRD body -> FLU body
                    v_body, w = v_body * np.array([1, -1, -1]), w * np.array([1, -1, -1])
                v = np.einsum("nij,nj->ni", quat_to_matrix(q), v_body)
                b.add_many(t, {"vx": v[:, 0], "vy": v[:, 1], "vz": v[:, 2]},
                           dict.fromkeys(("vx", "vy", "vz"), "m/s"), f"{topic} twist.linear (body -> world)")
                b.add_many(t, {"wx": w[:, 0], "wy": w[:, 1], "wz": w[:, 2]},
                           dict.fromkeys(("wx", "wy", "wz"), "rad/s"), f"{topic} twist.angular")
        elif role == "twist":
            v = V[:, 0:3]
            if ned:
                v = np.stack(ned_to_enu(v[:, 0], v[:, 1], v[:, 2]), axis=-1)
            b.add_many(t, {"vx": v[:, 0], "vy": v[:, 1], "vz": v[:, 2]},
                       dict.fromkeys(("vx", "vy", "vz"), "m/s"), f"{topic} twist.linear")
        elif role == "imu":
            w, a = V[:, 0:3], V[:, 3:6]
            if ned:
                w, a = w * np.array([1, -1, -1]), a * np.array([1, -1, -1])
            b.add_many(t, {"wx": w[:, 0], "wy": w[:, 1], "wz": w[:, 2]},
                       dict.fromkeys(("wx", "wy", "wz"), "rad/s"), f"{topic} angular_velocity")
            b.add_many(t, {"ax": a[:, 0], "ay": a[:, 1], "az": a[:, 2]},
                       dict.fromkeys(("ax", "ay", "az"), "m/s^2"), f"{topic} linear_acceleration")
        elif role == "battery":
            # ROS: NaN means "not measured" (not damage); current is negative while discharging
            for k, name, unit, sign, src in ((0, "battery_voltage", "V", 1.0, "voltage"),
                                             (1, "battery_current", "A", -1.0, "-current (ROS: negative discharging)")):
                ok = np.isfinite(V[:, k])
                if ok.any():
                    b.skip(f"{topic} {name}: NaN (not measured)", int((~ok).sum()))
                    b.add(name, t[ok], sign * V[ok, k], unit, f"{topic} {src}")
                else:
                    b.notes.append(f"{topic}: {name.split('_')[1]} not measured (NaN)")
    b.in_flight_from_height()


def _has(obj, *path) -> bool:
    try:
        _get(obj, *path)
        return True
    except (KeyError, AttributeError, TypeError):
        return False


def sniff(head: bytes) -> bool:
    """An MCAP file starts with the magic 0x89 ``MCAP0`` CR LF."""
    return head.startswith(b"\x89MCAP0\r\n")


READER = Reader("mcap", read_mcap, sniff, order=10, extensions=(".mcap",), options=("topics",),
                description="ROS 2 MCAP (.mcap), read with mcap + mcap-ros2-support")
