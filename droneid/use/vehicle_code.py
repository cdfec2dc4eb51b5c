"""The text of an exported vehicle file (``droneid export --vehicle``): the parts a vehicle is
made of (:class:`Part`: translation, rotation) and the builders that assemble them into one Python
or C99 file (:func:`vehicle_python`, :func:`vehicle_c`): an input conditioner fed the logged
inputs one step at a time, the state derivative and one RK4 step with the quaternion renormalised
at every stage (as :func:`droneid.simulation.openloop.simulate`). What goes into a part is
:mod:`droneid.use.vehicle_export`'s."""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

__all__ = ["Part", "num", "floats", "vehicle_python", "vehicle_c"]


def num(x) -> str:
    return repr(float(x))


def floats(values, to: str) -> str:
    """Floats as a Python list or a C initializer."""
    body = ", ".join(num(v) for v in values)
    return f"[{body}]" if to == "python" else f"{{{body}}}"


@dataclass(frozen=True)
class Part:
    """One half of a generated vehicle (translation or rotation).

    ``header``: its lines of the file header; ``width``: the input columns it reads from ``u``
    (after those of the parts before it); ``history``: how many steps back it reads the motor
    speeds (its largest delay); ``code[to]``: source snippets in language ``to``: ``defs``
    (module level), ``state`` (Python: lines of ``Inputs.__init__``; C: members of the
    ``droneid_inputs`` struct), ``fill`` (in the conditioner, after the motor speeds of this step
    joined the history ``h``, oldest first: its columns of ``u``) and ``deriv`` (in the
    derivative: v̇ or ω̇ from ``x``, ``R``, ``vb`` and its columns of ``u``); ``euler``: it reads
    ``roll``, ``pitch``, ``yaw`` of the simulated quaternion (the derivative then computes them)."""
    header: tuple
    width: int
    history: int
    code: Mapping
    imports: tuple = ()
    euler: bool = False


_PY_EULER = '''def _euler(q):
    """Z-Y-X (roll, pitch, yaw) in rad of the quaternion q (normalised first; pitch clipped at gimbal
    lock), as droneid.core.frames.quat_to_euler."""
    n = math.sqrt(sum(c * c for c in q))
    w, x, y, z = (c / n for c in q)
    roll = math.atan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    pitch = math.asin(min(1.0, max(-1.0, 2.0 * (w * y - z * x))))
    yaw = math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    return roll, pitch, yaw


'''

_C_EULER = '''/* Z-Y-X roll, pitch, yaw (rad) of the quaternion q (normalised first; pitch clipped at gimbal lock) */
static void droneid_euler(const double *q, double *roll, double *pitch, double *yaw)
{
    double n = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    double w = q[0] / n, x = q[1] / n, y = q[2] / n, z = q[3] / n;
    double sp = 2.0 * (w * y - z * x);
    *roll = atan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y));
    *pitch = asin(sp < -1.0 ? -1.0 : (sp > 1.0 ? 1.0 : sp));
    *yaw = atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z));
}

'''


def vehicle_python(parts, header, M: int, width: int, dt_s: float, arg: str = "rpm",
                   what: str = "motor speeds") -> str:
    """The Python file: ``M`` logged inputs per step (``arg``: the name of the conditioner's
    argument, ``what`` they are), ``width`` columns of u, the step ``dt_s`` (s)."""
    imports = sorted({"math", *(i for p in parts for i in p.imports)})
    euler = any(p.euler for p in parts)
    code = [p.code["python"] for p in parts]
    return '\n'.join(['"""' + "\n".join(header).replace('"""', "'''").replace("\\", "\\\\") + "\n\nUsage: "
                      f"inputs = Inputs() (one per flight); per step: x = step(x, inputs.push({arg})).\n"
                      '"""', *(f"import {i}" for i in imports), f'''
M = {M}
DT = {num(dt_s)}
U = {width}
HIST = {max(p.history for p in parts) + 1}
''' + "".join("\n\n" + c["defs"].strip() + "\n" for c in code if c["defs"]) + f'''

class Inputs:
    """The logged {what} to the model's inputs u, one step at a time (causal)."""

    def __init__(self, dt=DT):
        self.dt = dt
        self.hist = None
{"".join(c["state"] for c in code)}
    def push(self, {arg}):
        """{arg}: the M {what} of this step as logged -> u (list of U), held over the step."""
        now = [float(r) for r in {arg}]
        if len(now) != M:
            raise ValueError(f"push takes the {{M}} {what} of one step, got {{len(now)}}")
        if self.hist is None:
            self.hist = [now] * HIST
        self.hist = self.hist[1:] + [now]
        h = self.hist
        u = []
{"".join(c["fill"] for c in code)}        return u


{_PY_EULER if euler else ""}def _rot(q):
    n = math.sqrt(sum(c * c for c in q))
    w, x, y, z = (c / n for c in q)
    return [[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]]


def derivative(x, u):
    """dx/dt (list of 13) of the state x (13) with the inputs u (U) of this step."""
    R = _rot(x[6:10])
    v, w = x[3:6], x[10:13]
    vb = [sum(R[i][j] * v[i] for i in range(3)) for j in range(3)]
{"    roll, pitch, yaw = _euler(x[6:10])" + chr(10) if euler else ""}{"".join(c["deriv"] for c in code)}    qw, qx, qy, qz = x[6:10]
    dq = [0.5 * (-qx * w[0] - qy * w[1] - qz * w[2]), 0.5 * (qw * w[0] + qy * w[2] - qz * w[1]),
          0.5 * (qw * w[1] - qx * w[2] + qz * w[0]), 0.5 * (qw * w[2] + qx * w[1] - qy * w[0])]
    return list(v) + dv + dq + dw


def _unit_q(x):
    n = math.sqrt(sum(c * c for c in x[6:10]))
    return x[:6] + [c / n for c in x[6:10]] + x[10:]


def step(x, u, dt=DT):
    """The state after one step of dt seconds (RK4, the inputs u held over the step)."""
    x = _unit_q(list(map(float, x)))
    k1 = derivative(x, u)
    k2 = derivative(_unit_q([a + 0.5 * dt * b for a, b in zip(x, k1)]), u)
    k3 = derivative(_unit_q([a + 0.5 * dt * b for a, b in zip(x, k2)]), u)
    k4 = derivative(_unit_q([a + dt * b for a, b in zip(x, k3)]), u)
    return _unit_q([a + dt / 6.0 * (b + 2.0 * c + 2.0 * d + e) for a, b, c, d, e in zip(x, k1, k2, k3, k4)])
'''])


def vehicle_c(parts, header, M: int, width: int, dt_s: float, arg: str = "rpm", what: str = "motor speeds") -> str:
    """The C99 file, as :func:`vehicle_python`."""
    code = [p.code["c"] for p in parts]
    euler = any(p.euler for p in parts)
    lines = ["/*"] + [(" * " + h).rstrip() for h in header] + [
        " *", " * C99; compile with -lm. Usage: droneid_inputs c; droneid_inputs_init(&c, DRONEID_DT); per step:",
        f" * droneid_inputs_push(&c, {arg}, u); droneid_step(x, u, DRONEID_DT); with double u[DRONEID_U].", " */"]
    lines.append(f'''#include <math.h>
#include <string.h>

#define DRONEID_M {M}
#define DRONEID_U {max(width, 1)}
#define DRONEID_DT {num(dt_s)}
#define DRONEID_HIST {max(p.history for p in parts) + 1}

''' + "".join(c["defs"] + "\n" for c in code if c["defs"]) + f'''typedef struct {{
    int started;
    double hist[DRONEID_HIST][DRONEID_M];
{"".join(c["state"] for c in code)}    double dt;
}} droneid_inputs;

void droneid_inputs_init(droneid_inputs *c, double dt)
{{
    memset(c, 0, sizeof *c);
    c->dt = dt;
}}

/* {arg}: this step's DRONEID_M {what} as logged -> u (DRONEID_U), held over the step */
void droneid_inputs_push(droneid_inputs *c, const double {arg}[DRONEID_M], double u[DRONEID_U])
{{
    int i, h;
    if (!c->started)
        for (h = 0; h < DRONEID_HIST; h++)
            for (i = 0; i < DRONEID_M; i++) c->hist[h][i] = {arg}[i];
    for (h = 0; h + 1 < DRONEID_HIST; h++) memcpy(c->hist[h], c->hist[h + 1], sizeof c->hist[h]);
    for (i = 0; i < DRONEID_M; i++) c->hist[DRONEID_HIST - 1][i] = {arg}[i];
{"".join(c["fill"] for c in code)}    c->started = 1;
    (void)u;
}}

{_C_EULER if euler else ""}static void rotation_matrix(const double *q, double R[3][3])
{{
    double n = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    double w = q[0] / n, x = q[1] / n, y = q[2] / n, z = q[3] / n;
    R[0][0] = 1 - 2 * (y * y + z * z); R[0][1] = 2 * (x * y - w * z); R[0][2] = 2 * (x * z + w * y);
    R[1][0] = 2 * (x * y + w * z); R[1][1] = 1 - 2 * (x * x + z * z); R[1][2] = 2 * (y * z - w * x);
    R[2][0] = 2 * (x * z - w * y); R[2][1] = 2 * (y * z + w * x); R[2][2] = 1 - 2 * (x * x + y * y);
}}

void droneid_derivative(const double x[13], const double u[DRONEID_U], double dx[13])
{{
    double R[3][3], vb[3];
    const double *v = x + 3, *w = x + 10;
    int i, j;
    rotation_matrix(x + 6, R);
    for (j = 0; j < 3; j++) {{ vb[j] = 0.0; for (i = 0; i < 3; i++) vb[j] += R[i][j] * v[i]; }}
    for (i = 0; i < 3; i++) dx[i] = v[i];
{"    double roll, pitch, yaw;" + chr(10) + "    droneid_euler(x + 6, &roll, &pitch, &yaw);" + chr(10) if euler else ""}{"".join(c["deriv"] for c in code)}    dx[6] = 0.5 * (-x[7] * w[0] - x[8] * w[1] - x[9] * w[2]);
    dx[7] = 0.5 * (x[6] * w[0] + x[8] * w[2] - x[9] * w[1]);
    dx[8] = 0.5 * (x[6] * w[1] - x[7] * w[2] + x[9] * w[0]);
    dx[9] = 0.5 * (x[6] * w[2] + x[7] * w[1] - x[8] * w[0]);
    (void)u; (void)vb;{" (void)roll; (void)pitch; (void)yaw;" if euler else ""}
}}

static void unit_q(double *x)
{{
    double n = sqrt(x[6] * x[6] + x[7] * x[7] + x[8] * x[8] + x[9] * x[9]);
    int i;
    for (i = 6; i < 10; i++) x[i] /= n;
}}

/* x (13) advanced by one RK4 step of dt seconds, the inputs u held over the step */
void droneid_step(double x[13], const double u[DRONEID_U], double dt)
{{
    double k1[13], k2[13], k3[13], k4[13], y[13];
    int i;
    unit_q(x);
    droneid_derivative(x, u, k1);
    for (i = 0; i < 13; i++) y[i] = x[i] + 0.5 * dt * k1[i];
    unit_q(y);
    droneid_derivative(y, u, k2);
    for (i = 0; i < 13; i++) y[i] = x[i] + 0.5 * dt * k2[i];
    unit_q(y);
    droneid_derivative(y, u, k3);
    for (i = 0; i < 13; i++) y[i] = x[i] + dt * k3[i];
    unit_q(y);
    droneid_derivative(y, u, k4);
    for (i = 0; i < 13; i++) x[i] += dt / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
    unit_q(x);
}}
''')
    return "\n".join(lines)
