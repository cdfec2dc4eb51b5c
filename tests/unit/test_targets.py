"""The one target table: every module that needs a target's axis, velocity or default inputs
reads it from droneid.core.targets, and the core package never imports parsers or priors."""
import subprocess
import sys

import pytest

from droneid.errors import ConfigError
from droneid.core.targets import HORIZONTAL, TARGETS, axis_of, by_velocity, get_target, state_of, velocity_of


def test_each_target_is_the_derivative_of_its_velocity_along_its_axis():
    for name, t in TARGETS.items():
        assert name == t.name == f"{t.velocity}_dot" and t.velocity == f"v{t.axis}" == state_of(name)
        assert t.position == t.axis and by_velocity(t.velocity) is t
        assert t.paper_inputs[0] == t.velocity
    assert HORIZONTAL == ("vx_dot", "vy_dot")
    assert axis_of("x_dot") is None and velocity_of("x_dot") is None and state_of("x_dot") == "x"


def test_an_unknown_target_is_refused_with_a_hint():
    with pytest.raises(ConfigError, match="did you mean 'vx_dot'"):
        get_target("vx_dt")


def test_the_modules_that_used_their_own_copies_agree_with_the_table():
    from droneid.simulation.rollout import AXES
    from priors.effects import EffectContext
    from priors.constraints import drag_sign
    assert AXES == {t.velocity: (t.name, t.position) for t in TARGETS.values()}
    import numpy as np
    ctx = EffectContext.build("vy_dot", {"vx": np.ones(3), "vy": 2 * np.ones(3)}, np.arange(3.0), np.zeros(3))
    assert ctx.axis == "y" and np.all(ctx.columns["v_axis"] == 2)
    assert all(c.target == "vx_dot" and "vx" in c.domain for c in drag_sign("vx_dot", 2.0))
    with pytest.raises(ConfigError):
        drag_sign("vz_dot", 2.0)


CORE = ("droneid.logs.flight", "droneid.core.frames", "droneid.errors", "droneid.core.numerics", "droneid.core.expressions",
        "droneid.core.io_util", "droneid.core.constraint_samples", "droneid.core.targets", "droneid.core.plugins")


def test_the_core_modules_import_neither_parsers_nor_priors():
    code = ("import sys; import " + ", ".join(CORE) +
            "; print(sorted(m for m in sys.modules if m.split('.')[0] in ('parsers', 'priors')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


def test_a_target_the_prior_does_not_model_is_refused_before_any_work(tmp_path):
    """`--prior tilt-drag --target vz_dot`: one line naming the prior and what it models."""
    from droneid.identify.pipeline import IdentifyConfig
    from droneid.planning.plan import fixed_plan
    with pytest.raises(ConfigError, match="prior 'tilt-drag' has no model of vz_dot; it models vx_dot, vy_dot"):
        fixed_plan(IdentifyConfig.make(prior="tilt-drag", targets=("vz_dot",)))
    plan = fixed_plan(IdentifyConfig.make(prior="auto"))
    assert plan.prior.name == "tilt-drag" and plan.targets == ("vx_dot", "vy_dot")
    assert fixed_plan(IdentifyConfig.make(prior="rotor-thrust")).targets == tuple(TARGETS)


def test_prior_specs_are_told_from_expressions():
    from priors.registry import is_prior_spec
    assert is_prior_spec("tilt-drag") and is_prior_spec("my.toml:quad")
    assert not is_prior_spec("vx*pitch") and not is_prior_spec("a:b") and not is_prior_spec(3)
