"""inspect's fitness block is identify's verdict (issue 29, item 2): the rotor input identify
would use (not a 4 Hz rpm when 50 Hz motor commands exist), gap-aware rates with bursts named,
a warning every prior shares printed once, and the basis of the airborne time."""
from __future__ import annotations

import json

import numpy as np

from droneid.cli import main
from droneid.commands.inspect import render_fitness
from droneid.dataset.suitability import fitness_by_prior
from droneid.logs.flight import Flight, Provenance, Signal


def _quad(rpm_rate=4.0, motor_rate=50.0, duration=30.0, declared=True) -> Flight:
    """A hovering-and-moving quad that tilts as it accelerates, rpm and motor commands at the
    given rates."""
    t = np.arange(0, duration, 0.01)
    vx = 2.0 * np.sin(0.5 * t) * (t > 8)
    ax = np.gradient(vx, t)
    sig = [Signal("vx", t, vx, "m/s"), Signal("vy", t, 0 * t, "m/s"), Signal("vz", t, 0 * t, "m/s"),
           Signal("roll", t, 0 * t, "rad"), Signal("pitch", t, np.arctan(ax / 9.81), "rad"),
           Signal("yaw", t, 0.5 * np.sin(0.2 * t), "rad"), Signal("z", t, 2 + 0 * t, "m")]
    tr, tm = np.arange(0, duration, 1 / rpm_rate), np.arange(0, duration, 1 / motor_rate)
    for i in range(1, 5):
        sig += [Signal(f"rpm{i}", tr, 15000 + 0 * tr, "rpm"), Signal(f"motor{i}", tm, 0.5 + 0 * tm, "1")]
    prov = Provenance(files=("quad.ulg",), format="ulog", vehicle_type="multirotor" if declared else "unknown",
                      vehicle_declared="test" if declared else None)
    return Flight({s.name: s for s in sig}, prov, segments={"armed": ((0.0, duration),),
                                                            "in_flight": ((0.0, duration),)})


def test_rotor_input_is_the_one_identify_would_use():
    fit = fitness_by_prior([_quad()], 0.05)
    rt = fit["rotor-thrust"]
    assert rt["ok"], rt["problems"]
    assert "motor1" in rt["flights"][0]["rates_hz"] and "rpm1" not in rt["flights"][0]["rates_hz"]
    assert fit["auto"]["prior"] == "rotor-thrust" and "motor commands" in fit["auto"]["reason"]
    text = "\n".join(render_fitness(fit))
    assert "rotor-thrust: ok" in text and "--prior auto chooses: rotor-thrust" in text


def test_a_warning_every_prior_shares_is_printed_once():
    text = "\n".join(render_fitness(fitness_by_prior([_quad(declared=False)], 0.05)))
    assert text.count("vehicle type not declared") == 1, text
    assert "flies like: multirotor" in text


def test_inspect_json_rates_are_gap_aware_and_bursts_named(tmp_path, capsys):
    t = np.concatenate([np.arange(0, 5, 0.01), np.arange(60, 65, 0.01)])     # 2 bursts of 5 s
    p = tmp_path / "b.csv"
    p.write_text("t,x,y,z\n" + "".join(f"{a:.2f},{np.sin(a):.5f},0,1\n" for a in t))
    assert main(["inspect", str(p), "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    x = next(s for s in d["signals"] if s["name"] == "x")
    assert abs(x["rate_hz"] - 100.0) < 1.0 and x["bursts"].startswith("2 bursts: 0.0-5.0 s, 60.0-65.0 s")
    fl = d["fitness"]["tilt-drag"]["flights"][0]
    assert fl["airborne_s"] < 10.5                        # the data, not the 65 s span
    assert main(["inspect", str(p)]) == 0
    out = capsys.readouterr().out
    assert "in bursts: x, y, z, vx, vy, vz 2 bursts" in out
    assert "the log has no armed or in-flight state" in out
