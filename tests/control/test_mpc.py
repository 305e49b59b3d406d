"""Adaptive MPC on a cart-pole (issue 17 item 3): iLQR over the scene's horizon, the pole's mass
and the rail's damping refitted from the transitions seen; MuJoCo is the plant (its pole
0.3 kg, +50% on the prior mean of 0.2 kg; rail damping 0.4 N s/m). Nothing reads the plant's
parameters: the controller gets observations only. Short runs here; longer ones -m slow."""
from __future__ import annotations

from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import physdsl
from physdsl.cli import main
from physdsl.control import mpc, mpc_files, terminal
from physdsl.control.refit import Memory
from physdsl.control.transition import build_transition
from physdsl.errors import ModelError

mujoco = pytest.importorskip("mujoco")
from physdsl.control.mujoco_plant import MujocoPlant  # noqa: E402

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "control_cartpole"
SCENE, PLANT = EXAMPLE / "cartpole.phys", EXAMPLE / "plant.xml"
TRUE_MASS, TRUE_DAMPING = 0.3, 0.4  # the plant's (plant.xml): used by the asserts only
TILT = 0.05  # rad from upright at the start


def plant(tilt: float = TILT) -> MujocoPlant:
    return MujocoPlant(str(PLANT), period=0.02, initial={"pole_hinge": np.pi + tilt})


@pytest.fixture(scope="module")
def controller():
    return mpc.Controller(physdsl.compile(SCENE))


@pytest.fixture(scope="module")
def closed_loop(controller):
    """One second of plant time (50 periods), refits every 10."""
    return mpc.run(controller.transition.model, plant(), 1.0, refit_every=10,
                   controller=controller)


# one second of closed-loop MPC with refits (~70 s); the controller's parts: the tests below
@pytest.mark.slow
def test_balance_held_and_mass_refitted(closed_loop):
    """The pole stays within the goal's 0.1 rad of upright while the refitted pole mass moves
    from the prior's centre to within a quarter of its first error of the plant's."""
    r = closed_loop
    angle = r.states[:, r.joints.index("pole_hinge")]
    assert np.max(np.abs(angle - np.pi)) <= 0.1
    assert abs(angle[-1] - np.pi) < 0.02  # brought back up, not merely not fallen
    assert r.held()
    mass = [e["values"]["pole.mass"] for e in r.estimates]
    first, last = abs(mass[0] - TRUE_MASS), abs(mass[-1] - TRUE_MASS)
    assert first > 0.08  # the controller starts wrong (the prior's centre)
    assert last < 0.25 * first
    sd = r.estimates[-1]["sd"]["pole.mass"]
    assert last < 3 * sd  # the Laplace interval covers the plant's mass
    assert np.all(np.abs(r.forces) <= 10.0 + 1e-9)  # the control prior's bounds


def test_refit_schedule():
    """Regular refits every ``refit_every`` transitions, early ones where asked, none at 0."""
    due = [k for k in range(1, 31) if mpc.refit_due(k, 10, (1, 2, 5))]
    assert due == [1, 2, 5, 10, 20, 30]
    assert not any(mpc.refit_due(k, 0, (1, 2)) for k in range(1, 31))


def test_early_refits_fit_every_transition_so_far(controller):
    """Refits after 2 and 5 transitions, then the regular one at 10: each early refit fits every
    transition so far under the scene's prior, so the one at 10 is the MAP of all ten under the
    scene's prior (the same as without early refits), found again here from the prior's centre;
    the early estimates already move the pole's mass toward the plant's."""
    tr = controller.transition
    r = mpc.run(tr.model, plant(), 0.2, refit_every=10, early=(2, 5), controller=controller)
    assert [e["step"] for e in r.estimates] == [0, 2, 5, 10]
    memory = Memory.empty(tr.nx, tr.nu)
    for x, u, x_next in zip(r.states[:-1], r.forces, r.states[1:]):
        memory.add(x, u, x_next)
    z0 = jnp.asarray(tr.centre[tr.index])
    z, _ = controller.fit(z0, memory.x, memory.u, memory.x_next, memory.mask, z0,
                          jnp.eye(len(z0)), 1.0)
    again = {n: float(np.ravel(v)[0]) for n, v in tr.physical_values(z).items()}
    assert np.allclose(list(again.values()), list(r.estimates[-1]["values"].values()),
                       rtol=1e-3), (again, r.estimates[-1]["values"])
    mass = [e["values"]["pole.mass"] for e in r.estimates]
    assert abs(mass[2] - TRUE_MASS) < 0.5 * abs(mass[0] - TRUE_MASS), mass


def test_terminal_cost_is_the_lqr_cost_to_go(controller):
    """The goal (pole upright, cart at 0) is an equilibrium, so the horizon's terminal cost is
    the LQR cost-to-go of the model linearised there: its gain holds the linearised pole, which
    falls without it, and iLQR's first force from a small tilt over the 0.5 s horizon is the
    LQR's (the horizon plus the cost-to-go is the infinite horizon: a terminal cost off by a
    factor, or the stage cost's 10-step weight, gives another force)."""
    tr, eq = controller.transition, controller.equilibrium
    assert eq is not None
    z = jnp.asarray(tr.centre[tr.index])
    P, fallback = controller.terminal(z)
    assert float(fallback) == 0.0
    _, w = terminal.value_matrix(eq, z, tr.nu)
    K = terminal.lqr_gain(eq, z, np.asarray(P), w)
    _, A, B, *_ = (np.asarray(a) for a in eq.linearise(z, jnp.asarray(w)))
    assert np.max(np.abs(np.linalg.eigvals(A))) > 1.05  # upright falls
    assert np.max(np.abs(np.linalg.eigvals(A - B @ K))) < 0.999  # LQR holds it
    x0 = eq.x.copy()
    x0[tr.joints.index("pole_hinge")] += 2e-3
    W, X = jnp.zeros((tr.horizon, tr.nu)), jnp.tile(jnp.asarray(x0), (tr.horizon + 1, 1))
    for _ in range(4):
        W, X, _ = controller.plan(jnp.asarray(x0), W, X, z, (P, fallback), controller.iterations)
    lqr = w - K @ np.asarray(terminal.error(eq, jnp.asarray(x0)))
    assert abs(float(lqr[0])) > 0.01  # a force worth comparing
    assert np.allclose(np.asarray(W[0]), lqr, rtol=0.02), (W[0], lqr)


def test_transition_matches_mujoco_at_the_plants_values(controller):
    """The model's one-period step, at the plant's mass and damping, follows MuJoCo over 0.5 s
    of pushes (so the refit has something true to converge to)."""
    tr = controller.transition
    z = jnp.array([np.log(TRUE_MASS), np.log(TRUE_DAMPING)])  # log_normal, half_normal: exp
    assert np.allclose([float(v) for v in tr.physical_values(z).values()],
                       [TRUE_MASS, TRUE_DAMPING])
    prm, f = tr.params(z), jax.jit(tr.step)
    p = plant(0.3)
    obs = p.reset()
    x = controller.state(obs)
    for k in range(25):
        u = 3.0 * np.sin(0.3 * k)
        obs = p.step({"cart_slider": u})
        x = f(prm, x, jnp.array([u]))
    assert np.allclose(np.asarray(x), controller.state(obs), atol=2e-3)


@pytest.mark.slow  # the closed loop above
def test_files_written(closed_loop, tmp_path):
    out = mpc_files.write(closed_loop, tmp_path / "run", settings={"plant": "plant.xml"})
    rows = (out / "trajectory.csv").read_text().splitlines()
    assert rows[0].startswith("t,cart_slider.position,pole_hinge.position")
    assert len(rows) == 1 + 51
    est = (out / "estimates.csv").read_text().splitlines()
    assert len(est) == 1 + 6 and est[0].startswith("step,t,pole.mass,pole.mass.sd")
    with pytest.raises(Exception, match="not empty"):
        mpc_files.write(closed_loop, out)


def test_a_scene_without_goal_is_refused():
    text = SCENE.read_text()
    start = text.index("  goal {")
    no_goal = text[:start] + text[text.index("}\n", start) + 2:]
    with pytest.raises(ModelError, match="mpc needs a goal"):
        mpc.goal_terms(physdsl.compile(no_goal))


def test_a_scene_without_unknown_control_is_refused():
    text = SCENE.read_text().replace("values ~ uniform(-10 N, 10 N)", "values: " + ", ".join(
        ["(0"] + ["0"] * 24) + ") N")
    with pytest.raises(ModelError, match="no unknown control sequence"):
        build_transition(physdsl.compile(text))


@pytest.mark.parametrize("args, message", [
    (["--plant", "missing.xml"], "not found"),
    (["--plant", "nonsense"], "neither an MJCF file"),
    (["--plant", str(PLANT), "--initial", "pole_hinge"], "cannot read"),
])
def test_cli_usage_errors(tmp_path, capsys, args, message):
    code = main(["mpc", str(SCENE), "-o", str(tmp_path / "out"), *args])
    assert code == 2
    assert message in capsys.readouterr().err


@pytest.mark.slow
def test_cli_closed_loop_with_and_without_refits(tmp_path, capsys):
    """5 s of balance through the command line (exit 0, files), the refitted mass within 10% of
    the plant's; the same run without refits keeps the prior's centre throughout."""
    code = main(["mpc", str(SCENE), "--plant", str(PLANT), "-o", str(tmp_path / "a"),
                 "--duration", "5", "--initial", f"pole_hinge={np.pi + 0.08}"])
    assert code == 0, capsys.readouterr().err
    import json
    summary = json.loads((tmp_path / "a" / "mpc.json").read_text())
    assert summary["held"] and summary["hold_errors"]["pole_hinge"]["max_error"] <= 0.1
    assert abs(summary["final_estimates"]["pole.mass"] - TRUE_MASS) < 0.1 * TRUE_MASS
    code = main(["mpc", str(SCENE), "--plant", str(PLANT), "-o", str(tmp_path / "b"),
                 "--duration", "5", "--refit-every", "0", "--initial", f"pole_hinge={np.pi + 0.08}"])
    fixed = json.loads((tmp_path / "b" / "mpc.json").read_text())
    assert abs(fixed["final_estimates"]["pole.mass"] - TRUE_MASS) > 0.08
