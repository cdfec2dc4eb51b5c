"""Write tiny ArduPilot DataFlash logs for planted-truth tests (the record layout pymavlink's
DFReader reads: 0xA3 0x95, type byte, packed little-endian fields; FMT records first).
``DataFlashWriter(sdlog2=True)`` writes the records as PX4's sdlog2 does (``.px4log``): no FMT
record describing FMT itself."""
from __future__ import annotations

import struct

import numpy as np

_STRUCT = {"B": "B", "b": "b", "h": "h", "H": "H", "i": "i", "I": "I", "f": "f", "Q": "Q", "q": "q",
           "n": "4s", "N": "16s", "Z": "64s", "L": "i", "c": "h", "e": "i", "M": "B"}


class DataFlashWriter:
    """``w = DataFlashWriter(); w.fmt("ATT", "QfffFields", "TimeUS,Roll,..."); w.add("ATT", ...)``."""

    def __init__(self, sdlog2: bool = False):
        self.sdlog2 = sdlog2
        self.buf = bytearray()
        self.types = {}
        self._fmt_struct = struct.Struct("<BB4s16s64s")
        self.next_id = 129

    def fmt(self, name: str, fmt: str, columns: str) -> None:
        st = struct.Struct("<" + "".join(_STRUCT[c] for c in fmt))
        tid = self.next_id
        self.next_id += 1
        self.types[name] = (tid, st)
        body = self._fmt_struct.pack(tid, st.size + 3, name.encode(), fmt.encode(), columns.encode())
        self.buf += b"\xa3\x95\x80" + body

    def add(self, name: str, *values) -> None:
        tid, st = self.types[name]
        vals = [v.encode() if isinstance(v, str) else v for v in values]
        self.buf += bytes([0xA3, 0x95, tid]) + st.pack(*vals)

    def bytes(self) -> bytes:
        if self.sdlog2:         # "don't write format of format message, it's useless" (sdlog2)
            return bytes(self.buf)
        # FMT for FMT itself first, as ArduPilot writes it
        head = b"\xa3\x95\x80" + self._fmt_struct.pack(128, 89, b"FMT", b"BBnNZ",
                                                        b"Type,Length,Name,Format,Columns")
        return head + bytes(self.buf)


def sdlog2_log(n: int = 100, q_frd_ned=None, pflg: int = 15) -> DataFlashWriter:
    """A PX4 sdlog2 log of ``n`` cycles of 0.1 s (TIME.StartTime from 5 s of boot) holding
    planted NED/FRD values: attitude roll 0.1 rad, nose up 0.2 rad, heading north (quaternion
    ``q_frd_ned`` or, by default, all 0 as early sdlog2 writes it), rates 0.01/0.02/0.03 rad/s,
    specific force (0.1, 0.2, -9.8), LPOS north 0.1 m per cycle at 2 m up, velocity (1, 0.5,
    -0.25) NED with ``pflg`` on every tenth sample (else 15, all valid), PWM outputs 1500, 1000,
    2000, 1250 µs (the others 0: not driven), thrust 0.45, 22.2 V; STAT armed from 1 to 9 s,
    in flight from 2 to 8 s, MANUAL then AUTO_MISSION at 5 s; VER and MAV_TYPE 14 (octorotor)."""
    w = DataFlashWriter(sdlog2=True)
    w.fmt("ATT", "fffffffffffff", "qw,qx,qy,qz,Roll,Pitch,Yaw,RollRate,PitchRate,YawRate,GX,GY,GZ")
    w.fmt("IMU", "ffffff", "AccX,AccY,AccZ,GyroX,GyroY,GyroZ")
    w.fmt("LPOS", "ffffffffB", "X,Y,Z,Dist,VX,VY,VZ,EPH,PFlg")
    w.fmt("OUT0", "ffffffff", "Out0,Out1,Out2,Out3,Out4,Out5,Out6,Out7")
    w.fmt("ATTC", "ffff", "Roll,Pitch,Yaw,Thrust")
    w.fmt("BATT", "ffff", "V,VFilt,C,Discharged")
    w.fmt("STAT", "BBBfBBf", "MainState,ArmS,Failsafe,BatRem,BatWarn,Landed,Load")
    w.fmt("TIME", "Q", "StartTime")
    w.fmt("VER", "NZ", "Arch,FwGit")
    w.fmt("PARM", "Nf", "Name,Value")
    w.add("VER", "PX4FMU_V2", "44d2c4a1e5c0a044a1cbf69bc1199454f9c0238c")
    w.add("PARM", "MAV_TYPE", 14.0)
    q = np.zeros(4) if q_frd_ned is None else np.asarray(q_frd_ned, float)
    for i in range(n):
        w.add("TIME", 5_000_000 + i * 100_000)
        w.add("ATT", *q, 0.1, 0.2, 0.0, 0.01, 0.02, 0.03, 0, 0, 0)
        w.add("IMU", 0.1, 0.2, -9.8, 0.01, 0.02, 0.03)
        w.add("LPOS", 0.1 * i, 0.0, -2.0, 2.0, 1.0, 0.5, -0.25, 1.0, pflg if i % 10 == 5 else 15)
        w.add("OUT0", 1500, 1000, 2000, 1250, 0, 0, 0, 0)
        w.add("ATTC", 0, 0, 0, 0.45)
        w.add("BATT", 22.2, 22.2, 10.0, 0.0)
        if i % 5 == 0:
            w.add("STAT", 0 if i < 50 else 3, 2 if 10 <= i < 90 else 1, 0, 0.5, 0,
                  0 if 20 <= i < 80 else 1, 0.3)
    return w
