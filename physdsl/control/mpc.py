"""Model-predictive control that refits itself (``physdsl mpc``): iLQR over the scene's horizon
from the plant's observed state at every control period, the first planned force applied, the
plan shifted and kept as the next warm start; every ``refit_every`` periods the physical
unknowns are refitted (MAP, ``refit.map_fit``) from the transitions seen since the last
refit with the last refit's Laplace approximation as prior, and the next plans use them. Nothing reads the plant's parameters: only its observations.

The scene's goal is the cost: each ``hold`` term (``JOINT.angle from .. to .. -> VALUE within
TOL``) is a stage cost ``(e / TOL)^2`` averaged over the horizon (``e = q - VALUE`` for a slider,
the chord ``2 sin((q - VALUE) / 2)`` for a hinge: the same near VALUE, periodic in the angle), the horizon's end
weighing ``TERMINAL`` steps more (it stands for the future beyond the horizon) or, where the
goal is an equilibrium (every joint held) and the state is near it (every hinge within
``NEAR``), the LQR cost-to-go there (``terminal.py``, recomputed after each refit), plus the
effort ``weight * u^2 * period``. Forces are planned in the control prior's unconstrained space,
so they stay within its bounds (``uniform(-10 N, 10 N)``).
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import jax
import jax.numpy as jnp
import numpy as np

from ..compile import Model
from ..errors import ModelError, UsageError
from ..goal import Effort, Hold
from . import ilqr, terminal
from .plant import Observation, Plant
from .refit import CAPACITY, Memory, constrained_sd, map_fit
from .transition import Transition, build_transition, control_bounds

ITERATIONS = 1  # iLQR iterations per control period (warm-started from the shifted plan)
FIRST_ITERATIONS = 10  # before the first force: a cold plan
TERMINAL = 10.0  # without an LQR terminal cost, the horizon's last state weighs this many steps
NEAR = 0.5  # largest hinge chord from the goal's equilibrium where the LQR cost-to-go is the
# terminal cost: its quadratic is the model linearised there; far from it (a pole hanging
# below a swing-up's goal) it charges a pumping swing's speed as if it were an upright's
# error, and no pump beats standing still (measured: energy 2.5e-5 after 0.5 s against 0.34)
REFIT_EVERY = 10  # control periods between refits
EFFORT_FLOOR = 1e-6  # per N^2 s: keeps the control Hessian positive without an effort term
PUMP_PERIODS = (0.6, 0.9, 1.2, 1.6, 2.0)  # s: sine pushes screened before each solve
PUMP_AMPLITUDES = (1.0, 2.5)  # unconstrained units (uniform(-10 N, 10 N): 4.6 N, 8.5 N)
TAIL = 1e-3  # per unconstrained control squared per step: keeps plans out of the bounds' flat tails


@dataclass
class MpcResult:
    """A closed-loop run: states, forces, estimates over time and the time each step took."""

    joints: tuple[str, ...]
    targets: tuple[str, ...]
    times: np.ndarray  # (T + 1,) s
    states: np.ndarray  # (T + 1, 2J): coordinates then velocities
    forces: np.ndarray  # (T, nu) N (or N m)
    step_ms: np.ndarray  # (T,) wall time of each plan
    estimates: list[dict] = field(default_factory=list)  # t, step, values, sd, refit_ms
    holds: tuple[Hold, ...] = ()
    cost: float = 0.0  # the goal's stage cost summed over the run
    hinges: tuple[bool, ...] = ()  # per joint: its coordinate is a periodic angle
    final_z: np.ndarray | None = None  # the last estimate, in the prior's unconstrained space
    step_cpu_ms: np.ndarray | None = None  # (T,) the process's CPU time of each plan

    def hold_errors(self, settle: float = 0.0) -> list[float]:
        """Each hold term's largest error (its unit) from ``settle`` s to the end."""
        after = self.times >= settle - 1e-12
        out = []
        for term in self.holds:
            j = self.joints.index(term.joint)
            d = self.states[after, j] - term.value
            if self.hinges and self.hinges[j]:  # an angle: the nearest turn
                d = np.mod(d + np.pi, 2 * np.pi) - np.pi
            out.append(float(np.max(np.abs(d))))
        return out

    def held(self, settle: float = 0.0) -> bool:
        """Whether every hold term stayed within its tolerance from ``settle`` s on."""
        return all(e <= t.within for t, e in zip(self.holds, self.hold_errors(settle)))


def goal_costs(transition: Transition, holds, weight: float, squash):
    """(stage(x, w), miss(x)) of the goal's hold and effort terms over one horizon: the stage
    cost and its hold part (``TERMINAL * miss`` is the fallback terminal cost)."""
    columns = jnp.asarray([transition.joints.index(h.joint) for h in holds], dtype=int)
    targets = jnp.asarray([h.value for h in holds])
    tolerance = jnp.asarray([h.within for h in holds])
    hinge = jnp.asarray([transition.hinges[transition.joints.index(h.joint)] for h in holds])
    per_step = 1.0 / (transition.horizon + 1)

    def miss(x):
        d = x[columns] - targets
        e = jnp.where(hinge, 2.0 * jnp.sin(0.5 * d), d)
        return jnp.sum((e / tolerance) ** 2) * per_step

    def stage(x, w):
        u = squash(w)
        return (miss(x) + max(weight, EFFORT_FLOOR) * jnp.sum(u ** 2) * transition.period
                + TAIL * jnp.sum(w ** 2))

    return stage, miss


def goal_terms(model: Model) -> tuple[tuple[Hold, ...], float]:
    """The scene goal's hold terms and its effort weight (a reach term is refused)."""
    goal = model.scene.goal
    if goal is None:
        raise ModelError("mpc needs a goal: the scene has no `goal { ... }` block",
                         hint="e.g. `goal { pole_hinge.angle from 0 s to 500 ms -> 180 deg "
                              "within 0.1 rad  effort: 1e-3 }`")
    holds = tuple(t for t in goal.terms if isinstance(t, Hold))
    other = [t for t in goal.terms if not isinstance(t, (Hold, Effort))]
    if other or not holds:
        raise ModelError("mpc keeps joints near values: its goal takes `JOINT.angle ... -> VALUE "
                         "within TOL` and `effort:` terms", span=(other[0].span if other
                                                                   else goal.span),
                         hint="reach a point open-loop with `physdsl control`")
    return holds, sum(t.weight for t in goal.terms if isinstance(t, Effort))


def pumping_plans(horizon: int, period: float, nu: int) -> np.ndarray:
    """Candidate plans (C, horizon, nu) screened against the warm plan before each iLQR solve
    (``Controller(screen=True)``), in the controls' unconstrained space: each control alone pushing as a sine of each of ``PUMP_PERIODS`` s
    and ``PUMP_AMPLITUDES``, both signs (the pushes that pump energy into a swing)."""
    t = period * np.arange(horizon)
    plans = []
    for j in range(nu):
        for p in PUMP_PERIODS:
            for a in PUMP_AMPLITUDES:
                for sign in (1.0, -1.0):
                    w = np.zeros((horizon, nu))
                    w[:, j] = sign * a * np.sin(2 * np.pi * t / p)
                    plans.append(w)
    return np.asarray(plans)


class Controller:
    """The compiled pieces of one scene's MPC: planner, refit, state reader."""

    def __init__(self, model: Model, iterations: int = ITERATIONS, screen: bool = True,
                 lqr: bool = True):
        self.transition = tr = build_transition(model)
        self.holds, weight = goal_terms(model)
        self.squash = control_bounds(model, tr.controls)
        stage, miss = goal_costs(tr, self.holds, weight, self.squash)
        self.stage = jax.jit(stage)
        self.equilibrium = terminal.equilibrium(tr, self.holds, stage, self.squash) if lqr else None

        candidates = jnp.asarray(pumping_plans(tr.horizon, tr.period, tr.nu))

        def dynamics(z):
            prm = tr.params(z)
            return lambda x, w: tr.step(prm, x, self.squash(w))

        def final_cost(P, fallback):
            """0.5 e^T P e (the LQR cost-to-go) plus ``fallback`` * TERMINAL stage misses."""
            if self.equilibrium is None:
                return lambda x: fallback * TERMINAL * miss(x)

            def final(x):
                e = terminal.error(self.equilibrium, x)
                return 0.5 * e @ P @ e + fallback * TERMINAL * miss(x)
            return final

        def plan(x0, W, X, z, end, iterations):
            """iLQR from ``x0`` warm-started at the plan ``W`` and its trajectory ``X``."""
            f, final = dynamics(z), final_cost(*end)
            if screen:  # the warm plan against fresh pumping pushes, then iLQR
                W, X = ilqr.screen(f, stage, final, x0, W, candidates)
            return ilqr.solve(f, stage, final, x0, W, iterations, guess=X)

        self.plan = jax.jit(plan, static_argnums=5)
        self.iterations = iterations
        self.fit = map_fit(tr)

    def terminal(self, z, last=None):
        """The plan's terminal-cost argument at physical unknowns ``z``: (P, 0.0) with the LQR
        cost-to-go at the goal's equilibrium, else ``last`` (the previous one) or (0, 1.0):
        the horizon's last state weighing ``TERMINAL`` steps."""
        if self.equilibrium is not None:
            found = terminal.value_matrix(self.equilibrium, jnp.asarray(z), self.transition.nu)
            if found is not None:
                return jnp.asarray(found[0]), jnp.asarray(0.0)
        return last if last is not None else self.fallback()

    def fallback(self):
        """The terminal-cost argument without the LQR: the last state weighing ``TERMINAL``
        steps (no cost-to-go matrix)."""
        nx = self.transition.nx
        return jnp.zeros((nx, nx)), jnp.asarray(1.0)

    def near(self, x) -> bool:
        """Whether every hinge of ``x`` is within ``NEAR`` (chord) of the goal's equilibrium."""
        if self.equilibrium is None:
            return False
        e = np.asarray(terminal.error(self.equilibrium, jnp.asarray(x)))
        return bool(np.all(np.abs(e[self.equilibrium.hinge]) <= NEAR))

    def end(self, x, lqr_end):
        """The terminal-cost argument for a plan from ``x``: the LQR one near the equilibrium,
        else the horizon's last state weighing ``TERMINAL`` steps."""
        return lqr_end if self.near(x) else self.fallback()

    def state(self, obs: Observation) -> np.ndarray:
        missing = [j for j in self.transition.joints
                   if j not in obs.position or j not in obs.velocity]
        if missing:
            raise UsageError(f"the plant does not observe joint {', '.join(missing)}",
                             hint="a plant reports every scene joint by name")
        return np.array([obs.position[j] for j in self.transition.joints]
                        + [obs.velocity[j] for j in self.transition.joints], dtype=float)


def refit_due(k: int, refit_every: int, early: tuple[int, ...] = ()) -> bool:
    """Whether a refit follows the ``k``-th transition (1-based): every ``refit_every``, and
    after each count in ``early`` (refits before the first regular one: a model far from the
    plant is corrected while the first transitions arrive, before a fast system is lost)."""
    return bool(refit_every) and (k % refit_every == 0 or k in early)


def run(model: Model, plant: Plant, duration: float, *, refit_every: int = REFIT_EVERY,
        early: tuple[int, ...] = (), controller: Controller | None = None,
        on_step=None) -> MpcResult:
    """Drive ``plant`` for ``duration`` s; ``refit_every`` 0 never refits (the prior's centre
    throughout); ``early``: extra refits after these numbers of transitions (``refit_due``).
    ``on_step(k, t, x, u, z)`` hears of each period."""
    ctl = controller or Controller(model)
    tr = ctl.transition
    if not np.isclose(plant.period, tr.period, rtol=1e-6):
        raise UsageError(f"the plant's period {plant.period:g} s differs from the scene's control "
                         f"period {tr.period:g} s", hint="give the plant the scene's period")
    steps = int(round(duration / tr.period))
    obs = plant.reset()
    x = ctl.state(obs)
    z = jnp.asarray(tr.centre[tr.index])
    W = jnp.zeros((tr.horizon, tr.nu))
    X = jnp.tile(jnp.asarray(x), (tr.horizon + 1, 1))  # a first guess: staying put
    end = ctl.terminal(z)
    for _ in range(FIRST_ITERATIONS // ctl.iterations):  # a cold plan (one compiled solve)
        W, X, _ = ctl.plan(jnp.asarray(x), W, X, z, ctl.end(x, end), ctl.iterations)
    memory = Memory.empty(tr.nx, tr.nu, CAPACITY)
    precision, first = jnp.eye(len(z)), 1.0  # the first refit's prior: the model's
    times, states, forces, step_ms, step_cpu = [obs.t], [x], [], [], []
    estimates = [_estimate(tr, 0, obs.t, z, None, 0.0)]
    cost = 0.0
    for k in range(steps):
        start, cpu = time.perf_counter(), time.process_time()
        W, X, _ = ctl.plan(jnp.asarray(x), W, X, z, ctl.end(x, end), ctl.iterations)
        u = np.asarray(ctl.squash(W[0]))
        if not np.all(np.isfinite(u)):
            raise ModelError(f"mpc: the plan at t = {obs.t:g} s is not finite (state "
                             f"{np.round(x, 4).tolist()}); nothing was sent to the plant",
                             hint="check the scene's physics at this state (`physdsl lint`)")
        step_ms.append(1e3 * (time.perf_counter() - start))
        step_cpu.append(1e3 * (time.process_time() - cpu))
        cost += float(ctl.stage(jnp.asarray(x), W[0]))
        obs = plant.step(dict(zip(tr.targets, (float(v) for v in u))))
        x_next = ctl.state(obs)
        memory.add(x, u, x_next)
        x = x_next
        W = jnp.concatenate([W[1:], W[-1:]])  # the warm start of the next period
        X = jnp.concatenate([X[1:], X[-1:]])
        times.append(obs.t), states.append(x), forces.append(u)
        if tr.physical and refit_due(k + 1, refit_every, early):
            start = time.perf_counter()
            z, fitted = jax.block_until_ready(ctl.fit(
                z, memory.x, memory.u, memory.x_next, memory.mask, z, precision, first))
            if k + 1 >= refit_every:  # a regular refit: its Laplace is the next one's prior
                precision, first = fitted, 0.0
                memory.clear()
            # an early refit: every transition so far under the scene's prior (a few
            # transitions' Laplace would be a narrow prior in directions they barely inform)
            end = ctl.terminal(z, end)
            estimates.append(_estimate(tr, k + 1, obs.t, z, jnp.linalg.inv(fitted),
                                       1e3 * (time.perf_counter() - start)))
        if on_step is not None:
            on_step(k, obs.t, x, u, z)
    return MpcResult(tr.joints, tr.targets, np.asarray(times), np.asarray(states),
                     np.asarray(forces).reshape(steps, tr.nu), np.asarray(step_ms), estimates,
                     ctl.holds, cost, tr.hinges, np.asarray(z), np.asarray(step_cpu))


def _estimate(tr: Transition, step: int, t: float, z, cov, ms: float) -> dict:
    values = {n: float(np.ravel(v)[0]) for n, v in tr.physical_values(z).items()}
    sd = constrained_sd(tr, z, cov) if cov is not None else {n: float("nan") for n in values}
    return {"step": step, "t": t, "values": values, "sd": sd, "refit_ms": ms}
