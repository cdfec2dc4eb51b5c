import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from droneid.core.differentiation import DIFFERENTIATORS, get_differentiator
from droneid.errors import ConfigError, DataError


def _err(name, ts, **kw):
    t = np.arange(0.0, 10.0, ts)
    x = np.sin(1.3 * t)
    d = get_differentiator(name, **kw)(x, t)
    truth = 1.3 * np.cos(1.3 * t)
    inner = slice(5, -5)
    return float(np.sqrt(np.nanmean((d[inner] - truth[inner]) ** 2)))


def test_forward_is_first_order_and_central_second_order():
    f1, f2 = _err("forward", 0.05), _err("forward", 0.025)
    c1, c2 = _err("central", 0.05), _err("central", 0.025)
    assert 1.8 < f1 / f2 < 2.2          # O(Ts)
    assert 3.6 < c1 / c2 < 4.4          # O(Ts²)
    # forward: error ≈ Ts/2 · |x''| (RMS of 1.69 sin = 1.195)
    assert f1 == pytest.approx(0.05 / 2 * 1.69 / np.sqrt(2), rel=0.05)
    assert c1 < 1e-3


def test_forward_is_the_papers_and_last_sample_is_nan():
    t = np.array([0.0, 0.05, 0.1, 0.15])
    v = np.array([0.0, 1.0, 3.0, 6.0])
    d = get_differentiator("forward")(v, t)
    np.testing.assert_allclose(d[:-1], [20.0, 40.0, 60.0])
    assert np.isnan(d[-1])


@pytest.mark.parametrize("name", ["savgol", "spline"])
def test_smoothing_differentiators_are_accurate_noise_free(name):
    assert _err(name, 0.01) < 0.01


def test_smoothing_beats_forward_on_noisy_samples():
    rng = np.random.default_rng(1)
    t = np.arange(0.0, 20.0, 0.01)
    x = np.sin(1.3 * t) + rng.normal(0, 0.02, t.size)
    truth = 1.3 * np.cos(1.3 * t)
    errs = {}
    for name in DIFFERENTIATORS:
        d = get_differentiator(name, **({"window_s": 0.5} if name == "spline" else {}))(x, t)
        errs[name] = float(np.sqrt(np.nanmean((d[10:-10] - truth[10:-10]) ** 2)))
    assert errs["savgol"] < 0.1 * errs["forward"]
    assert errs["spline"] < 0.1 * errs["forward"]


@settings(max_examples=40, deadline=None)
@given(a=st.floats(-50, 50), b=st.floats(-50, 50),
       steps=st.lists(st.floats(0.001, 0.2), min_size=6, max_size=40))
def test_linear_signals_are_differentiated_exactly(a, b, steps):
    t = np.concatenate([[0.0], np.cumsum(steps)])
    x = a * t + b
    for name in ("forward", "central", "spline"):
        d = get_differentiator(name)(x, t)
        np.testing.assert_allclose(d[np.isfinite(d)], a, atol=1e-6 * (1 + abs(a) + abs(b)))


@settings(max_examples=30, deadline=None)
@given(c=st.lists(st.floats(-10, 10), min_size=3, max_size=3), h=st.floats(0.005, 0.1),
       n=st.integers(8, 60))
def test_quadratics_exact_for_central_and_savgol(c, h, n):
    t = h * np.arange(n)
    x = c[0] + c[1] * t + c[2] * t * t
    truth = c[1] + 2 * c[2] * t
    tol = 1e-6 * (1 + np.abs(c).sum() * (1 + t[-1]) ** 2)
    np.testing.assert_allclose(get_differentiator("central")(x, t), truth, atol=tol)
    np.testing.assert_allclose(get_differentiator("savgol", window_s=5 * h)(x, t), truth, atol=tol)


def test_registry_and_errors():
    assert set(DIFFERENTIATORS) == {"forward", "central", "savgol", "spline"}
    with pytest.raises(ConfigError, match="did you mean 'savgol'"):
        get_differentiator("savgl")
    with pytest.raises(ConfigError, match="takes no parameter 'window_s'"):
        get_differentiator("forward", window_s=0.2)
    with pytest.raises(ConfigError, match="window_s"):
        get_differentiator("savgol", window_s=-1)
    d = get_differentiator("central")
    with pytest.raises(DataError, match="strictly increasing"):
        d(np.zeros(4), np.array([0.0, 1.0, 1.0, 2.0]))
    with pytest.raises(DataError, match="finite"):
        d(np.array([0.0, np.nan, 1.0]), np.arange(3.0))
    with pytest.raises(DataError, match="at least"):
        d(np.zeros(2), np.arange(2.0))
    with pytest.raises(DataError, match="uniformly spaced"):
        get_differentiator("savgol")(np.zeros(30), np.cumsum(np.r_[0, np.linspace(0.01, 0.02, 29)]))


@pytest.mark.parametrize("method", ["central", "forward"])
def test_a_grid_difference_is_the_mean_of_the_derivative_over_its_window(method):
    """What the thrust-curve stage compares its thrust as (droneid.fitting.command_thrust)."""
    from droneid.core.differentiation import averaging_window, get_differentiator
    ts = 0.05
    t = np.arange(0.0, 2.0, ts)
    x = np.sin(3.0 * t) + t ** 3
    d = get_differentiator(method)(x, t)
    before, after = averaging_window(method, ts)
    k = np.arange(2, t.size - 2)
    mean = (np.sin(3.0 * (t[k] + after)) + (t[k] + after) ** 3 - np.sin(3.0 * (t[k] - before))
            - (t[k] - before) ** 3) / (before + after)
    np.testing.assert_allclose(d[k], mean, rtol=1e-12, atol=1e-12)
    assert averaging_window("savgol", ts) == (0.0, 0.0)
