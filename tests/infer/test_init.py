"""``--init name=value[,name=value]``: start values read like scene values (units, dimension,
shape, support), errors placed under the ``--init`` text (golden files), and the values are
the first start of the fit (CLI and Python)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from physdsl.errors import PhysError

DATA = Path(__file__).parent / "data" / "init"
CASES = sorted(DATA.glob("*.args"))


@pytest.fixture(scope="module")
def thrown():
    from physdsl.syntax import load

    return load(DATA / "thrown.phys")


def test_values_with_units_become_si(thrown):
    from physdsl.infer.init import parse_init

    v = parse_init("ball.velocity=(300, 0, 250) cm/s, linear_drag@ball.coefficient=300 g/s",
                   thrown.unknowns)
    np.testing.assert_allclose(v["ball.velocity"], [3.0, 0.0, 2.5], rtol=1e-15)
    np.testing.assert_allclose(v["linear_drag@ball.coefficient"], 0.3, rtol=1e-15)


def test_names_with_a_comma_are_one_item():
    """Contact effects' unknowns hold a comma (``restitution@floor,ball.coefficient``)."""
    from physdsl.infer.init import parse_init
    from physdsl.syntax import load

    scene = load(Path(__file__).parents[2] / "examples" / "bouncing_ball" / "bouncing_ball.phys")
    v = parse_init("h0=110 cm, restitution@floor,ball.coefficient=0.8", scene.unknowns)
    assert set(v) == {"h0", "restitution@floor,ball.coefficient"}
    assert float(v["h0"]) == pytest.approx(1.1) and float(v["restitution@floor,ball.coefficient"]) == 0.8


def test_python_values_are_checked_like_text(thrown):
    from physdsl.infer.init import start_values

    v = start_values({"ball.velocity": [3.0, 0.0, 2.5], "linear_drag@ball.coefficient": "0.2 kg/s"},
                     thrown.unknowns)
    np.testing.assert_array_equal(v["ball.velocity"], [3.0, 0.0, 2.5])
    assert float(v["linear_drag@ball.coefficient"]) == 0.2
    with pytest.raises(PhysError, match="needs a vector of 3"):
        start_values({"ball.velocity": 3.0}, thrown.unknowns)
    with pytest.raises(PhysError, match="outside the support"):
        start_values({"linear_drag@ball.coefficient": -1.0}, thrown.unknowns)


@pytest.mark.parametrize("case", CASES, ids=lambda p: p.stem)
def test_init_errors_are_located_like_scene_errors(case, cli, tmp_path):
    """Exit 2 before anything compiles, the golden message: place, caret, hint."""
    code, _, err = cli("infer", DATA / "thrown.phys", "-o", tmp_path / "run", "--init",
                       case.read_text().rstrip("\n"))
    assert code == 2
    assert "Traceback" not in err and "internal error" not in err
    assert err.strip() == case.with_suffix(".expected").read_text().strip()
    assert not (tmp_path / "run").exists()  # nothing written


def test_init_is_the_first_start(projectile_model):
    """The given values are where the first optimisation starts (the other starts unchanged)."""
    import jax

    from physdsl.infer.base import Settings
    from physdsl.infer.init import with_init
    from physdsl.infer.run import starts

    settings = with_init(projectile_model, Settings(chains=2, seed=4),
                         {"ball.velocity": "(3.1, 0.2, 4.4) m/s",
                          "linear_drag@ball.coefficient": "250 g/s"})
    assert dict(settings.start) == {"ball.velocity": [3.1, 0.2, 4.4],
                                    "linear_drag@ball.coefficient": 0.25}
    problem, positions = starts(projectile_model, settings, 0)
    first = problem.to_constrained(jax.numpy.asarray(positions[0]), problem.data)
    np.testing.assert_allclose(first["ball.velocity"], [3.1, 0.2, 4.4], rtol=1e-12)
    np.testing.assert_allclose(first["linear_drag@ball.coefficient"], 0.25, rtol=1e-12)
