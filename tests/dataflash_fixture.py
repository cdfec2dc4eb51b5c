"""Write tiny ArduPilot DataFlash logs for planted-truth tests (the record layout pymavlink's
DFReader reads: 0xA3 0x95, type byte, packed little-endian fields; FMT records first)."""
from __future__ import annotations

import struct

_STRUCT = {"B": "B", "b": "b", "h": "h", "H": "H", "i": "i", "I": "I", "f": "f", "Q": "Q", "q": "q",
           "n": "4s", "N": "16s", "Z": "64s", "L": "i", "c": "h", "e": "i", "M": "B"}


class DataFlashWriter:
    """``w = DataFlashWriter(); w.fmt("ATT", "QfffFields", "TimeUS,Roll,..."); w.add("ATT", ...)``."""

    def __init__(self):
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
        # FMT for FMT itself first, as ArduPilot writes it
        head = b"\xa3\x95\x80" + self._fmt_struct.pack(128, 89, b"FMT", b"BBnNZ",
                                                        b"Type,Length,Name,Format,Columns")
        return head + bytes(self.buf)
