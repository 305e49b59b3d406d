"""``fit.quick_fit`` from a start that gives every unknown (a nested model's fit, a cut-off
fit started at the whole record's): the mode is searched from there alone (``warm_modes``),
no multistart, and the posterior is the one the multistart finds."""
from __future__ import annotations

import numpy as np

from physdsl.compile import compile as compile_phys
from physdsl.diagnose.workflow import point_estimate
from physdsl.infer import fit as fit_module
from physdsl.infer.fit import quick_fit

from .conftest import PROJECTILE, PROJECTILE_TIMES, PROJECTILE_TRUTH, simulated_scene


def test_complete_start_skips_the_multistart_and_finds_its_posterior(tmp_path, monkeypatch):
    scene = simulated_scene(tmp_path, PROJECTILE.replace("NOISE", "1 cm"), PROJECTILE_TRUTH,
                            PROJECTILE_TIMES, 0.01, 0)
    model = compile_phys(scene)
    searched = []
    real = fit_module.starts
    monkeypatch.setattr(fit_module, "starts", lambda *a, **k: searched.append(1) or real(*a, **k))
    full = quick_fit(model)
    assert searched == [1]
    start = point_estimate(model, full)
    # a start that leaves an unknown to the prior is a hint: the multistart runs
    quick_fit(model, start={"ball.velocity": start["ball.velocity"]})
    assert searched == [1, 1]
    warm = quick_fit(model, start=start)
    assert searched == [1, 1]  # searched from the start alone
    for name in ("ball.velocity", "linear_drag@ball.coefficient"):
        a = np.asarray(full.posterior[name].values).reshape(-1, *np.shape(start[name]))
        b = np.asarray(warm.posterior[name].values).reshape(a.shape)
        sd = a.std(axis=0)
        np.testing.assert_allclose(b.mean(axis=0), a.mean(axis=0), atol=0.02 * sd.max())
        # 128 Laplace draws: an sd is known to ~6% (the chains' modes differ within the basin)
        np.testing.assert_allclose(b.std(axis=0), sd, rtol=0.15)
