"""A quadrotor flight simulator whose ground truth is known: the test bench of droneid.

Model (world ENU, body FLU, Z-Y-X Euler angles as in :mod:`droneid.core.frames`)::

    m p'' = T R e3 - m g e3 + m D(v - w)        thrust T along body +z
    D(u)  = -k_D u                              nominal linear drag (k_D = 0.28 1/s, the paper's)

Attitude ``(roll, pitch, yaw)`` follows the controller's set-point through a first-order lag of
``att_tau_s`` (0.1 s). The controller is a position PID with drag feed-forward giving a desired
acceleration; the desired thrust vector gives the roll/pitch set-point (Z-Y-X, at the current
yaw) and the collective thrust ``T = m f_z / (cos roll cos pitch)`` (altitude priority), sent
as a throttle ``T / T_max``. The state is integrated with RK4 at ``sim_rate_hz`` (>= 200 Hz) and
logged at ``rate_hz``.

Rotors (:class:`_Rotors`): four in an X layout (ArduPilot QUAD/X order), rotor ``i`` pushing
``T_i = k_f ω_i²`` along body +z (ω in rpm; ``k_f`` = 5.45e-9 N/rpm² puts the 0.5 kg vehicle's
hover at 15 000 rpm). The collective ``T`` above and the torque ``J ẇ + w × J w`` of the flown
attitude are split over the rotors (torque part scaled down where a command would leave 0..1);
command ``u_i`` in 0..1 gives ``T_i = (t_max_n/4) f_e(u_i s)``, the thrust curve
``f_e(u) = (1 − e) u + e u²`` of ``thrust_expo`` e (ArduPilot's MOT_THST_EXPO; default 1: u²), with
``s = 1`` at the nominal voltage (``battery_sag``: ``s = (V/v_start)^(exponent/2)``, V/v_start
for the default exponent 2, ArduPilot's voltage scaling u·V/V_ref). Each speed lags
its command by ``motor_tau_s`` (default 0; with a lag the flight is integrated again with the
speeds in the state). Either way the acceleration is ``Σ T_i R e3 / m − g e3 + D``, so the
rotor-thrust prior ``v̇ = k_T Σ(ω_i/10⁴)² R e3 − g e3 − k_D v`` is exact on the true speeds with
``k_T = k_f·10⁸/m`` (1.09 m/s² per (10⁴ rpm)² by default; ``truth["rotors"]``). The
``weak_motor`` effect gives one rotor ``gain·k_f`` (a damaged propeller): its command and speed
rise so it still delivers its allocated thrust, and the prior holds with that rotor's term
scaled by ``gain`` (``truth["rotors"]["thrust_gain"]``). Logged:
``motor1..4`` (the commands) and ``rpm1..4``, the speeds ``rpm_delay_s`` before they act (a
logging delay, default 0) plus ``rpm_noise`` (30 rpm) white noise.

Nominal flights are at constant altitude, so vertical force balance holds and the paper's
tilt-drag model ``v'x = g cosψ tanθ/cosφ + g sinψ tanφ − k_D vx`` (and v'y) holds up to its
second-order geometric error with Z-Y-X angles; ``truth["model"]`` records that error.

Effects the tilt-drag model does not declare are switched on with ``effects={id: params}``;
``params`` is ``None``/``True`` (defaults), a number or sequence (positional, in the order of
:data:`EFFECTS`) or a dict by name. See :data:`EFFECTS` for ids, parameters and defaults.

Measurement model (``noise=True``): a mocap at the internal rate with ``pos_noise_m`` (1 mm) white
position noise; velocity is the least-squares slope of the noisy positions over ``vel_window_s``
(0.1 s, centred); logged Euler angles get ``att_noise_rad`` (0.2 deg) white noise (the quaternion
is built from the logged angles); IMU rates/specific force get ``gyro_noise`` / ``acc_noise``.
All randomness comes from ``numpy.random.default_rng(SeedSequence(seed))`` children.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from types import MappingProxyType

import numpy as np

from priors.thrust import RPM_SCALE, inverse_thrust_curve, thrust_curve

from droneid.errors import ConfigError, check_choice, did_you_mean
from droneid.logs.flight import Flight, Provenance, Signal, canonical_unit
from droneid.simulation.rk4 import rk4_step
from droneid.core.frames import body_rates_from_euler as _body_rates, euler_to_matrix, euler_to_quat, wrap_angle

__all__ = ["simulate", "SimResult", "EFFECTS", "PATHS", "DEFAULT_PARAMS", "tilt_drag_model",
           "parse_effects"]

G = 9.81

PATHS = ("eight", "square", "circle", "lissajous", "random", "hover")

#: effect id -> ordered {param: default}. Positional values fill params in this order.
EFFECTS = MappingProxyType({
    # quadratic (parasitic) drag -c |v_air| v_air, c in 1/m
    "quadratic_drag": {"c": 0.1},
    # constant wind: world air velocity (m/s); drag acts on v - w
    "wind": {"wx": 2.0, "wy": 0.0},
    # wind with an Ornstein-Uhlenbeck gust process around a mean (m/s, m/s, m/s, s)
    "gust": {"wx": 1.0, "wy": 0.0, "sigma": 0.8, "tau_s": 2.0},
    # thrust gain 1/(1-(R/4z)^2) near ground (Cheeseman-Bennett); flies at altitude_m
    "ground_effect": {"rotor_radius_m": 0.12, "altitude_m": 0.15},
    # battery voltage falls linearly; thrust per throttle scales with (V/v_start)^exponent
    "battery_sag": {"v_start": 12.6, "v_end": 10.8, "exponent": 2.0},
    # constant offsets added to the LOGGED roll and pitch (rad)
    "attitude_bias": {"roll": 0.03, "pitch": -0.02},
    # logged attitude lags the true attitude by tau_s
    "attitude_delay": {"tau_s": 0.1},
    # vertical motion: altitude += amp_m sin(2 pi t / period_s), thrust departs from hover balance
    "thrust_variation": {"amp_m": 0.5, "period_s": 4.0},
    # drag coefficients along body x, body y and body z (1/s), replacing the isotropic k_D
    "anisotropic_drag": {"kx": 0.15, "ky": 0.45, "kz": 0.28},
    # one motor (1..4) gives `gain` of the nominal thrust per rpm² (a damaged propeller): the
    # controller commands it harder, so its logged speed is 1/sqrt(gain) higher for its share
    "weak_motor": {"motor": 2.0, "gain": 0.85},
})

# (effect, param) -> (lower bound, inclusive)
_EFFECT_MIN = {
    ("quadratic_drag", "c"): (0.0, True), ("gust", "sigma"): (0.0, True), ("gust", "tau_s"): (0.0, False),
    ("ground_effect", "rotor_radius_m"): (0.0, False), ("ground_effect", "altitude_m"): (0.0, False),
    ("battery_sag", "v_start"): (0.0, False), ("battery_sag", "v_end"): (0.0, False),
    ("attitude_delay", "tau_s"): (0.0, True), ("thrust_variation", "period_s"): (0.0, False),
    ("anisotropic_drag", "kx"): (0.0, True), ("anisotropic_drag", "ky"): (0.0, True),
    ("anisotropic_drag", "kz"): (0.0, True), ("weak_motor", "gain"): (0.0, False),
    ("weak_motor", "motor"): (1.0, True),
}

#: keyword parameters of :func:`simulate` (besides path, duration_s, rate_hz, effects, seed, noise)
DEFAULT_PARAMS = MappingProxyType({
    "mass_kg": 0.5,            # Parrot Bebop 2 class
    "k_drag": 0.28,            # linear drag k_D (1/s), the paper's value
    "g": G,
    "t_max_n": 2.0 * 0.5 * G,  # thrust at full throttle (hover throttle 0.5)
    "altitude_m": 1.5,
    "size_m": None,            # path half-extent; per-path default
    "period_s": None,          # path period / time per side; per-path default
    "yaw_amp_rad": 0.8,        # yaw sweeps yaw0 + amp sin(2 pi t / yaw_period_s)
    "yaw_period_s": 23.0,
    "yaw0_rad": 0.0,
    "att_tau_s": 0.1,          # attitude tracking lag
    "max_tilt_rad": 0.35,
    "kp": 4.0, "kd": 3.6, "ki": 0.4,            # horizontal position PID (1/s^2, 1/s, 1/s^3)
    "kp_z": 9.0, "kd_z": 6.0, "ki_z": 3.0,      # altitude PID
    "sim_rate_hz": 400.0,
    "pos_noise_m": 0.001,
    "att_noise_rad": math.radians(0.2),
    "vel_window_s": 0.1,
    "gyro_noise": 0.005,       # rad/s
    "acc_noise": 0.05,         # m/s^2
    "volt_noise": 0.01,        # V
    "battery_v": 12.0,         # nominal (constant) battery voltage
    "n_waypoints": 12,         # random path
    # rotors (X layout, see _Rotors): T_i = k_f w_i^2 with w in rpm
    "k_f": 5.45e-9,            # N/rpm^2: hover of the 0.5 kg vehicle at 15 000 rpm (0.5*9.81/4/15000^2)
    "arm_m": 0.17,             # motor distance from the centre of mass (m)
    "yaw_moment_m": 0.016,     # rotor drag torque per unit thrust (m)
    "inertia_xx": 0.0022, "inertia_yy": 0.0029, "inertia_zz": 0.0048,   # kg m^2, Bebop 2 class
    "motor_tau_s": 0.0,        # first-order lag of each rotor speed behind its command (s)
    "thrust_expo": 1.0,        # thrust curve of a command: T_i = T_max ((1-e) u + e u^2) (ArduPilot's MOT_THST_EXPO)
    "rpm_delay_s": 0.0,        # logged motor speeds lead the speeds that act by this (s)
    "rpm_noise": 30.0,         # white noise on the logged rpm (rpm std, with noise=True)
})

_PATH_DEFAULTS = {  # size_m, period_s
    "eight": (2.0, 9.0), "circle": (1.5, 8.0), "square": (1.5, 3.2),
    "lissajous": (1.5, 20.0), "random": (2.0, 3.5), "hover": (0.0, 10.0),
}


@dataclass(frozen=True)
class SimResult:
    """A simulated flight and its ground truth (JSON-able dict, see :func:`simulate`)."""
    flight: Flight
    truth: dict


def tilt_drag_model(vx, vy, roll, pitch, yaw, k_drag=0.28, g=G):
    """The paper's tilt-drag model (v̇x, v̇y) in droneid's angles (see CONTEXT / frames)."""
    cr, cy, sy = np.cos(roll), np.cos(yaw), np.sin(yaw)
    tp, tr = np.tan(pitch), np.tan(roll)
    ax = g * cy * tp / cr + g * sy * tr - k_drag * np.asarray(vx)
    ay = g * sy * tp / cr - g * cy * tr - k_drag * np.asarray(vy)
    return ax, ay


def _exact_hover_model(vx, vy, roll, pitch, yaw, k_drag=0.28, g=G):
    """Thrust geometry of Z-Y-X angles with vertical balance T cos(roll) cos(pitch) = m g."""
    R = euler_to_matrix(roll, pitch, yaw)
    b3z = R[..., 2, 2]
    return (g * R[..., 0, 2] / b3z - k_drag * np.asarray(vx),
            g * R[..., 1, 2] / b3z - k_drag * np.asarray(vy))


def parse_effects(effects) -> dict:
    """Normalise ``effects`` to ``{id: {param: float}}`` with defaults filled in."""
    if effects is None:
        return {}
    if isinstance(effects, (list, tuple)):
        effects = {e: None for e in effects}
    if not isinstance(effects, dict):
        raise ConfigError(f"The 'effects' parameter of simulate must be a dict id -> params. "
                          f"Got {type(effects).__name__} instead.")
    out = {}
    for eid, val in effects.items():
        if eid not in EFFECTS:
            raise ConfigError(f"unknown effect '{eid}'{did_you_mean(eid, EFFECTS)}; "
                              f"effects: {', '.join(EFFECTS)}")
        spec = dict(EFFECTS[eid])
        names = list(spec)
        if val is None or val is True:
            pass
        elif isinstance(val, dict):
            for k, v in val.items():
                if k not in spec:
                    raise ConfigError(f"effect '{eid}' has no parameter '{k}'"
                                      f"{did_you_mean(k, names)}; parameters: {', '.join(names)}")
                spec[k] = float(v)
        else:
            vals = list(val) if isinstance(val, (list, tuple, np.ndarray)) else [val]
            if len(vals) > len(names):
                raise ConfigError(f"effect '{eid}' takes at most {len(names)} values "
                                  f"({', '.join(names)}); got {len(vals)}")
            for k, v in zip(names, vals):
                spec[k] = float(v)
        for k, v in spec.items():
            if not math.isfinite(v):
                raise ConfigError(f"effect '{eid}' parameter '{k}' must be finite, got {v}")
            if (eid, k) == ("weak_motor", "motor") and v not in (1.0, 2.0, 3.0, 4.0):
                raise ConfigError(f"effect 'weak_motor' parameter 'motor' must be 1, 2, 3 or 4, got {v}")
            lo = _EFFECT_MIN.get((eid, k))
            if lo is not None and not (v > lo[0] or (lo[1] and v == lo[0])):
                raise ConfigError(f"effect '{eid}' parameter '{k}' must be {'>=' if lo[1] else '>'} "
                                  f"{lo[0]}, got {v}")
        out[eid] = spec
    return out


# ---------------------------------------------------------------------------------------
# reference paths: vectorised p, v, a (each (n, 3)) at times t
# ---------------------------------------------------------------------------------------
def _min_jerk_path(waypoints, seg_times, t):
    """Rest-to-rest minimum-jerk segments through waypoints; holds the ends."""
    wp = np.asarray(waypoints, float)
    knots = np.concatenate([[0.0], np.cumsum(seg_times)])
    t = np.asarray(t, float)
    idx = np.clip(np.searchsorted(knots, t, side="right") - 1, 0, len(seg_times) - 1)
    T = np.asarray(seg_times)[idx]
    tau = np.clip((t - knots[idx]) / T, 0.0, 1.0)
    s = 10 * tau**3 - 15 * tau**4 + 6 * tau**5
    ds = (30 * tau**2 - 60 * tau**3 + 30 * tau**4) / T
    dds = (60 * tau - 180 * tau**2 + 120 * tau**3) / T**2
    inside = ((t >= 0) & (t <= knots[-1]))[:, None]
    d = wp[idx + 1] - wp[idx]
    p = wp[idx] + d * s[:, None]
    v = np.where(inside, d * ds[:, None], 0.0)
    a = np.where(inside, d * dds[:, None], 0.0)
    return p, v, a


def _reference(path, t, P, rng, total_s):
    t = np.asarray(t, float)
    n = t.size
    size, period = P["size_m"], P["period_s"]
    p = np.zeros((n, 3))
    v = np.zeros((n, 3))
    a = np.zeros((n, 3))
    if path == "eight":  # lemniscate of Gerono: x = A sin(wt), y = (A/2) sin(2wt)
        w = 2 * math.pi / period
        A, B = size, size / 2
        p[:, 0], v[:, 0], a[:, 0] = A * np.sin(w * t), A * w * np.cos(w * t), -A * w * w * np.sin(w * t)
        p[:, 1], v[:, 1], a[:, 1] = (B * np.sin(2 * w * t), 2 * B * w * np.cos(2 * w * t),
                                     -4 * B * w * w * np.sin(2 * w * t))
    elif path == "circle":
        w = 2 * math.pi / period
        p[:, 0], p[:, 1] = size * np.cos(w * t), size * np.sin(w * t)
        v[:, 0], v[:, 1] = -size * w * np.sin(w * t), size * w * np.cos(w * t)
        a[:, 0], a[:, 1] = -size * w * w * np.cos(w * t), -size * w * w * np.sin(w * t)
    elif path == "lissajous":  # 3:2 figure
        w = 2 * math.pi / period
        for k, (f, ph) in enumerate(((3.0, math.pi / 2), (2.0, 0.0))):
            p[:, k] = size * np.sin(f * w * t + ph)
            v[:, k] = size * f * w * np.cos(f * w * t + ph)
            a[:, k] = -size * (f * w) ** 2 * np.sin(f * w * t + ph)
    elif path in ("square", "random"):
        n_seg = int(math.ceil(total_s / period)) + 1
        if path == "square":
            corners = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], float) * size
            wp = np.array([corners[i % 4] for i in range(n_seg + 1)])
        else:
            wp = rng.uniform(-size, size, size=(n_seg + 1, 2))
            wp[0] = 0.0
        segs = np.full(n_seg, float(period))
        if path == "random":  # time per segment grows with its length (min-jerk peak speed <= 1 m/s)
            dist = np.linalg.norm(np.diff(wp, axis=0), axis=1)
            segs = np.maximum(period, 1.875 * dist / 1.0)
        pp, vv, aa = _min_jerk_path(wp, segs, t)
        p[:, :2], v[:, :2], a[:, :2] = pp, vv, aa
    elif path == "hover":
        pass
    else:  # pragma: no cover - checked in simulate
        raise ConfigError(f"unknown path {path!r}")
    p[:, 2] = P["altitude_m"]
    return p, v, a


# ---------------------------------------------------------------------------------------
# rotors
# ---------------------------------------------------------------------------------------
class _Rotors:
    """Four rotors in an X layout, ArduPilot QUAD/X order: motor 1 front-right and motor 2
    back-left spin counter-clockwise seen from above, motor 3 front-left and motor 4 back-right
    clockwise; each at ``arm_m`` from the centre of mass on the body diagonals (FLU).

    Rotor ``i`` pushes ``T_i = k_f ω_i²`` (N, ω in rpm) along body +z. Its command ``u_i`` in 0..1
    sets the speed ``ω_i = ω_max u_i sqrt(gain)`` (``ω_max = sqrt(T_max / k_f)``,
    ``T_max = t_max_n / 4``, ``gain`` the battery gain of ``battery_sag``, 1 otherwise), so at the
    nominal voltage ``T_i = T_max u_i²``. The collective thrust ``T`` and the body torque
    ``τ = J ẇ + w × J w`` are allocated by the (pseudo-)inverse of
    ``[Σ T_i, Σ y_i T_i, −Σ x_i T_i, Σ c_i T_i] = [T, τx, τy, τz]`` (``c_i = −yaw_moment_m`` for
    counter-clockwise rotors, ``+yaw_moment_m`` for clockwise ones); where a command would
    leave 0..1 the torque part is scaled down, never the collective.
    """

    def __init__(self, P, thrust_gain=(1.0, 1.0, 1.0, 1.0)):
        #: thrust per rpm² of each rotor relative to k_f (weak_motor); its command is raised so
        #: that it still gives its share of the allocated thrust (the attitude loop sees to that)
        self.gain = np.asarray(thrust_gain, float)
        self._cmd_scale = [1.0 / math.sqrt(g) for g in self.gain.tolist()]
        a = P["arm_m"] / math.sqrt(2.0)
        x = np.array([a, -a, a, -a])
        y = np.array([-a, a, a, -a])
        ccw = np.array([1.0, 1.0, -1.0, -1.0])
        A = np.vstack([np.ones(4), y, -x, -P["yaw_moment_m"] * ccw])
        self.torque_mix = np.linalg.pinv(A)[:, 1:]     # (4, 3): rotor thrust (N) per torque (N m)
        self.k_f = P["k_f"]
        self.expo = P.get("thrust_expo", 1.0)
        self.t_max = P["t_max_n"] / 4.0
        self.w_max = math.sqrt(self.t_max / self.k_f)
        self.inertia = np.array([P["inertia_xx"], P["inertia_yy"], P["inertia_zz"]])

    def torque_thrusts(self, w, wdot):
        """Per-rotor thrust differences (n, 4) in N (summing to zero) giving the torque that makes
        the body rates ``w`` (n, 3, rad/s, FLU) change at ``wdot`` (rad/s²)."""
        jw = w * self.inertia
        tau = wdot * self.inertia + np.cross(w, jw)
        return tau @ self.torque_mix.T

    def command(self, collective, dT):
        """The 4 motor commands in 0..1 for the collective thrust (N) and the per-rotor thrust
        differences ``dT`` (4 N, scaled down where a command would leave 0..1). Scalar: the
        integrator calls it at every stage."""
        base = collective / 4.0
        scale = 1.0
        for d in dT:
            if d > 0:
                scale = min(scale, (self.t_max - base) / d)
            elif d < 0:
                scale = min(scale, base / -d)
        scale = max(scale, 0.0)
        if self.expo != 1.0:     # the thrust curve's inverse (ArduPilot's thrust linearisation)
            return [min(k * float(inverse_thrust_curve(min(max((base + scale * d) / self.t_max, 0.0), 1.0),
                                                       self.expo)), 1.0)
                    for k, d in zip(self._cmd_scale, dT)]
        return [min(k * math.sqrt(min(max((base + scale * d) / self.t_max, 0.0), 1.0)), 1.0)
                for k, d in zip(self._cmd_scale, dT)]

    def commands(self, collective, dT):
        """:meth:`command` on arrays: collective (n,) N, dT (n, 4) N -> u (n, 4)."""
        return np.array([self.command(c, d) for c, d in zip(np.asarray(collective, float).tolist(),
                                                            np.asarray(dT, float).tolist())]).reshape(-1, 4)

    def speeds(self, u, gain):
        """Rotor speeds (rpm) the commands ``u`` (n, 4) settle to at battery gain ``gain`` (n,)."""
        if self.expo != 1.0:
            return self.w_max * np.sqrt(thrust_curve(u * np.sqrt(np.asarray(gain, float))[:, None], self.expo))
        return self.w_max * u * np.sqrt(np.asarray(gain, float))[:, None]

    def speed(self, u: float, gain: float) -> float:
        """:meth:`speeds` of one command (scalar, for the integrator)."""
        if self.expo != 1.0:
            return self.w_max * math.sqrt(thrust_curve(u * math.sqrt(gain), self.expo))
        return self.w_max * math.sqrt(gain) * u


# ---------------------------------------------------------------------------------------
# dynamics (scalar, math module: called ~4 x sim_rate_hz x duration times)
# ---------------------------------------------------------------------------------------
class _Dyn:
    def __init__(self, P, eff):
        self.P = P
        self.m = P["mass_kg"]
        self.g = P["g"]
        self.kd = P["k_drag"]
        self.tau = P["att_tau_s"]
        self.tmax = P["t_max_n"]
        self.max_tilt = P["max_tilt_rad"]
        self.c_quad = eff.get("quadratic_drag", {}).get("c", 0.0)
        an = eff.get("anisotropic_drag")
        self.aniso = (an["kx"], an["ky"], an["kz"]) if an else None
        ge = eff.get("ground_effect")
        self.ge_r = ge["rotor_radius_m"] if ge else 0.0
        wm = eff.get("weak_motor")
        gains = [1.0, 1.0, 1.0, 1.0]
        if wm:
            gains[int(wm["motor"]) - 1] = wm["gain"]
        self.rotors = _Rotors(P, gains)
        self.motor_tau = P["motor_tau_s"]

    def command(self, s, ref):
        """The controller (it knows the nominal drag only, no wind): roll and pitch set-points
        and the vertical thrust per unit mass ``fz``."""
        (px, py, pz, vx, vy, vz, r, p, y, ix, iy, iz) = s[:12]
        (rpx, rpy, rpz, rvx, rvy, rvz, rax, ray, raz, _, _) = ref
        P, g, kd = self.P, self.g, self.kd
        fx = rax + P["kp"] * (rpx - px) + P["kd"] * (rvx - vx) + P["ki"] * ix + kd * vx
        fy = ray + P["kp"] * (rpy - py) + P["kd"] * (rvy - vy) + P["ki"] * iy + kd * vy
        fz = raz + P["kp_z"] * (rpz - pz) + P["kd_z"] * (rvz - vz) + P["ki_z"] * iz + kd * vz + g
        fz = max(fz, 0.2 * g)
        cy, sy = math.cos(y), math.sin(y)
        fxb = cy * fx + sy * fy          # desired thrust vector in the yaw frame
        fyb = -sy * fx + cy * fy
        fn = math.sqrt(fxb * fxb + fyb * fyb + fz * fz)
        mt = self.max_tilt
        r_d = max(-mt, min(mt, math.asin(max(-1.0, min(1.0, -fyb / fn)))))
        p_d = max(-mt, min(mt, math.atan2(fxb, fz)))
        return r_d, p_d, fz

    def rhs(self, s, ref, wind, gain_batt, dT=None):
        """Derivative of the state and auxiliaries (world accel, thrust, throttle, ...).

        Without ``dT`` the thrust is the commanded collective at once (rotor speeds follow it
        without lag). With ``dT`` (the 4 rotor-thrust differences of the torque demand, N) the
        state carries the 4 rotor speeds (rpm), each lagging its command by ``motor_tau_s``,
        and the thrust is Σ k_f ω_i²."""
        (px, py, pz, vx, vy, vz, r, p, y, ix, iy, iz) = s[:12]
        (rpx, rpy, rpz, rvx, rvy, rvz, rax, ray, raz, ryaw, ryawd) = ref
        g, kd = self.g, self.kd
        ex, ey, ez = rpx - px, rpy - py, rpz - pz
        r_d, p_d, fz = self.command(s, ref)
        cy, sy = math.cos(y), math.sin(y)
        cr, sr, cp, sp = math.cos(r), math.sin(r), math.cos(p), math.sin(p)
        t_cmd = self.m * fz / (cr * cp)
        throttle = max(0.0, min(1.0, t_cmd / self.tmax))
        gain = gain_batt
        ge = 1.0
        if self.ge_r:
            q = self.ge_r / (4.0 * max(pz, self.ge_r / 2.0))
            ge = 1.0 / (1.0 - q * q)
            gain *= ge
        if dT is None and self.rotors.expo != 1.0:   # the collective through the thrust curve
            e = self.rotors.expo
            thrust = self.tmax * thrust_curve(float(inverse_thrust_curve(throttle, e)) * math.sqrt(gain_batt), e) * ge
        elif dT is None:
            thrust = throttle * self.tmax * gain
        else:
            rot = self.rotors
            w = s[12:16]
            if rot.expo != 1.0:
                dw = [(rot.speed(c, gain_batt) - v) / self.motor_tau
                      for c, v in zip(rot.command(throttle * self.tmax, dT), w)]
            else:
                k = rot.w_max * math.sqrt(gain_batt)        # settled speed per unit command (rpm)
                dw = [(k * c - v) / self.motor_tau for c, v in zip(rot.command(throttle * self.tmax, dT), w)]
            thrust = ge * rot.k_f * sum(gi * v * v for gi, v in zip(rot.gain.tolist(), w))
        # --- attitude lag ---
        dr = (r_d - r) / self.tau
        dp = (p_d - p) / self.tau
        ey_ = (ryaw - y + math.pi) % (2 * math.pi) - math.pi
        dy = ryawd + ey_ / self.tau
        # --- translational dynamics ---
        b3x = cy * sp * cr + sy * sr
        b3y = sy * sp * cr - cy * sr
        b3z = cp * cr
        ux, uy, uz = vx - wind[0], vy - wind[1], vz
        if self.aniso is None:
            dx_, dy_, dz_ = -kd * ux, -kd * uy, -kd * uz
        else:
            R = ((cy * cp, cy * sp * sr - sy * cr, b3x),
                 (sy * cp, sy * sp * sr + cy * cr, b3y),
                 (-sp, cp * sr, b3z))
            ub = [R[0][i] * ux + R[1][i] * uy + R[2][i] * uz for i in range(3)]
            db = [-k * u for k, u in zip(self.aniso, ub)]
            dx_, dy_, dz_ = (sum(R[j][i] * db[i] for i in range(3)) for j in range(3))
        if self.c_quad:
            un = math.sqrt(ux * ux + uy * uy + uz * uz)
            dx_ -= self.c_quad * un * ux
            dy_ -= self.c_quad * un * uy
            dz_ -= self.c_quad * un * uz
        tm = thrust / self.m
        ax = tm * b3x + dx_
        ay = tm * b3y + dy_
        az = tm * b3z - g + dz_
        # integrator with anti-windup
        lim = 2.0
        dix = ex if abs(ix) < lim or ex * ix < 0 else 0.0
        diy = ey if abs(iy) < lim or ey * iy < 0 else 0.0
        diz = ez if abs(iz) < lim or ez * iz < 0 else 0.0
        deriv = (vx, vy, vz, ax, ay, az, dr, dp, dy, dix, diy, diz)
        if dT is not None:
            deriv = deriv + tuple(dw)
        aux = (ax, ay, az, thrust, throttle, dx_, dy_, dz_)
        return deriv, aux


def _rk4(dyn, state0, refs, winds, gains, n_steps, dt, dTs=None):
    """Integrate; refs/winds/gains (and the rotor-thrust differences ``dTs`` of the lagged-rotor
    model) are given on the half-step grid (2 n_steps + 1 points)."""
    if dTs is None:
        dTs = [None] * len(refs)
    nstate = len(state0)
    states = np.empty((n_steps + 1, nstate))
    auxs = np.empty((n_steps + 1, 8))
    derivs = np.empty((n_steps + 1, nstate))
    s = list(state0)
    for i in range(n_steps + 1):
        j = 2 * i
        k1, aux = dyn.rhs(s, refs[j], winds[j], gains[j], dTs[j])
        states[i] = s
        auxs[i] = aux
        derivs[i] = k1
        if i == n_steps:
            break
        s = rk4_step(lambda y, at, j=j: dyn.rhs(y, refs[j + at], winds[j + at], gains[j + at], dTs[j + at])[0],
                     s, dt, stage=_list_axpy, update=_list_combine, k1=k1)
    return states, derivs, auxs


def _list_axpy(x: list, h: float, k: list) -> list:
    return [a + h * b for a, b in zip(x, k)]


def _list_combine(x: list, h: float, k1: list, k2: list, k3: list, k4: list) -> list:
    return [a + h * (b1 + 2 * b2 + 2 * b3 + b4) for a, b1, b2, b3, b4 in zip(x, k1, k2, k3, k4)]


def _check_params(params, path):
    unknown = [k for k in params if k not in DEFAULT_PARAMS]
    if unknown:
        k = unknown[0]
        raise ConfigError(f"simulate() got an unknown parameter '{k}'"
                          f"{did_you_mean(k, DEFAULT_PARAMS)}; parameters: {', '.join(DEFAULT_PARAMS)}")
    P = dict(DEFAULT_PARAMS)
    P.update(params)
    size, period = _PATH_DEFAULTS[path]
    if P["size_m"] is None:
        P["size_m"] = size
    if P["period_s"] is None:
        P["period_s"] = period
    for k, v in P.items():
        if not isinstance(v, (int, float)) or isinstance(v, bool) or not math.isfinite(v):
            raise ConfigError(f"The '{k}' parameter of simulate must be a finite number. Got {v!r} instead.")
        P[k] = float(v)
    for k in ("mass_kg", "t_max_n", "att_tau_s", "sim_rate_hz", "period_s", "max_tilt_rad", "vel_window_s",
              "k_f", "arm_m", "inertia_xx", "inertia_yy", "inertia_zz"):
        if P[k] <= 0:
            raise ConfigError(f"The '{k}' parameter of simulate must be > 0. Got {P[k]} instead.")
    for k in ("yaw_moment_m", "motor_tau_s", "rpm_delay_s", "rpm_noise"):
        if P[k] < 0:
            raise ConfigError(f"The '{k}' parameter of simulate must be >= 0. Got {P[k]} instead.")
    if not 0.0 <= P["thrust_expo"] <= 1.0:
        raise ConfigError(f"The 'thrust_expo' parameter of simulate must be in [0, 1]. Got {P['thrust_expo']} instead.")
    if P["sim_rate_hz"] < 200:
        raise ConfigError(f"The 'sim_rate_hz' parameter of simulate must be >= 200. Got {P['sim_rate_hz']} instead.")
    return P


def _ou(rng, n, dt, sigma, tau):
    """Ornstein-Uhlenbeck samples (stationary start) on a uniform grid."""
    a = math.exp(-dt / tau)
    b = sigma * math.sqrt(1.0 - a * a)
    e = rng.standard_normal(n)
    x = np.empty(n)
    x[0] = sigma * e[0]
    for i in range(1, n):
        x[i] = a * x[i - 1] + b * e[i]
    return x


def simulate(*, path: str = "eight", duration_s: float | None = None, rate_hz: float = 100.0,
             effects=None, seed: int = 0, noise: bool = True, **params) -> SimResult:
    """Simulate a quadrotor flight and return the logged :class:`Flight` and its ground truth.

    Parameters
    ----------
    path : one of :data:`PATHS` ("eight", "square", "circle", "lissajous", "random", "hover").
    duration_s : logged duration in seconds (default 20 s).
    rate_hz : log rate (Hz); the internal rate ``sim_rate_hz`` is rounded up to a multiple of it.
    effects : ``{id: params}`` of :data:`EFFECTS` (undeclared effects), default none.
    seed : integer seed; the same arguments give bit-identical results.
    noise : add the mocap-like measurement noise (see module docstring).
    **params : :data:`DEFAULT_PARAMS` overrides (``mass_kg``, ``k_drag``, ``altitude_m``, ...).

    Returns
    -------
    SimResult(flight, truth). ``truth`` (JSON-able) has ``params``, ``effects``, ``path``,
    ``seed``, ``rate_hz``, ``t`` and the true world accelerations ``ax, ay, az`` (m/s², ENU) at the
    logged times, ``true`` (noise-free vx, vy, vz, roll, pitch, yaw, thrust_n, wind_x, wind_y) and
    ``model`` (RMSE of the paper's model against the exact Z-Y-X hover geometry and against the
    true accelerations, both on the true states).
    """
    check_choice("path", path, PATHS, owner="simulate")
    P = _check_params(params, path)
    eff = parse_effects(effects)
    if duration_s is None:
        duration_s = 20.0
    if not (isinstance(duration_s, (int, float)) and math.isfinite(duration_s) and duration_s > 0):
        raise ConfigError(f"The 'duration_s' parameter of simulate must be > 0. Got {duration_s!r} instead.")
    if not (isinstance(rate_hz, (int, float)) and math.isfinite(rate_hz) and 0 < rate_hz <= 1000):
        raise ConfigError(f"The 'rate_hz' parameter of simulate must be in (0, 1000]. Got {rate_hz!r} instead.")
    if "ground_effect" in eff and "altitude_m" not in params:
        P["altitude_m"] = eff["ground_effect"]["altitude_m"]

    ss = np.random.SeedSequence(int(seed))
    rng_path, rng_gust, rng_noise = (np.random.default_rng(c) for c in ss.spawn(3))
    grid = _Grid.make(P, eff, duration_s, rate_hz)
    drive = _drive(path, P, eff, grid, rng_path, rng_gust)
    flown = _fly(P, eff, grid, drive)
    cols, S, A, R, a_world, rpm_true = _logged(P, eff, grid, drive, flown, rng_noise if noise else None)
    signals = {k: Signal(k, grid.t_log, v, canonical_unit(k), source="simulate") for k, v in cols.items()}
    span = ((0.0, float(grid.t_log[-1])),)
    note_params = {k: P[k] for k in sorted(P)}
    prov = Provenance(
        files=(), format="simulated", vehicle="simulated quadrotor", firmware=None,
        vehicle_type="multirotor",
        notes=(f"simulate(path={path!r}, duration_s={float(duration_s)}, rate_hz={float(rate_hz)}, "
               f"seed={int(seed)}, noise={bool(noise)})",
               f"effects: {eff if eff else 'none'}",
               f"params: {note_params}"),
    )
    flight = Flight(signals, prov, segments={"armed": span, "in_flight": span})
    truth = {"path": path, "duration_s": float(duration_s), "rate_hz": float(rate_hz), "seed": int(seed),
             "noise": bool(noise), "params": note_params, "effects": eff,
             **_truth(P, eff, grid, drive, flown.rotors, S, A, R, a_world, rpm_true, noise)}
    return SimResult(flight, truth)


@dataclass(frozen=True)
class _Grid:
    """The simulation's time grids (s): the log's, the integrator's (``dt``) and its half steps,
    with a margin before and after the log for the velocity window, the delays and the lag."""
    ts: float
    n_sub: int
    dt: float
    n_log: int
    n_margin: int
    t0: float
    n_steps: int
    th: np.ndarray          # half-step grid
    total: float            # the reference's length (s)
    delay: float            # attitude_delay's tau_s (s)

    @classmethod
    def make(cls, P: dict, eff: dict, duration_s: float, rate_hz: float) -> "_Grid":
        ts = 1.0 / rate_hz
        n_sub = int(math.ceil(P["sim_rate_hz"] / rate_hz - 1e-9))
        dt = ts / n_sub
        n_log = int(round(duration_s * rate_hz)) + 1
        delay = eff.get("attitude_delay", {}).get("tau_s", 0.0)
        margin_s = max(0.5, P["vel_window_s"] + abs(delay) + P["rpm_delay_s"] + 0.1)
        n_margin = int(math.ceil(margin_s / ts))
        t0 = -n_margin * ts
        n_steps = (n_log - 1 + 2 * n_margin) * n_sub
        th = t0 + np.arange(2 * n_steps + 1) * (dt / 2.0)
        return cls(ts, n_sub, dt, n_log, n_margin, t0, n_steps, th, (n_log - 1) * ts + n_margin * ts, delay)

    @property
    def t_int(self) -> np.ndarray:
        return self.t0 + np.arange(self.n_steps + 1) * self.dt

    @property
    def i_log(self) -> np.ndarray:
        return (self.n_margin + np.arange(self.n_log)) * self.n_sub

    @property
    def t_log(self) -> np.ndarray:
        return np.arange(self.n_log) * self.ts


@dataclass(frozen=True)
class _Drive:
    """What drives the flight on the half-step grid: the reference (position, velocity,
    acceleration, yaw, yaw rate), the wind (m/s, ENU) and the battery (V, thrust gain)."""
    rp: np.ndarray
    rv: np.ndarray
    ryaw: np.ndarray
    refs: list
    wind: np.ndarray
    volts: np.ndarray
    gains: np.ndarray


def _drive(path: str, P: dict, eff: dict, grid: _Grid, rng_path, rng_gust) -> _Drive:
    """The reference path (+ optional vertical motion + yaw sweep), the wind and the battery."""
    th, dt = grid.th, grid.dt
    rp, rv, ra = _reference(path, th, P, rng_path, grid.total)
    tv = eff.get("thrust_variation")
    if tv:
        w = 2 * math.pi / tv["period_s"]
        rp[:, 2] += tv["amp_m"] * np.sin(w * th)
        rv[:, 2] += tv["amp_m"] * w * np.cos(w * th)
        ra[:, 2] += -tv["amp_m"] * w * w * np.sin(w * th)
    wy_ = 2 * math.pi / P["yaw_period_s"]
    ryaw = P["yaw0_rad"] + P["yaw_amp_rad"] * np.sin(wy_ * th)
    ryawd = P["yaw_amp_rad"] * wy_ * np.cos(wy_ * th)
    refs = np.column_stack([rp, rv, ra, ryaw, ryawd]).tolist()

    wind = np.zeros((th.size, 2))
    if "wind" in eff:
        wind += (eff["wind"]["wx"], eff["wind"]["wy"])
    if "gust" in eff:
        gu = eff["gust"]
        wind += (gu["wx"], gu["wy"])
        if gu["sigma"] > 0:
            wind[:, 0] += _ou(rng_gust, th.size, dt / 2, gu["sigma"], gu["tau_s"])
            wind[:, 1] += _ou(rng_gust, th.size, dt / 2, gu["sigma"], gu["tau_s"])
    volts = np.full(th.size, P["battery_v"])
    gains = np.ones(th.size)
    bs = eff.get("battery_sag")
    if bs:
        frac = np.clip((th - 0.0) / max(grid.total, 1e-9), 0.0, 1.0)
        volts = bs["v_start"] + (bs["v_end"] - bs["v_start"]) * frac
        gains = (volts / bs["v_start"]) ** bs["exponent"]
    return _Drive(rp, rv, ryaw, refs, wind, volts, gains)


@dataclass(frozen=True)
class _Flown:
    """The integrated flight on the integrator's grid: states, derivatives, the controller's
    auxiliaries, body rates (rad/s), motor commands and rotor speeds (rpm), and the rotors."""
    states: np.ndarray
    derivs: np.ndarray
    auxs: np.ndarray
    w_int: np.ndarray
    u_int: np.ndarray
    rpm_int: np.ndarray
    rotors: object


def _fly(P: dict, eff: dict, grid: _Grid, drive: _Drive) -> _Flown:
    """Fly the reference (RK4), then the rotors: the torque demand of the flown attitude, the
    commands and the speeds (with lagging rotors, fly again with the four speeds in the state)."""
    rp, gains, dt, n_steps = drive.rp, drive.gains, grid.dt, grid.n_steps
    dyn = _Dyn(P, eff)
    # initial state: on the reference, attitude at the controller's set-point (a few fixed-point passes)
    s0 = [*rp[0], *drive.rv[0], 0.0, 0.0, drive.ryaw[0], 0.0, 0.0, 0.0]
    if "battery_sag" in eff or "ground_effect" in eff:  # start with the integrator at the hover trim
        g0 = gains[0]
        if dyn.ge_r:
            q = dyn.ge_r / (4.0 * max(rp[0, 2], dyn.ge_r / 2))
            g0 /= (1 - q * q)
        s0[11] = (1.0 / g0 - 1.0) * P["g"] / P["ki_z"]
    for _ in range(30):
        s0[6], s0[7], _ = dyn.command(s0, drive.refs[0])
    states, derivs, auxs = _rk4(dyn, s0, drive.refs, drive.wind.tolist(), gains.tolist(), n_steps, dt)

    t_int = grid.t_int
    rot = dyn.rotors
    w_int = _body_rates(states[:, 6:9], derivs[:, 6:9])
    dT_int = rot.torque_thrusts(w_int, np.gradient(w_int, dt, axis=0))
    if P["motor_tau_s"] > 0:
        # lagging rotors: fly again with the 4 speeds in the state (the torque demand of the
        # lag-free flight as an input), so the acceleration follows the lagged Σ k_f ω_i²
        dT_half = np.column_stack([np.interp(grid.th, t_int, dT_int[:, k]) for k in range(4)])
        u0 = rot.commands(auxs[:1, 4] * P["t_max_n"], dT_int[:1])
        s0 = s0 + rot.speeds(u0, gains[:1])[0].tolist()
        states, derivs, auxs = _rk4(dyn, s0, drive.refs, drive.wind.tolist(), gains.tolist(), n_steps, dt,
                                    dT_half.tolist())
        w_int = _body_rates(states[:, 6:9], derivs[:, 6:9])
    u_int = rot.commands(auxs[:, 4] * P["t_max_n"], dT_int)
    rpm_int = states[:, 12:16] if P["motor_tau_s"] > 0 else rot.speeds(u_int, gains[::2])
    return _Flown(states, derivs, auxs, w_int, u_int, rpm_int, rot)


def _logged(P: dict, eff: dict, grid: _Grid, drive: _Drive, flown: _Flown, rng_noise):
    """The logged columns at the log times (``rng_noise`` None: noise-free), and the true states,
    auxiliaries, rotation matrices, world accelerations and rotor speeds behind them."""
    states, t_int, t_log, i_log = flown.states, grid.t_int, grid.t_log, grid.i_log
    n_log, delay = grid.n_log, grid.delay
    S = states[i_log]
    A = flown.auxs[i_log]
    roll_t, pitch_t, yaw_t = S[:, 6], S[:, 7], S[:, 8]
    wx_t, wy_t, wz_t = flown.w_int[i_log].T
    R = euler_to_matrix(roll_t, pitch_t, yaw_t)
    a_world = A[:, :3]
    spec_world = a_world + np.array([0.0, 0.0, P["g"]])
    spec_body = np.einsum("nji,nj->ni", R, spec_world)   # R^T f

    # logged attitude: delayed and/or biased
    if delay > 0:
        t_src = t_log - delay
        att_log = [np.interp(t_src, t_int, states[:, k]) for k in (6, 7, 8)]
    else:
        att_log = [roll_t.copy(), pitch_t.copy(), yaw_t.copy()]
    ab = eff.get("attitude_bias")
    if ab:
        att_log[0] = att_log[0] + ab["roll"]
        att_log[1] = att_log[1] + ab["pitch"]

    pos = states[:, 0:3]
    if rng_noise is not None:
        dt = grid.dt
        pos_noisy = pos + rng_noise.normal(0.0, P["pos_noise_m"], size=pos.shape)
        half = int(round(P["vel_window_s"] / 2 / dt))
        j = np.arange(-half, half + 1)
        c = j / (dt * np.sum(j * j))
        vel_log = np.stack([pos_noisy[i_log[:, None] + j[None, :], k] @ c for k in range(3)], axis=1)
        pos_log = pos_noisy[i_log]
        att_log = [a + rng_noise.normal(0.0, P["att_noise_rad"], n_log) for a in att_log]
        gyro = np.column_stack([wx_t, wy_t, wz_t]) + rng_noise.normal(0.0, P["gyro_noise"], (n_log, 3))
        acc = spec_body + rng_noise.normal(0.0, P["acc_noise"], (n_log, 3))
        volt_log = np.interp(t_log, grid.th, drive.volts) + rng_noise.normal(0.0, P["volt_noise"], n_log)
    else:
        vel_log = S[:, 3:6].copy()
        pos_log = S[:, 0:3].copy()
        gyro = np.column_stack([wx_t, wy_t, wz_t])
        acc = spec_body.copy()
        volt_log = np.interp(t_log, grid.th, drive.volts)
    att_log[2] = wrap_angle(att_log[2])
    q = euler_to_quat(*att_log)
    q = np.where(q[:, :1] < 0, -q, q)

    throttle = A[:, 4]
    thrust_cmd = throttle * P["t_max_n"]     # what the flight controller believes it commands
    motors = flown.u_int[i_log]
    # logged speeds: rpm_delay_s ahead of the speeds that act, plus white noise
    rpm_delay = P["rpm_delay_s"]
    rpm_int = flown.rpm_int
    rpm_true = rpm_int[i_log]
    rpm_log = (np.column_stack([np.interp(t_log + rpm_delay, t_int, rpm_int[:, k]) for k in range(4)])
               if rpm_delay > 0 else rpm_true.copy())
    if rng_noise is not None:
        rpm_log = rpm_log + rng_noise.normal(0.0, P["rpm_noise"], rpm_log.shape)

    cols = {
        "x": pos_log[:, 0], "y": pos_log[:, 1], "z": pos_log[:, 2],
        "vx": vel_log[:, 0], "vy": vel_log[:, 1], "vz": vel_log[:, 2],
        "roll": att_log[0], "pitch": att_log[1], "yaw": att_log[2],
        "qw": q[:, 0], "qx": q[:, 1], "qy": q[:, 2], "qz": q[:, 3],
        "wx": gyro[:, 0], "wy": gyro[:, 1], "wz": gyro[:, 2],
        "ax": acc[:, 0], "ay": acc[:, 1], "az": acc[:, 2],
        "throttle": throttle, "thrust": thrust_cmd,
        "motor1": motors[:, 0], "motor2": motors[:, 1], "motor3": motors[:, 2], "motor4": motors[:, 3],
        "rpm1": rpm_log[:, 0], "rpm2": rpm_log[:, 1], "rpm3": rpm_log[:, 2], "rpm4": rpm_log[:, 3],
        "battery_voltage": volt_log,
    }
    return cols, S, A, R, a_world, rpm_true


def _rms(x) -> float:
    """RMS (m/s²), to 1e-12: below that it is round-off, which differs between numpy builds."""
    return round(float(np.sqrt(np.mean(np.square(x)))), 12)


def _truth(P: dict, eff: dict, grid: _Grid, drive: _Drive, rot, S, A, R, a_world, rpm_true,
           noise: bool) -> dict:
    """The ground truth at the log times: true accelerations and states, the models' errors on
    the true states, and the rotors' constants (JSON-able)."""
    t_log, th = grid.t_log, grid.th
    roll_t, pitch_t, yaw_t = S[:, 6], S[:, 7], S[:, 8]
    vx_t, vy_t = S[:, 3], S[:, 4]
    mx, my = tilt_drag_model(vx_t, vy_t, roll_t, pitch_t, yaw_t, P["k_drag"], P["g"])
    ex_, ey_ = _exact_hover_model(vx_t, vy_t, roll_t, pitch_t, yaw_t, P["k_drag"], P["g"])
    wind_log = np.column_stack([np.interp(t_log, th, drive.wind[:, 0]), np.interp(t_log, th, drive.wind[:, 1])])
    bs = eff.get("battery_sag")
    rpm_delay = P["rpm_delay_s"]
    m = P["mass_kg"]
    k_T = P["k_f"] * RPM_SCALE ** 2 / m
    # the rotor-thrust prior with the planted k_T, k_D on the true states and true speeds
    rotor_model = (k_T * np.sum(rot.gain * np.square(rpm_true / RPM_SCALE), axis=1)[:, None] * R[:, :, 2]
                   - np.array([0.0, 0.0, P["g"]]) - P["k_drag"] * S[:, 3:6])
    rotor_err = a_world - rotor_model

    return {
        "t": _round(t_log), "ax": _round(a_world[:, 0]), "ay": _round(a_world[:, 1]),
        "az": _round(a_world[:, 2]),
        "true": {
            "vx": _round(vx_t), "vy": _round(vy_t), "vz": _round(S[:, 5]),
            "roll": _round(roll_t), "pitch": _round(pitch_t), "yaw": _round(wrap_angle(yaw_t)),
            "thrust_n": _round(A[:, 3]), "wind_x": _round(wind_log[:, 0]), "wind_y": _round(wind_log[:, 1]),
        },
        "model": {
            "geometry_rmse_x": _rms(mx - ex_), "geometry_rmse_y": _rms(my - ey_),
            "geometry_max_abs": float(max(np.max(np.abs(mx - ex_)), np.max(np.abs(my - ey_)))),
            "truth_rmse_x": _rms(a_world[:, 0] - mx), "truth_rmse_y": _rms(a_world[:, 1] - my),
            "max_tilt_rad": float(np.max(np.abs(np.concatenate([roll_t, pitch_t])))),
            "rotor_rmse_x": _rms(rotor_err[:, 0]), "rotor_rmse_y": _rms(rotor_err[:, 1]),
            "rotor_rmse_z": _rms(rotor_err[:, 2]),
            "note": "paper tilt-drag model on the TRUE states vs the exact Z-Y-X hover-balance "
                    "geometry (geometry_*) and vs the true accelerations (truth_*); rotor_*: the "
                    "rotor-thrust prior with rotors.k_T and k_drag on the true states and the "
                    "true (undelayed, noise-free) rotor speeds vs the true accelerations; m/s^2",
        },
        "rotors": {
            "k_f": P["k_f"], "k_f_unit": "N/rpm^2 (T_i = k_f rpm_i^2)",
            "k_T": k_T,
            "k_T_unit": "m/s^2 per (10^4 rpm)^2 = k_f 1e8 / mass_kg: the coefficient of "
                        "sum_i (rpm_i/1e4)^2 in the rotor-thrust prior",
            "hover_rpm": math.sqrt(m * P["g"] / 4.0 / P["k_f"]), "rpm_max": rot.w_max,
            "motor_tau_s": P["motor_tau_s"], "rpm_delay_s": rpm_delay,
            "thrust_gain": rot.gain.tolist(),
            "rpm_noise": P["rpm_noise"] if noise else 0.0,
            "thrust_expo": P["thrust_expo"],
            "k_cmd": P["t_max_n"] / 4.0 / m,
            "k_cmd_unit": "m/s^2 per unit of the thrust curve f_e(u) of one motor: (t_max_n/4)/mass_kg",
            "v_ref": (bs or {}).get("v_start", P["battery_v"]),
            "command_map": "T_i = (t_max_n/4) f_e(u_i s), f_e(u) = (1-e) u + e u^2 (e = thrust_expo), "
                           "s = sqrt(battery gain) (V/v_start for battery_sag's exponent 2); rpm_i = "
                           "rpm_max sqrt(f_e(u_i s)) once settled (lag motor_tau_s)",
            "layout": "X, ArduPilot QUAD/X order: 1 front-right CCW, 2 back-left CCW, "
                      "3 front-left CW, 4 back-right CW",
        },
    }


def _round(x, nd: int = 9):
    return [round(float(v), nd) for v in np.asarray(x).ravel()]
