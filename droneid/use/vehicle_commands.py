"""The motor lag of a command-driven vehicle in an exported vehicle file (``droneid export
--vehicle``): the code of :meth:`droneid.simulation.motor_model.MotorModel.effective`, one step at a
time, in the input conditioner. Its state is each rotor's normalised speed ``w = ω/ω_max``
(dimensionless, 0..1), so the file answers its inputs (the commands and the battery voltage) as
the rotors would: a command step spins the rotor up over τ, not at once. The arithmetic is the
library's, operation for operation, so the file and ``predict --open-loop`` agree to rounding."""
from __future__ import annotations

from droneid.use.vehicle_code import num

__all__ = ["lag_header", "lag_code"]


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
