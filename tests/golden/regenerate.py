"""Regenerate the golden parser summaries of the real logs (run after an INTENDED reader change,
then review the diff):

    .venv/bin/python tests/golden/regenerate.py

One small JSON per real log: format, vehicle, firmware, duration, each signal's unit, count,
span and source, segments and diagnostics. tests/real_logs/test_parsers_golden.py compares against them.
"""
from __future__ import annotations

import hashlib
import json
import os
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
REAL = Path(os.environ.get("DRONEID_REAL_LOGS") or ROOT.parent / "shared" / "real_logs")
#: real log -> read_flight keyword arguments
LOGS = {
    "ardupilot/copter33_quad_log171.bin": {},
    "ardupilot/copter462_quad_first80k.bin": {},
    "mavlink/copter357_quad_mission1.tlog": {},
    "mavlink/copter34_quad_bench_battery.tlog": {},
    "px4/vtol_short_hop.ulg": {},
    "px4/quad_fmuv5_ground.ulg": {},
    "px4/x500_sitl_events.ulg": {},
    "px4/octo_px4tools_01_07_59.px4log": {},
    "mcap/sportcub_fixedwing_qualisys.mcap": {},
    "mocap/optitrack_motive/motive_1.23_three_rigid_bodies.csv": {"body": "device02"},
    "mocap/crazyflie_nanodrone/square_run1.csv": {},
}


def golden_name(rel: str) -> str:
    """The summary's file name: the log's folder and a hash of its path. The log's own name is
    kept out of it, so nothing in this repo looks like a copy of a real log (only these small
    summaries of what the readers make of them are committed; the logs stay in ../shared)."""
    digest = hashlib.sha1(rel.encode("utf-8")).hexdigest()[:12]
    return f"{rel.split('/')[0]}__{digest}.summary.json"


def pinned(flight) -> dict:
    """The part of Flight.summary() a golden pins (no absolute paths)."""
    s = flight.summary()
    return {
        "format": s["format"], "vehicle": s["vehicle"], "firmware": s["firmware"],
        "vehicle_type": s["vehicle_type"], "vehicle_declared": s["vehicle_declared"],
        "duration_s": s["duration_s"],
        "signals": {g["name"]: [g["unit"], g["count"], g["start_s"], g["end_s"], g["source"]]
                    for g in s["signals"]},
        "segments": s["segments"],
        "n_events": len(s["events"]),
        "skipped": s["diagnostics"]["skipped"],
    }


def main() -> int:
    sys.path.insert(0, str(ROOT))
    from parsers import read_flight
    if not REAL.is_dir():
        print(f"regenerate: {REAL} is absent; nothing to do")
        return 0
    for rel, kw in LOGS.items():
        p = REAL / rel
        if not p.is_file():
            print(f"skip {rel} (absent)")
            continue
        out = HERE / golden_name(rel)
        out.write_text(json.dumps(pinned(read_flight(p, **kw)), indent=1, sort_keys=True) + "\n")
        print(f"wrote {out.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
