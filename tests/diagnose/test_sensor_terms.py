"""Sensor terms of an observation (offset, gain, delay): parsed, printed back, checked, and
fitted like any unknown (physdsl-simulated data with a known offset and gain)."""
from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from physdsl.errors import PhysError
from physdsl.observe.sensor import delayed
from physdsl.syntax import edit, format_source

from .conftest import PENDULUM, fit, interval, load_scene, write_csv

# the encoder's angle, and the bob's position from a camera (unbiased): the physics is pinned
# down by the positions, the sensor terms by the difference
SHORT = PENDULUM.replace("timestep: 10 ms", "timestep: 20 ms").replace(
    "  observe hinge.angle", '  observe bob.position from "bob.csv" where body == "bob" { noise: 2 mm }\n'
    "  observe hinge.angle")
TIMES = np.linspace(0.0, 2.0, 51)


def _placeholders(folder):
    write_csv(folder / "joints.csv", TIMES, np.zeros((51, 1)), "hinge")
    write_csv(folder / "bob.csv", TIMES, np.zeros((51, 3)), "bob")


def _with_terms(text: str, **terms) -> str:
    for k, v in terms.items():
        text = edit.replace_value(text, f"hinge.angle.{k}", v)
    return text


def test_printer_round_trips_the_sensor_terms(tmp_path):
    text = _with_terms(SHORT, offset="~ normal(0 rad, 0.1 rad)", gain="~ normal(1, 0.1)",
                       delay="5 ms")
    assert "offset ~ normal(0 rad, 0.1 rad)" in text and "delay: 5 ms" in text
    assert format_source(text) == text
    _placeholders(tmp_path)
    scene = load_scene(tmp_path, text)
    s = next(o for o in scene.observations if o.name == "hinge.angle").sensor
    assert {u.name for u in scene.unknowns} >= {"hinge.angle.offset", "hinge.angle.gain"}
    assert float(s.delay.array()) == pytest.approx(0.005)


@pytest.mark.parametrize("field, value, words", [
    ("offset", "(1, 2) rad", "one per axis"), ("gain", "-1", "positive"),
    ("offset", "2 m", "unit"), ("delay", "3 rad", "unit")])
def test_bad_sensor_terms_are_clear_errors(tmp_path, field, value, words):
    _placeholders(tmp_path)
    with pytest.raises(PhysError) as ex:
        load_scene(tmp_path, _with_terms(SHORT, **{field: value}))
    assert words in str(ex.value).lower() or words in ex.value.render().lower()


def test_delayed_reading_matches_interpolation_and_its_gradient():
    jax.config.update("jax_enable_x64", True)
    grid = np.arange(0, 101) * 0.01
    track = jnp.asarray(np.stack([np.sin(3 * grid), grid ** 2], axis=1))
    times = np.linspace(0.05, 0.95, 37)
    got = np.asarray(delayed(track, grid, times, 0.0123))
    want = np.stack([np.interp(times - 0.0123, grid, np.asarray(track[:, a])) for a in range(2)], 1)
    np.testing.assert_allclose(got, want, atol=1e-12)
    f = lambda d: jnp.sum(delayed(track, grid, times, d) ** 2)  # noqa: E731
    h = 1e-6
    fd = (f(0.0123 + h) - f(0.0123 - h)) / (2 * h)
    assert float(jax.grad(f)(0.0123)) == pytest.approx(float(fd), rel=1e-5)


@pytest.mark.slow  # a MAP fit (~30 s); the terms' reading and gradient: the tests above
def test_map_recovers_a_known_offset_and_gain(tmp_path):
    from physdsl.compile import Model

    text = _with_terms(SHORT, offset="~ normal(0 rad, 0.1 rad)", gain="~ normal(1, 0.1)")
    _placeholders(tmp_path)
    truth = {"hinge.initial": np.array(0.7), "hinge.angle.offset": np.array(0.05),
             "hinge.angle.gain": np.array(1.1)}
    clean = Model(load_scene(tmp_path, text)).predict(truth)
    rng = np.random.default_rng(0)
    for key, file, name, sd in (("hinge.angle", "joints.csv", "hinge", 0.003),
                                ("bob.position", "bob.csv", "bob", 0.002)):
        c = np.asarray(clean[key])
        write_csv(tmp_path / file, TIMES, c + rng.normal(0.0, sd, c.shape), name)
    idata = fit(Model(load_scene(tmp_path, text)))
    for name, v in truth.items():
        lo, hi = interval(idata, name, (0.005, 0.995))
        assert lo <= float(v) <= hi, (name, lo, hi)
    lo, hi = interval(idata, "hinge.angle.offset")
    assert hi - lo < 0.01  # the data pin the offset down (its prior sd is 0.1 rad)
