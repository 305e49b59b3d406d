"""Checkpoints: a run interrupted between blocks and resumed yields exactly the draws of an
uninterrupted run with the same seed; a checkpoint from other settings is refused."""
from __future__ import annotations

import physdsl

import numpy as np
import pytest

from physdsl.errors import UsageError
from physdsl.infer import get_backend

# the default block (100) as in the recovery tests, so the compiled block is shared; three
# blocks of draws (100, 100, 50), the run interrupted in the second
SETTINGS = dict(backend="nuts", chains=2, warmup=60, samples=250, seed=11, progress=False)


def _interrupt_on_block(monkeypatch, backend: str, block: int):
    """Make ``backend``'s ``sample`` raise KeyboardInterrupt on its ``block``-th call (1-based)."""
    algo = get_backend(backend)
    real = algo.sample
    calls = {"n": 0}

    def sample(*args, **kwargs):
        calls["n"] += 1
        if calls["n"] == block:
            raise KeyboardInterrupt
        return real(*args, **kwargs)

    monkeypatch.setattr(algo, "sample", sample)
    return calls


def test_interrupt_and_resume_gives_the_same_draws(projectile_model, tmp_path, monkeypatch):
    reference = physdsl.infer(projectile_model, outdir=tmp_path / "reference", **SETTINGS)

    out = tmp_path / "interrupted"
    calls = _interrupt_on_block(monkeypatch, "nuts", 2)
    with pytest.raises(KeyboardInterrupt):
        physdsl.infer(projectile_model, outdir=out, **SETTINGS)
    assert calls["n"] == 2
    assert (out / "checkpoint.pkl").exists() and not (out / "posterior.nc").exists()
    monkeypatch.undo()

    resumed = physdsl.infer(projectile_model, outdir=out, resume=True, **SETTINGS)
    assert (out / "posterior.nc").exists() and not (out / "checkpoint.pkl").exists()
    for name in projectile_model.unknown_names:
        np.testing.assert_array_equal(resumed.posterior[name].values, reference.posterior[name].values)
    for stat in reference.sample_stats.data_vars:
        np.testing.assert_array_equal(resumed.sample_stats[stat].values,
                                      reference.sample_stats[stat].values)
    np.testing.assert_array_equal(resumed.log_likelihood["obs:ball.position"].values,
                                  reference.log_likelihood["obs:ball.position"].values)


def test_resume_refuses_a_checkpoint_of_other_settings(projectile_model, tmp_path, monkeypatch):
    out = tmp_path / "run"
    _interrupt_on_block(monkeypatch, "nuts", 1)
    with pytest.raises(KeyboardInterrupt):
        physdsl.infer(projectile_model, outdir=out, **SETTINGS)
    monkeypatch.undo()
    with pytest.raises(UsageError, match="another scene, data or settings"):
        physdsl.infer(projectile_model, outdir=out, resume=True, **{**SETTINGS, "seed": 12})

