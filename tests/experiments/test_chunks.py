"""The rollout over recordings in chunks equals one vmap over all of them (memory bounded by
the chunk, results unchanged), zero-size leaves included."""
from __future__ import annotations

import jax.numpy as jnp
import numpy as np

import physdsl
from physdsl import pooled

DATA = __import__("pathlib").Path(__file__).parent / "data"


def test_chunked_map_equals_vmap_with_padding_and_empty_leaves():
    xs = {"a": jnp.arange(5.0), "b": jnp.arange(15.0).reshape(5, 3)}

    def fn(x):
        return {"s": x["a"] * x["b"].sum(), "empty": jnp.zeros((4, 0)) + x["a"]}

    for chunk in (1, 2, 5):
        out = pooled.chunked_map(fn, xs, 5, chunk)
        np.testing.assert_allclose(out["s"], xs["a"] * xs["b"].sum(axis=1))
        assert out["empty"].shape == (5, 4, 0)


def test_rollouts_in_chunks_equal_all_at_once(monkeypatch):
    model = physdsl.compile(DATA / "glob_scene.phys")
    values = {"mass_mu": 0.4, "ball.mass": jnp.array([0.4, 0.42]),
              "ball.position": jnp.array([[0, 0, 1.8], [0, 0, 1.7]]),
              "ball.velocity": jnp.array([[3.0, 0, 3], [5, 0, 5]]),
              "quadratic_drag@ball.coefficient": 0.01}
    monkeypatch.setattr(pooled, "CHUNK", 1)
    one = np.asarray(model.rollouts(values).body_pos)
    monkeypatch.setattr(pooled, "CHUNK", 16)
    both = np.asarray(model.rollouts(values).body_pos)
    np.testing.assert_allclose(one, both, rtol=1e-12)
    assert not np.allclose(both[0], both[1])  # each recording its own launch
    np.testing.assert_allclose(both[:, 0, 0], [[0, 0, 1.8], [0, 0, 1.7]])


def test_log_likelihood_sums_each_recordings_own_terms():
    """The pooled log-likelihood is the sum over recordings of each one's own (its values
    sliced once: a per-recording scalar unknown is read as that recording's)."""
    model = physdsl.compile(DATA / "glob_scene.phys")
    values = {"mass_mu": 0.4, "ball.mass": jnp.array([0.4, 0.42]),
              "ball.position": jnp.array([[0, 0, 1.8], [0, 0, 1.8]]),
              "ball.velocity": jnp.array([[3.0, 0, 3], [5, 0, 5]]),
              "quadratic_drag@ball.coefficient": 0.0}
    ll = model.pointwise_log_likelihood(values, model.predict(values))
    assert set(ll) == {"ball.position[00]", "ball.position[01]"}
    # the data were made as drag-free throws at exactly these launches (rounded to 0.1 mm)
    for v in ll.values():
        assert np.all(np.asarray(v) > 3 * (np.log(1 / (0.01 * np.sqrt(2 * np.pi)))) - 0.01)
