"""Sparse regression of a learned force on the dictionary: from forces sampled along a motion
(as the network gives them, with a small error), STLSQ's sparsest support is the true law and
its least-squares coefficients the true ones; a force the library holds is named as such."""
from __future__ import annotations

import jax.numpy as jnp
import numpy as np
import pytest

from physdsl.discover.distil import Samples, supports
from physdsl.discover.terms import body_law, joint_law


def _body(law: dict, seed=0, n=300):
    rng = np.random.default_rng(seed)
    t = np.linspace(0, 2, n)
    v = np.stack([4 + 0 * t, 0.3 * np.sin(t), 20 - 9.81 * t], 1)  # a throw: speeds 0-21 m/s
    x = np.stack([4 * t, 0.1 * t, 20 * t - 4.9 * t ** 2], 1) + np.array([-1.0, 0.0, 0.4])
    f = np.asarray(body_law(law, jnp.asarray(v), jnp.asarray(x)))
    f = f + 0.002 * np.sqrt(np.mean(f ** 2)) * rng.standard_normal(f.shape)
    return Samples("body", v, x, f)


def _joint(law: dict, seed=0, n=300):
    rng = np.random.default_rng(seed)
    t = np.linspace(0, 3, n)
    q, qd = 1.2 * np.cos(3.4 * t), -1.2 * 3.4 * np.sin(3.4 * t)
    f = np.asarray(joint_law(law, jnp.asarray(q), jnp.asarray(qd)))
    f = f + 0.002 * np.sqrt(np.mean(f ** 2)) * rng.standard_normal(f.shape)
    return Samples("hinge", q, qd, f)


@pytest.mark.parametrize("samples, law", [
    (_body, {"v_sqrt_speed": -0.012}),
    (_body, {"d_inv2": -0.03}),
    (_joint, {"q3": -4.0}),
    (_joint, {"q3": -4.0, "qdot": -0.05}),
    (_body, {"v_speed": -0.004}),  # quadratic drag: a law the library holds
])
def test_the_sparsest_support_is_the_true_law(samples, law):
    found = supports(samples(law))
    best = next(s for s in found if s.unexplained < 1e-3)
    assert set(best.terms) == set(law)
    assert all(len(s.terms) >= len(law) for s in found if s.unexplained < 1e-3)
    for t, c in law.items():
        assert best.coefficients[t] == pytest.approx(c, rel=0.01)


def test_one_term_fits_are_all_offered_sparsest_first():
    found = supports(_body({"v_sqrt_speed": -0.012}))
    sizes = [len(s.terms) for s in found]
    assert sizes == sorted(sizes)
    assert {s.terms[0] for s in found if len(s.terms) == 1} == {
        "v", "v_sqrt_speed", "v_speed", "v_speed2", "d", "d_norm", "d_inv", "d_inv2"}
