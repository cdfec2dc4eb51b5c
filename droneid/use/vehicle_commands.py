"""The motor lag of a command-driven vehicle in an exported vehicle file (``droneid export
--vehicle``): the code of :meth:`droneid.simulation.motor_model.MotorModel.effective`, one step at a
time, in the input conditioner. Its state is each rotor's normalised speed ``w = ω/ω_max``
(dimensionless, 0..1), so the file answers its inputs (the commands and the battery voltage) as
the rotors would: a command step spins the rotor up over τ, not at once. The arithmetic is the
library's, operation for operation, so the file and ``predict --open-loop`` agree to rounding.
A command-driven rotational model (:mod:`droneid.rotation.commands`) reads the rotors' normalised
speeds the same way (:func:`speed_code`): its own copy of the lag's state, as the library computes
them for the rotation apart from the translation."""
from __future__ import annotations

from droneid.use.vehicle_code import num

__all__ = ["lag_header", "lag_code", "speed_header", "speed_code"]


def lag_header(motor) -> tuple[str, ...]:
    """The header lines that state the motor model (units included; ASCII, as the rest of the file)."""
    lo, hi = motor.spin
    batt = (f"s = V/V_REF with V the logged battery_voltage (V), V_REF = {num(motor.v_ref)} V (1 where V <= 0)"
            if motor.v_ref is not None else "s = 1 (no battery compensation kept)")
    lines = [f"  Motor model (identified; droneid.simulation.motor_model): q = (u - SPIN_LO)/(SPIN_HI - SPIN_LO) * s "
             f"with SPIN_LO = {num(lo)}, SPIN_HI = {num(hi)},",
             f"  {batt}; thrust of a motor proportional to f_e(q) = (1 - EXPO) q + EXPO q^2, EXPO = {num(motor.expo)}."]
    if motor.lagged:
        lines += [f"  Motor lag: each rotor's normalised speed w (0..1) lags w* = sqrt(max(f_e(q), 0)) to first order "
                  f"with TAU = {num(motor.lag_s)} s,",
                  "  thrust proportional to w^2; the input conditioner keeps w: with a = exp(-dt/TAU) the speed over a",
                  "  step averages w_mean = w* + (w - w*) TAU/dt (1 - a) (held over the step) and ends at w* + (w - w*) a;",
                  "  w starts at w*. The models read the effective command u_eff whose curve gives w_mean^2.",
                  "  The commands and the voltage are read at t, not at the models' offsets: identify chose the lag with",
                  "  the commands read at t, and the offset without a lag (both describe how the commands lead their",
                  "  thrust; together they would count it twice), as droneid.simulation.openloop does."]
    else:
        lines.append("  No motor lag was kept: the commands are read at the models' offsets.")
    return tuple(lines)


def lag_code(motor, cmd_index: list[int], v_index: int | None) -> dict:
    """{"python" | "c": {"defs", "state", "fill"}} of the motor lag: ``cmd_index`` the positions
    of the commands in the logged inputs, ``v_index`` that of the battery voltage (used only
    where the model compensates it). The fill leaves the effective commands in ``eff``."""
    v_idx = v_index if motor.v_ref is not None and v_index is not None else None
    lo, hi = motor.spin
    n = len(cmd_index)
    py_defs = f'''EXPO = {num(motor.expo)}          # the thrust curve's shape e: f_e(q) = (1 - e) q + e q^2
SPIN_LO, SPIN_HI = {num(lo)}, {num(hi)}          # the commands where the curve starts and ends
V_REF = {"None" if v_idx is None else num(motor.v_ref)}          # V: the commands scaled by V/V_REF (None: not)
V_IDX = {v_idx}          # the battery voltage's position in the logged inputs
CMD_IDX = {list(cmd_index)}          # the commands' positions in the logged inputs
TAU = {num(motor.lag_s)}          # s: the first-order lag of each rotor's speed


def _inverse(f):
    """The normalised command q >= 0 whose thrust curve f_e(q) is f (f < 0: 0)."""
    f = max(f, 0.0)
    if EXPO <= 0.0:
        return f
    return (-(1.0 - EXPO) + math.sqrt((1.0 - EXPO) ** 2 + 4.0 * EXPO * f)) / (2.0 * EXPO)


'''
    py_state = '''        self.w = None          # the rotors' normalised speeds (the motor lag's state)
        self.lag_a = math.exp(-self.dt / TAU)
        self.lag_c = TAU / self.dt * (1.0 - self.lag_a)
'''
    py_fill = '''        s = h[-1][V_IDX] / V_REF if V_IDX is not None and h[-1][V_IDX] > 0 else 1.0
        target = [math.sqrt(max((1.0 - EXPO) * q + EXPO * q * q, 0.0))
                  for q in ((h[-1][i] - SPIN_LO) / (SPIN_HI - SPIN_LO) * s for i in CMD_IDX)]
        if self.w is None:
            self.w = target
        mean = [t + (w - t) * self.lag_c for t, w in zip(target, self.w)]
        self.w = [t + (w - t) * self.lag_a for t, w in zip(target, self.w)]
        eff = [SPIN_LO + (SPIN_HI - SPIN_LO) * _inverse(m * m) / s for m in mean]
'''
    c_defs = f'''#define DRONEID_NCMD {n}
static const double EXPO = {num(motor.expo)};          /* the thrust curve's shape e */
static const double SPIN_LO = {num(lo)}, SPIN_HI = {num(hi)};
static const double V_REF = {"1.0" if v_idx is None else num(motor.v_ref)};          /* V */
static const int V_IDX = {-1 if v_idx is None else v_idx};          /* -1: no battery compensation */
static const int CMD_IDX[DRONEID_NCMD] = {{{", ".join(map(str, cmd_index))}}};
static const double TAU = {num(motor.lag_s)};          /* s: the lag of each rotor's speed */

/* the normalised command q >= 0 whose thrust curve f_e(q) is f (f < 0: 0) */
static double droneid_inverse(double f)
{{
    if (f < 0.0) f = 0.0;
    if (EXPO <= 0.0) return f;
    return (-(1.0 - EXPO) + sqrt((1.0 - EXPO) * (1.0 - EXPO) + 4.0 * EXPO * f)) / (2.0 * EXPO);
}}

'''
    c_state = "    double w[DRONEID_NCMD];          /* the rotors' normalised speeds (the motor lag's state) */\n"
    c_fill = '''        double eff[DRONEID_NCMD], s = 1.0, a = exp(-c->dt / TAU), q, f, tgt, mean;
        double cc = TAU / c->dt * (1.0 - a);
        int k;
        if (V_IDX >= 0 && c->hist[DRONEID_HIST - 1][V_IDX] > 0) s = c->hist[DRONEID_HIST - 1][V_IDX] / V_REF;
        for (k = 0; k < DRONEID_NCMD; k++) {
            q = (c->hist[DRONEID_HIST - 1][CMD_IDX[k]] - SPIN_LO) / (SPIN_HI - SPIN_LO) * s;
            f = (1.0 - EXPO) * q + EXPO * q * q;
            tgt = sqrt(f > 0.0 ? f : 0.0);
            if (!c->started) c->w[k] = tgt;
            mean = tgt + (c->w[k] - tgt) * cc;
            c->w[k] = tgt + (c->w[k] - tgt) * a;
            eff[k] = SPIN_LO + (SPIN_HI - SPIN_LO) * droneid_inverse(mean * mean) / s;
        }
'''
    return {"python": {"defs": py_defs, "state": py_state, "fill": py_fill},
            "c": {"defs": c_defs, "state": c_state, "fill": c_fill}}


def speed_header(commands, offset: int) -> tuple[str, ...]:
    """The header lines of a command-driven rotational model's inputs (:mod:`droneid.rotation.commands`)."""
    m = commands.motor
    read = (f"through the motor lag (TAU = {num(m.lag_s)} s, the arithmetic above), the commands read at t"
            if m.lagged else f"the commands of {offset} step(s) earlier (the plan's offset), no lag")
    return ("  Its rotor speeds are the rotors' NORMALISED speeds w (0..1 of full speed) from the commands through the",
            f"  identified motor model: w = sqrt(max(f_e(q), 0)), {read};",
            "  so s_r = w^2 is each rotor's thrust as a fraction of full thrust (not rad/s): the torque",
            "  coefficients are in rad/s^2 per unit of normalised thrust.")


def speed_code(commands, cmd_index: list[int], v_index: int | None, offset: int, delay_r: int) -> dict:
    """{"python" | "c": {"defs", "state", "fill"}} that keep the rotors' normalised speeds of the
    last ``delay_r + 1`` steps (``self.rw_hist`` / ``c->rw_hist``, oldest first), as
    :meth:`droneid.rotation.commands.CommandSpeeds.speeds` computes them: the commands at positions
    ``cmd_index`` of the logged inputs (``offset`` steps back without a lag), the battery voltage
    at ``v_index`` where the compensation was kept, through the lag where one was kept."""
    m = commands.motor
    v_idx = v_index if m.v_ref is not None and v_index is not None else None
    lo, hi = m.spin
    n = len(cmd_index)
    py_defs = f'''RW_EXPO = {num(m.expo)}          # the thrust curve's shape e of the rotors' speeds
RW_LO, RW_HI = {num(lo)}, {num(hi)}
RW_VREF = {"None" if v_idx is None else num(m.v_ref)}          # V (None: no battery compensation)
RW_V = {v_idx}
RW_CMD = {list(cmd_index)}
RW_OFFSET = {int(offset)}          # steps the commands are read back (0 through a lag)
RW_TAU = {num(m.lag_s)}          # s: the motor lag (0: none)
RW_HIST = {int(delay_r) + 1}
'''
    py_state = '''        self.rw = self.rw_hist = None          # the rotors' normalised speeds (lag state, history)
'''
    py_fill = '''        hs = h[-1 - RW_OFFSET]
        sv = hs[RW_V] / RW_VREF if RW_V is not None and hs[RW_V] > 0 else 1.0
        target = [math.sqrt(max((1.0 - RW_EXPO) * q + RW_EXPO * q * q, 0.0))
                  for q in ((hs[i] - RW_LO) / (RW_HI - RW_LO) * sv for i in RW_CMD)]
        if RW_TAU > 0:
            a = math.exp(-self.dt / RW_TAU)
            if self.rw is None:
                self.rw = target
            wr = [t + (w - t) * RW_TAU / self.dt * (1.0 - a) for t, w in zip(target, self.rw)]
            self.rw = [t + (w - t) * a for t, w in zip(target, self.rw)]
        else:
            wr = target
        self.rw_hist = (self.rw_hist or [wr] * RW_HIST)[1:] + [wr]
'''
    c_defs = f'''#define DRONEID_NR {n}
#define DRONEID_RWH {int(delay_r) + 1}
static const double RW_EXPO = {num(m.expo)}, RW_LO = {num(lo)}, RW_HI = {num(hi)};
static const double RW_VREF = {"1.0" if v_idx is None else num(m.v_ref)};          /* V */
static const int RW_V = {-1 if v_idx is None else v_idx};          /* -1: no battery compensation */
static const int RW_CMD[DRONEID_NR] = {{{", ".join(map(str, cmd_index))}}};
static const int RW_OFFSET = {int(offset)};
static const double RW_TAU = {num(m.lag_s)};          /* s: the motor lag (0: none) */
'''
    c_state = "    double rw[DRONEID_NR], rw_hist[DRONEID_RWH][DRONEID_NR];          /* the rotors' normalised speeds */\n"
    c_fill = '''    {
        const double *hs = c->hist[DRONEID_HIST - 1 - RW_OFFSET];
        double sv = 1.0, q, f, tgt, wr[DRONEID_NR], a = RW_TAU > 0.0 ? exp(-c->dt / RW_TAU) : 0.0;
        int k, j;
        if (RW_V >= 0 && hs[RW_V] > 0) sv = hs[RW_V] / RW_VREF;
        for (k = 0; k < DRONEID_NR; k++) {
            q = (hs[RW_CMD[k]] - RW_LO) / (RW_HI - RW_LO) * sv;
            f = (1.0 - RW_EXPO) * q + RW_EXPO * q * q;
            tgt = sqrt(f > 0.0 ? f : 0.0);
            if (RW_TAU > 0.0) {
                if (!c->started) c->rw[k] = tgt;
                wr[k] = tgt + (c->rw[k] - tgt) * RW_TAU / c->dt * (1.0 - a);
                c->rw[k] = tgt + (c->rw[k] - tgt) * a;
            } else {
                wr[k] = tgt;
            }
        }
        for (j = 0; j < DRONEID_RWH; j++)
            for (k = 0; k < DRONEID_NR; k++)
                c->rw_hist[j][k] = (!c->started || j + 1 == DRONEID_RWH) ? wr[k] : c->rw_hist[j + 1][k];
    }
'''
    return {"python": {"defs": py_defs, "state": py_state, "fill": py_fill},
            "c": {"defs": c_defs, "state": c_state, "fill": c_fill}}
