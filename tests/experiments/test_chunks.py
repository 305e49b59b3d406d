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
