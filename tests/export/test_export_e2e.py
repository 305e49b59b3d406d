"""Export end to end: a posterior becomes a program that lints, is fmt-stable, and whose
prior reproduces the posterior's means, sds and correlations (synthetic posteriors)."""
from __future__ import annotations

import json
from pathlib import Path

import jax
import numpy as np
import pytest

from physdsl import syntax
from physdsl.compile import compile_scene
from physdsl.errors import PhysError, UsageError
from physdsl.export import export
from physdsl.infer import posterior_data
from physdsl.sample import parameter_values

DATA = Path(__file__).resolve().parent / "data"
TOSS = DATA / "toss.phys"
N = 10000


def _toss_posterior(seed=0, chains=4, draws=500, corr=-0.7):
    """Draws with known unconstrained mean/cov: log mass, h0, velocity (3,), log drag."""
    rng = np.random.default_rng(seed)
    mean = np.array([np.log(0.4), 1.2, 2.0, 0.0, 3.0, np.log(0.004)])
    sd = np.array([0.05, 0.01, 0.03, 0.02, 0.03, 0.2])
    c = np.eye(6)
    c[0, 1] = c[1, 0] = corr       # mass and height
    c[2, 4] = c[4, 2] = 0.5        # vx and vz
    y = rng.multivariate_normal(mean, c * np.outer(sd, sd), (chains, draws))
    post = {"ball.mass": np.exp(y[..., 0]), "h0": y[..., 1], "ball.velocity": y[..., 2:5],
            "quadratic_drag@ball.coefficient": np.exp(y[..., 5])}
    return posterior_data.from_dict({"posterior": post}, dims={"ball.velocity": ["axis"]}), post


def _flat(post):
    return {k: v.reshape(-1, *v.shape[2:]) for k, v in post.items()}


def _columns(values):
    cols, names = [], []
    for k, v in values.items():
        v = np.asarray(v).reshape(len(v), -1)
        for i in range(v.shape[1]):
            cols.append(v[:, i])
            names.append(f"{k}[{i}]" if v.shape[1] > 1 else k)
    return names, np.stack(cols, 1)


def _write(tmp_path, text, name="proto.phys"):
    out = tmp_path / name
    out.write_text(text)
    return out


def _proto(tmp_path, scene, idata, name="proto.phys", **kw):
    """Export ``scene``'s posterior to ``tmp_path/name``; returns the path."""
    out = tmp_path / name
    out.write_text(export(scene, idata, out_path=out, **kw))
    return out


def _draw_parameters(path, n=N, seed=0):
    scene = syntax.load(path)
    model = compile_scene(scene)
    draws = model.sample_prior(jax.random.PRNGKey(seed), n)
    module = syntax.parse(Path(path).read_text(), str(path))
    params = parameter_values(module, draws, {u.name: u.unit for u in scene.unknowns})
    return {k: v for k, (v, _) in params.items()}


def test_export_lints_is_fmt_stable_and_reproduces_the_posterior(tmp_path):
    idata, post = _toss_posterior()
    out = tmp_path / "sub" / "proto.phys"
    text = export(TOSS, idata, out_path=out)
    out.parent.mkdir()
    out.write_text(text)
    assert syntax.format_source(text) == text
    scene = syntax.load(out)  # resolves from its new place: data paths were rebased
    assert len(scene.observations) == 2
    assert "proto_z1" in text and "r-hat max" in text
    drawn = _draw_parameters(out)
    names, a = _columns(_flat(post))
    names_b, b = _columns({k: drawn[k] for k in _flat(post)})
    assert names == names_b
    sd = a.std(0)
    se = sd * np.sqrt(1 / len(a) + 1 / len(b))
    assert np.all(np.abs(a.mean(0) - b.mean(0)) < 5 * se), (a.mean(0), b.mean(0))
    np.testing.assert_allclose(b.std(0), sd, rtol=0.05)
    np.testing.assert_allclose(np.corrcoef(b.T), np.corrcoef(a.T), atol=0.05)
    assert np.corrcoef(b.T)[0, 1] < -0.6  # mass-height correlation kept


def test_small_correlations_give_independent_readable_distributions(tmp_path):
    idata, post = _toss_posterior(corr=0.0)
    proto = _proto(tmp_path, TOSS, idata)
    text = proto.read_text()
    assert "mass ~ log_normal(" in text and "coefficient ~ log_normal(" in text
    # the correlated velocity components stay one block; h0 (a param in metres) is written
    # through a standard normal because log-space/unitless distributions cannot carry a unit
    assert "h0 ~ normal(" in text
    drawn = _draw_parameters(proto)
    np.testing.assert_allclose(drawn["ball.mass"].std(), _flat(post)["ball.mass"].std(), rtol=0.05)


def test_support_respected_in_10000_draws(tmp_path):
    text = TOSS.read_text().replace(
        "  effect quadratic_drag on ball { coefficient ~ half_normal(0.01 kg/m) }",
        "  effect quadratic_drag on ball { coefficient ~ uniform(0 kg/m, 0.02 kg/m) }")
    scene_path = _write(tmp_path, text, "toss.phys")
    (tmp_path / "toss.csv").write_text((DATA / "toss.csv").read_text())
    rng = np.random.default_rng(3)
    for corr in (0.8, 0.0):
        # tiny masses and a drag coefficient crowding its upper bound, widened 3x
        y = rng.multivariate_normal([np.log(0.01), 3.0], [[1.0, corr], [corr, 1.0]], (2, 1000))
        post = {"ball.mass": np.exp(y[..., 0]), "h0": rng.normal(1.2, 0.01, (2, 1000)),
                "ball.velocity": rng.normal([2, 0, 3], 0.03, (2, 1000, 3)),
                "quadratic_drag@ball.coefficient": 0.02 / (1 + np.exp(-y[..., 1]))}
        idata = posterior_data.from_dict({"posterior": post}, dims={"ball.velocity": ["axis"]})
        proto = _proto(tmp_path, scene_path, idata, f"proto{corr}.phys", widen=3.0)
        drawn = _draw_parameters(proto)
        assert len(drawn["ball.mass"]) == N
        assert np.all(drawn["ball.mass"] > 0)
        c = drawn["quadratic_drag@ball.coefficient"]
        assert np.all((c >= 0) & (c <= 0.02))
        if corr == 0.0:
            assert "truncated_normal(" in proto.read_text()


def test_widen_inflates_the_spread(tmp_path):
    idata, post = _toss_posterior()
    narrow = _draw_parameters(_proto(tmp_path, TOSS, idata, "a.phys"), n=4000)
    wide = _draw_parameters(_proto(tmp_path, TOSS, idata, "b.phys", widen=2.0), n=4000)
    ratio = wide["h0"].std() / narrow["h0"].std()
    assert 1.85 < ratio < 2.15


def test_free_keeps_the_original_prior():
    idata, _ = _toss_posterior()
    text = export(TOSS, idata, free=["quadratic_drag@ball.coefficient"])
    assert "coefficient ~ half_normal(0.01 kg/m)" in text
    with pytest.raises(UsageError, match="--free nothing"):
        export(TOSS, idata, free=["nothing"])


def test_drop_body_removes_it_and_what_depends_on_it(tmp_path):
    idata, _ = _toss_posterior()
    scene = syntax.load(_proto(tmp_path, TOSS, idata, drop=["marker"]))
    assert [b.name for b in scene.bodies] == ["ball"]
    assert [o.target for o in scene.observations] == ["ball"]
    proto = _proto(tmp_path, TOSS, idata, "d.phys", drop=["ball"])
    body = proto.read_text().split("scene toss")[1].replace("# release height of the ball", "")
    assert "ball" not in body and "quadratic_drag" not in body
    scene = syntax.load(proto)  # lints
    assert [b.name for b in scene.bodies] == ["marker"]
    assert [o.target for o in scene.observations] == ["marker"]


def test_drop_with_a_remaining_reference_names_both_places(tmp_path):
    text = TOSS.read_text().replace("    position: (0.5, 0, 1) m",
                                    "    position: ball.position + (0.5, 0, -0.2) m")
    scene_path = _write(tmp_path, text, "toss.phys")
    (tmp_path / "toss.csv").write_text((DATA / "toss.csv").read_text())
    idata, _ = _toss_posterior()
    with pytest.raises(PhysError) as err:
        export(scene_path, idata, drop=["ball"])
    msg = err.value.render()
    assert "'ball.position' in body marker refers to body ball" in msg
    assert msg.count("toss.phys:") >= 2  # the reference's place and the declaration's


def test_no_observe_is_a_pure_generator(tmp_path):
    idata, _ = _toss_posterior()
    proto = _proto(tmp_path, TOSS, idata, observe=False)
    text = proto.read_text()
    scene = syntax.load(proto)
    assert not scene.observations and scene.duration == pytest.approx(0.5)
    assert "observe" not in text.replace("no observations", "")
