"""Build small MAVLink tlogs in memory (pymavlink's own encoder) for planted-truth tests."""
from __future__ import annotations

T0_US = 1_700_000_000_000_000


def tlog_bytes(messages, sysid: int = 1, compid: int = 1, v2: bool = True) -> bytes:
    """``messages``: (encoder name without ``_encode``, t_s, fields) tuples."""
    from pymavlink.dialects.v20 import ardupilotmega as mav
    defaults = {
        "heartbeat": dict(type=2, autopilot=3, base_mode=0, custom_mode=0, system_status=3, mavlink_version=3),
    }
    out = bytearray()
    m = mav.MAVLink(None, srcSystem=sysid, srcComponent=compid)
    if not v2:
        m.WIRE_PROTOCOL_VERSION = "1.0"
    for item in messages:
        name, t_s, fields = item[:3]
        src = item[3] if len(item) > 3 else sysid
        m.srcSystem = src
        kw = dict(defaults.get(name, {}))
        kw.update(fields)
        msg = getattr(m, f"{name}_encode")(**kw)
        frame = msg.pack(m, force_mavlink1=not v2)
        out += int(T0_US + round(t_s * 1e6)).to_bytes(8, "big") + frame
    return bytes(out)
