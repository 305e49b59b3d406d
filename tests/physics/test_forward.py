"""forward_mode: a function's jvp and gradient through its jaxpr-level forward-mode Jacobian
(stretches of equations by one vmapped jvp, loops as scans with explicit tangent carries) equal
JAX's own, for loops with integer carries, differentiated constants and scanned-over inputs."""
import jax
import jax.extend
import jax.numpy as jnp
import numpy as np

import physdsl  # noqa: F401 - float64
from physdsl.physics.forward import forward_mode


def rollout(vals):
    a, b, c = vals["a"], vals["b"], vals["c"]

    def body(carry, x):
        i, s, u = carry
        s = s * a + jnp.sin(u) * x
        u = u + b * s
        return (i + 1, s, u), (s * c, i)

    (_, s, u), (ys, steps) = jax.lax.scan(body, (0, jnp.ones(2), jnp.zeros(2)),
                                          jnp.linspace(0.0, 1.0, 7) * c)
    return {"s": s, "ys": jnp.cos(ys) * a, "steps": steps, "u": u * a}  # vals["d"]: unread


VALS = {"a": jnp.array(0.9), "b": jnp.array([0.3, -0.2]), "c": jnp.array(1.5), "d": jnp.array(3.0)}
TANGENT = {"a": jnp.array(0.3), "b": jnp.array([1.0, 2.0]), "c": jnp.array(-0.7),
           "d": jnp.array(0.5)}


def test_jvp_matches_jax():
    out, tan = jax.jvp(forward_mode(rollout), (VALS,), (TANGENT,))
    ref, ref_tan = jax.jvp(rollout, (VALS,), (TANGENT,))
    for k in ("s", "ys", "u"):
        np.testing.assert_allclose(out[k], ref[k], rtol=0, atol=0)
        np.testing.assert_allclose(tan[k], ref_tan[k], rtol=1e-12, atol=1e-12)
    np.testing.assert_array_equal(out["steps"], ref["steps"])


def test_gradient_matches_jax_under_jit_and_vmap():
    def loss(f):
        return lambda v: jnp.sum(f(v)["ys"]) + jnp.sum(f(v)["u"] ** 2)

    g = jax.jit(jax.grad(loss(forward_mode(rollout))))(VALS)
    ref = jax.grad(loss(rollout))(VALS)
    for k in VALS:
        np.testing.assert_allclose(g[k], ref[k], rtol=1e-12, atol=1e-12)
    batch = jax.vmap(lambda a: forward_mode(rollout)({**VALS, "a": a})["s"])(jnp.array([0.5, 0.9]))
    np.testing.assert_allclose(batch[1], rollout(VALS)["s"], rtol=1e-14)


def test_inline_calls_replaces_nested_and_shared_jit_calls():
    from physdsl.physics.forward import inline_calls

    inner = jax.jit(lambda u, v: (jnp.where(u > 0, u * v, v), u, 2.0))  # a pass-through, a literal

    def f(x, y):
        a, b, c = inner(x, y)
        d, _, _ = inner(a + b, y)  # the same jaxpr twice: fresh variables
        return jax.jit(lambda z: inner(z, z)[0] * c)(d), b

    x, y = jnp.array([0.5, -1.0, 2.0]), jnp.array([3.0, 4.0, -5.0])
    closed = jax.make_jaxpr(f)(x, y)
    flat = inline_calls(closed)
    assert any(e.primitive.name in ("jit", "pjit") for e in closed.jaxpr.eqns)
    assert not any(e.primitive.name in ("jit", "pjit") for e in flat.jaxpr.eqns)
    for got, want in zip(jax.extend.core.jaxpr_as_fun(flat)(x, y), f(x, y)):
        np.testing.assert_array_equal(got, want)


def test_jacobian_scan_carries_only_the_columns_that_reach_it():
    """x[0] and x[4] never reach the loop (pieces of a flat vector, as a noise scale's): the
    loop carries 2 tangent columns, not 5, and the Jacobian still equals JAX's."""
    from physdsl.physics.forward import jacobian, prune

    def f(x):
        a, b, c = jnp.split(x, [1, 3])
        s = jax.lax.scan(lambda s, _: (s * b[0] + jnp.sin(s) * b[1], None), 1.0, None, length=5)[0]
        return jnp.exp(a[0]) * s + jnp.sum(c ** 2)

    x = jnp.array([0.3, 0.9, -0.4, 1.5, 2.0])
    closed = jax.make_jaxpr(f)(x)
    (v,), (g,) = jacobian(prune(closed)[0], [x], [0])
    np.testing.assert_allclose(v, f(x), rtol=1e-15)
    np.testing.assert_allclose(g, jax.jacfwd(f)(x), rtol=1e-13)
    scans = [e for e in jax.make_jaxpr(lambda x: jacobian(prune(closed)[0], [x], [0]))(x).eqns
             if e.primitive.name == "scan"]
    assert [e.outvars[1].aval.shape[0] for e in scans] == [2]  # (P, ...) tangent carry


def test_jacobian_scan_carries_only_the_carries_a_tangent_reaches():
    """A falling body's height does not enter its velocity: differentiated in its start height
    alone, the loop carries the height's tangent and not the velocity's (found from the body's
    dependencies, to a fixed point: ``u`` reaches ``w`` only in the second trip of the analysis);
    in the drag coefficient, every carry. Both Jacobians equal JAX's."""
    from physdsl.physics.forward import _scan_sizes, jacobian, prune

    def fall(x, z0, k):
        def body(c, _):
            z, v, u, w = c
            return (1.001 * z + 0.01 * v, v - 0.01 * (9.81 + k * v * jnp.abs(v)), u * x, w + u), z
        c, zs = jax.lax.scan(body, (z0, 0.0, 1.0, 0.0), None, length=50)
        return jnp.sum(zs) + c[1] + c[3]

    args = [jnp.array(1.01), jnp.array(1.8), jnp.array(0.3)]
    closed = jax.make_jaxpr(fall)(*args)
    for col, carried in ((1, 1), (2, 2), (0, 2)):  # z0: z alone; k: z, v; x: u, then w
        (v,), (g,) = jacobian(prune(closed)[0], args, [col])
        np.testing.assert_allclose(v, fall(*args), rtol=1e-15)
        np.testing.assert_allclose(g[0], jax.grad(fall, col)(*args), rtol=1e-12)
        scans = [e for e in jax.make_jaxpr(
            lambda *a, col=col: jacobian(prune(closed)[0], list(a), [col]))(*args).eqns
            if e.primitive.name == "scan"]
        # 4 primal carries, then one (P, ...) tangent per carried one (any JAX's scan params)
        assert _scan_sizes(scans[0].params)[1] == 4 + carried


def test_inline_calls_with_rollouts_puts_the_forward_mode_loop_in_the_callers_jaxpr():
    """A caller that reads the Jacobian of a larger function (the log density) asks for the
    rollout's own equations (``rollouts=True``, no mode flag): the scan then sits in its jaxpr,
    the rollout's constants come along, and the Jacobian read off it equals JAX's."""
    from physdsl.physics.forward import inline_calls, jacobian, prune

    weights = np.linspace(0.5, 2.0, 2)  # a constant of the rollout's own jaxpr

    def f(x):
        out = forward_mode(lambda v: rollout(v))({"a": x[0], "b": x[1:3], "c": x[3],
                                                  "d": VALS["d"]})
        return jnp.sum(out["ys"]) + jnp.sum(weights * out["u"]) + x[0] ** 2

    x = jnp.array([0.9, 0.3, -0.2, 1.5])
    closed = jax.make_jaxpr(f)(x)
    names = lambda c: {e.primitive.name for e in c.jaxpr.eqns}  # noqa: E731
    assert "custom_jvp_call" in names(inline_calls(closed)) and "scan" not in names(closed)
    flat = inline_calls(closed, rollouts=True)
    assert "custom_jvp_call" not in names(flat) and "scan" in names(flat)
    (v,), (g,) = jacobian(prune(flat)[0], [x], [0])
    np.testing.assert_allclose(v, f(x), rtol=1e-14)
    np.testing.assert_allclose(g, jax.jacfwd(lambda x: f(x))(x), rtol=1e-12)


def test_jacobian_through_a_loop_of_at_most_one_trip_equals_jax_in_both_branches(monkeypatch):
    """The contact rollout under ``integrate.either`` (forward only: a while loop of at most one
    trip around a scan) is carried with its tangents (``forward._while``), its scan inside by
    ``forward._scan`` as a top-level one (not by JAX's jvp and vmap of the loop, which trace the
    step several times over): the Jacobian equals JAX's where the loop runs and where it does
    not, and the new loop carries the tangent of the float carry alone (not the flag's)."""
    from physdsl.physics import forward
    from physdsl.physics.forward import jacobian, prune
    from physdsl.physics.integrate import either

    scans = []
    plain_scan = forward._scan
    monkeypatch.setattr(forward, "_scan", lambda *a: scans.append(1) or plain_scan(*a))

    def contact(x):
        return jax.lax.scan(lambda s, _: (s * x[1] + jnp.sin(s) * x[2], None), x[:2], None,
                            length=6)[0]

    def f(x):
        out = either(x[0] > 0.5, contact, lambda x: x[:2] * x[2], x, forward_only=True)
        return jnp.sum(out ** 2) + x[1]

    for x0 in (0.9, 0.1):  # the loop runs; it does not
        x = jnp.array([x0, 0.8, -0.3])
        closed = jax.make_jaxpr(f)(x)
        assert "while" in {e.primitive.name for e in closed.jaxpr.eqns}
        (v,), (g,) = jacobian(prune(closed)[0], [x], [0])
        np.testing.assert_allclose(v, f(x), rtol=1e-15)
        np.testing.assert_allclose(g, jax.jacfwd(f)(x), rtol=1e-12)
    assert len(scans) == 2  # the scan inside the loop, once per x
    loops = [e for e in jax.make_jaxpr(lambda x: jacobian(prune(closed)[0], [x], [0]))(x).eqns
             if e.primitive.name == "while"]
    assert len(loops) == 1
    carries = [v.aval.shape for v in loops[0].outvars]
    assert carries == [(), (2,), (3, 2)]  # flag, state, the state's 3 tangent columns
