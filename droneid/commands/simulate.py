"""``droneid simulate``: simulate a quadrotor flight and write it as logs plus its truth JSON."""
from __future__ import annotations

from droneid.errors import ConfigError
from droneid.core.lazy import lazy_module

_simulate = lazy_module("droneid.simulation.simulator")
_samples = lazy_module("droneid.simulation.sample_logs")


def register(sub):
    DEFAULT_PARAMS, EFFECTS, PATHS = _simulate.DEFAULT_PARAMS, _simulate.EFFECTS, _simulate.PATHS
    p = sub.add_parser(
        "simulate",
        description="Simulate a quadrotor flight (tilt-drag dynamics, PID tracking, mocap-like noise; "
                    "four rotors with thrust k_f rpm^2 logged as rpm1..4 and motor1..4, optional motor "
                    "lag motor_tau_s and rpm logging delay rpm_delay_s) and write it as logs plus "
                    "NAME.truth.json (parameters, effects, true accelerations, rotor constants). "
                    "Effects: " + "; ".join(f"{k} ({', '.join(f'{n}={v:g}' for n, v in d.items())})"
                                             for k, d in EFFECTS.items()) + ".")
    p.add_argument("--path", default="eight", choices=PATHS, help="reference path (default: eight)")
    p.add_argument("--duration", type=float, default=20.0, metavar="S", help="logged seconds (default 20)")
    p.add_argument("--rate", type=float, default=100.0, metavar="HZ", help="log rate (default 100)")
    p.add_argument("--effect", action="append", default=[], metavar="ID[=V1,V2|=NAME:V,...]",
                   help="switch on an undeclared effect, e.g. wind=2,-1.5 or quadratic_drag=0.1 "
                        "or gust=sigma:0.5 (repeatable)")
    p.add_argument("--param", action="append", default=[], metavar="KEY=VALUE",
                   help="simulator parameter, e.g. k_drag=0.3 (one of: " + ", ".join(DEFAULT_PARAMS) + ")")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.add_argument("--no-noise", action="store_true", help="log the true states without measurement noise")
    p.add_argument("--format", default="tlog,mcap,csv", help="comma-separated: tlog, mcap, csv (Motive, pose "
                   "only), flatcsv (every signal) (default tlog,mcap,csv)")
    p.add_argument("-o", "--out", default=".", metavar="DIR", help="output folder (default .)")
    p.add_argument("--name", default=None, help="file stem (default sim_PATH_sSEED)")
    p.set_defaults(func=run)


def parse_effect_args(items) -> dict:
    """``["wind=2,-1.5", "gust=sigma:0.5", "battery_sag"]`` -> simulate(effects=...)."""
    effects = {}
    for item in items:
        eid, _, rest = item.partition("=")
        eid = eid.strip()
        if not rest.strip():
            effects[eid] = None
            continue
        parts = [s.strip() for s in rest.split(",") if s.strip()]
        try:
            if all(":" in s for s in parts):
                effects[eid] = {k.strip(): float(v) for k, v in (s.split(":", 1) for s in parts)}
            elif any(":" in s for s in parts):
                raise ValueError("mixed")
            else:
                effects[eid] = [float(s) for s in parts]
        except ValueError:
            raise ConfigError(f"--effect {item!r}: expected ID=V1,V2 or ID=NAME:V,NAME:V with numbers") from None
    return effects


def parse_params(items) -> dict:
    out = {}
    for item in items:
        k, sep, v = item.partition("=")
        try:
            if not sep:
                raise ValueError
            out[k.strip()] = float(v)
        except ValueError:
            raise ConfigError(f"--param {item!r}: expected KEY=NUMBER") from None
    return out


def run(args) -> int:
    formats = [f.strip() for f in args.format.split(",") if f.strip()]
    res = _simulate.simulate(path=args.path, duration_s=args.duration, rate_hz=args.rate,
                   effects=parse_effect_args(args.effect), seed=args.seed, noise=not args.no_noise,
                   **parse_params(args.param))
    name = args.name or f"sim_{args.path}_s{args.seed}"
    for p in _samples.save(res, args.out, name, formats):
        if not args.quiet:
            print(p)
    return 0
