"""Per-motor thrust: one rotor gives less (or more) thrust per rpm² than the others (a damaged or
wrong propeller, a weak motor).

Physics. Rotor i pushes T_i = k_i ω_i² (ω_i its logged speed). On a symmetric quadrotor (centre
of mass at the centre, equal arms, rotor drag torque ∝ thrust) the attitude loop keeps the roll,
pitch and yaw torques balanced on average, which forces T_1 = T_2 = T_3 = T_4 whatever the motor
order: so k_i ∝ 1 / mean(ω_i²), and a motor that needs a higher speed for its share of the thrust
is weaker. Its thrust relative to the others is r_i = k_i / median_{j≠i} k_j (the coefficients
are relative to their mean; the median of the others keeps one weak motor from making the rest
look strong). (A centre of mass
off the centre makes the motors of one SIDE spin faster, not one motor.) The translational data
cannot show this: the rotors' shares of the thrust barely change in flight, so Σ k_i ω_i² is
within noise of (mean k) Σ ω_i².

Decision (the one rule, :func:`droneid.fitting.decide.decide`): rows are every motor's thrust share
k_i ω_i² / Σ_j k_j ω_j² − 1/N at every sample, validation blocks the diagnosis's time blocks;
without the effect k_i = 1, with it the k_i come from the OTHER blocks (leave-one-block-out).
Its size: the rule's size floor (``DiagnoseConfig.min_rel_improvement``, 1 %) is held to the largest
``|r_i − 1|``, not to the drop of the share residuals, which has no physical scale (their base is
the controller's differential thrust, near zero: four noise-free simulated flights proved a
0.45 % side-to-side difference, a centre of mass off the centre, at −5.9 % of those residuals).
Uncertainty: block jackknife of r_i. A motor is NAMED when |r_i − 1| ≥ ``MIN_DEVIATION`` (5 %) and
≥ ``Z_NAME`` (3) standard errors: "motor 2 gives 85 ± 3 % of the others' thrust: check its
propeller". Applies with a rotor-thrust prior from the logged motor speeds rpm1..rpmN, N ≥ 3.

Once accepted, its v̇ feature G·(Σ k_i ω_i² / Σ ω_i² − 1) (the prior's thrust with the motors
weighted by k_i = their coefficients relative to the mean, fixed from training; coefficient ``w``,
1 = exactly k_T Σ k_i ω_i²) joins the model, so the effects tried after it see the corrected
thrust, and it folds into the rotor-thrust prior.
"""
import numpy as np
import sympy as sp

from droneid.core.expressions import symbol
from droneid.core.targets import TARGETS
from priors.effects import TILT, Effect, Interpretation
from priors.thrust import RPM_SCALE, motor_count

#: smallest deviation from the others' thrust that names a motor
MIN_DEVIATION = 0.05
#: standard errors a deviation must reach to name a motor (≈ Bonferroni over 4 motors at 1 %)
Z_NAME = 3.0


def _motors(available) -> int:
    return motor_count(available).get("rpm", 0)


def _applicable(ctx):
    if ctx.tilt_role != "thrust" or ctx.tilt is None or not any(
            s.name.startswith("rpm") for s in ctx.tilt.free_symbols):
        return "needs a rotor-thrust prior whose thrust comes from the logged motor speeds"
    if _motors(ctx.columns) < 3:
        return "needs the speeds of at least 3 motors (rpm1..rpmN)"
    return None


def _coefficients(ctx):
    """k_i ∝ 1/mean(ω_i²) over the training rows, relative to their mean (constants k1..kN)."""
    n = _motors(ctx.columns)
    m = np.array([np.mean((np.asarray(ctx.columns[f"rpm{i}"], float) / RPM_SCALE) ** 2)
                  for i in range(1, n + 1)])
    k = 1.0 / m
    return {f"k{i + 1}": float(v) for i, v in enumerate(k / k.mean())}


def _features(ctx, consts):
    n = _motors(ctx.columns)
    if any(f"k{i}" not in consts for i in range(1, n + 1)):
        return {}
    w2 = [(symbol(f"rpm{i}") / int(RPM_SCALE)) ** 2 for i in range(1, n + 1)]
    weighted = sp.Add(*[sp.Float(consts[f"k{i}"]) * w for i, w in enumerate(w2, 1)])
    return {"w": ctx.tilt * (weighted / sp.Add(*w2) - 1)}


def ratios_from_means(m) -> np.ndarray:
    """Thrust of each motor relative to the others (the median of their k), from the mean squared
    speeds ``m`` (equal thrusts: k_i ∝ 1/m_i). The median, so one weak motor does not make the
    others look strong (with the mean, a motor at 85 % puts the others at 105 %)."""
    k = 1.0 / np.asarray(m, float)
    return np.array([k[i] / np.median(np.delete(k, i)) for i in range(k.size)])


def _pct(x: float) -> str:
    """A fraction in percent to 3 significant digits (at least one decimal under 100 %):
    0.9955 -> "99.6", 0.85 -> "85.0", 0.0005 -> "0.05"."""
    v = 100 * x
    return f"{v:.2g}" if abs(v) < 1 else f"{v:.1f}"


def _shares(w2, k):
    """Thrust shares k_i ω_i² / Σ k_j ω_j² (rows: samples) minus 1/N."""
    t = w2 * k
    return t / t.sum(axis=1, keepdims=True) - 1.0 / w2.shape[1]


def assess(ctx, blocks):
    """(err_without, err_with, row blocks, Interpretation) of the per-motor thrust on ``ctx``'s
    rows (``blocks``: their validation block ids): the share residuals with equal k and with k
    from the other blocks, and the ratios with their block-jackknife errors."""
    n = _motors(ctx.columns)
    w2 = np.column_stack([(np.asarray(ctx.columns[f"rpm{i}"], float) / RPM_SCALE) ** 2
                          for i in range(1, n + 1)])
    blocks = np.asarray(blocks)
    ids = np.unique(blocks)
    sums = np.array([w2[blocks == b].sum(axis=0) for b in ids])
    counts = np.array([np.sum(blocks == b) for b in ids])
    e1 = np.empty_like(w2)
    folds = []
    for j, b in enumerate(ids):
        m = (sums.sum(axis=0) - sums[j]) / (counts.sum() - counts[j])
        e1[blocks == b] = _shares(w2[blocks == b], 1.0 / m)
        folds.append(ratios_from_means(m))
    e0 = _shares(w2, np.ones(n))
    r = ratios_from_means(sums.sum(axis=0) / counts.sum())
    f = np.array(folds)
    nb = f.shape[0]
    se = np.sqrt((nb - 1) / nb * np.sum((f - f.mean(axis=0)) ** 2, axis=0))
    return e0.ravel(), e1.ravel(), np.repeat(blocks, n), _interpret_ratios(r, se)


def _interpret_ratios(r, se) -> Interpretation:
    n = len(r)
    values = {f"motor{i + 1}_ratio": float(r[i]) for i in range(n)}
    values.update({f"motor{i + 1}_ratio_se": float(se[i]) for i in range(n)})
    named = [i + 1 for i in range(n)
             if abs(r[i] - 1) >= MIN_DEVIATION and abs(r[i] - 1) >= Z_NAME * se[i]]
    values["named_motors"] = named
    if named:
        text = "; ".join(f"motor {i} gives {_pct(r[i - 1])} ± {_pct(se[i - 1])} % of the others' "
                         f"thrust: check its {'propeller' if r[i - 1] < 1 else 'propeller size and motor'}"
                         for i in named)
    else:
        text = ("per-motor thrust differs, but no single motor by ≥ 5 % and 3 standard errors "
                "(thrust relative to the others: " + ", ".join(
                    f"{i + 1}: {_pct(r[i])} ± {_pct(se[i])} %" for i in range(n)) + ")")
    return Interpretation(text, values, size=float(np.max(np.abs(np.asarray(r, float) - 1.0))),
                          size_what="the largest motor's thrust differs from the others' by")


def _interpret(coef, base):
    """The fitted weight of the per-motor thrust column (the ratios come from :func:`assess`)."""
    w = coef.get("w", float("nan"))
    return Interpretation(f"thrust weighted per motor (k_i from the torque balance): weight {w:.2f} "
                          "(1 = thrust k_T Σ k_i ω_i²)", {"weight": w})


EFFECT = Effect("motor_thrust", "one thrust coefficient per motor relative to the others (a weak "
                "motor or damaged propeller), from the logged motor speeds and the torque balance",
                ((TILT,), ("rpm1",)), _interpret, expr_fn=_features, constants_fn=_coefficients,
                applicable_fn=_applicable, assess_fn=assess, targets=tuple(TARGETS),
                explain_signal="rpm", order=85)
