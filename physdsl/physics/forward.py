"""Forward-mode derivatives of a rollout: its Jacobian with respect to the few scalar unknowns.

``forward_mode(f)`` gives ``f`` a custom jvp whose rule evaluates the Jacobian with P tangents
carried alongside the state (one scan of state and tangents), which compiles and runs far faster
than reverse mode through a scan of many small steps when P is small; gradients then come by
transposing that linear rule. ``f``'s Python is traced once, into a jaxpr pruned of what no output
reads, and the Jacobian is read off that jaxpr directly: each stretch of equations between loops
by one vmapped jvp, each scan as a new scan whose body is the vmapped jvp of the old body with
every tangent an explicit carry (JAX's own jvp and vmap of a scan trace its body four or five
times over, to find which carries have tangents and which are batched), each while loop (the
contact rollout under ``integrate.either``) as a new while loop whose body carries the tangents
through the old body the same way, its scans included. Small jit calls (e.g.
``jnp.where``'s) are inlined first. A caller that differentiates a larger function the same way
(the log density, ``infer.base``) says so explicitly: ``inline_calls(closed, rollouts=True)``
replaces each forward-mode call in its jaxpr by the rollout's own equations, whose loops then
take the caller's tangents (no mode flag: the call is marked in the jaxpr itself).
"""
from __future__ import annotations

import jax
import jax.extend
import jax.numpy as jnp
import numpy as np

core = jax.extend.core

# at most this many scalar unknowns: derivatives by forward mode; more: reverse mode
FORWARD_MODE_MAX = 24
# the name of the function under ``forward_mode``'s custom jvp: it marks the call in a jaxpr
# (``inline_calls(..., rollouts=True)``)
_MARK = "forward_mode_run"


def forward_mode(f):
    """``f(values)`` whose derivatives (jvp, and grad by transposition) come from its forward-mode
    Jacobian with respect to the float leaves of ``values`` that ``f`` reads (others get no
    tangent column)."""
    def apply(values):
        leaves, in_tree = jax.tree_util.tree_flatten(values)
        closed, shape = jax.make_jaxpr(lambda *xs: f(jax.tree_util.tree_unflatten(in_tree, xs)),
                                       return_shape=True)(*leaves)
        closed, used = prune(inline_calls(closed))
        run_flat = core.jaxpr_as_fun(closed)
        out_tree = jax.tree_util.tree_structure(shape)
        cols = [i for i, x in enumerate(leaves) if used[i] and _is_float(x)]

        def forward_mode_run(*xs):
            return jax.tree_util.tree_unflatten(out_tree, run_flat(*xs))

        run = forward_mode_run
        g = jax.custom_jvp(run)

        @g.defjvp
        def rule(primals, tangents):
            if not cols:
                out = run(*primals)
                return out, jax.tree_util.tree_map(_zero_tangent, out)
            outs, jac = jacobian(closed, list(primals), cols)
            dx = jnp.concatenate([jnp.ravel(tangents[i]) for i in cols])
            douts = [_zero_tangent(o) if j is None else jnp.tensordot(dx, j, axes=1)
                     for o, j in zip(outs, jac)]
            return (jax.tree_util.tree_unflatten(out_tree, outs),
                    jax.tree_util.tree_unflatten(out_tree, douts))

        return g(*leaves)

    return apply


def prune(closed):
    """(``closed`` without the equations no output depends on, which inputs it still reads).

    Top-level only (a loop or call is kept whole if any of its outputs is read); equations with
    effects are kept."""
    jaxpr = closed.jaxpr
    live = {v for v in jaxpr.outvars if isinstance(v, core.Var)}
    kept = []
    for eqn in reversed(jaxpr.eqns):
        if eqn.effects or any(v in live for v in eqn.outvars):
            kept.append(eqn)
            live.update(v for v in eqn.invars if isinstance(v, core.Var))
    pruned = core.ClosedJaxpr(jaxpr.replace(eqns=kept[::-1]), closed.consts)
    return pruned, [v in live for v in jaxpr.invars]


def inline_calls(closed, rollouts: bool = False):
    """``closed`` with its jit calls (e.g. ``jnp.where``'s) replaced by their equations: a call
    would be transformed (jvp, vmap) as a jaxpr of its own and lowered as a function of its own,
    for a handful of elementwise operations. ``rollouts``: the calls of ``forward_mode`` too
    (replaced by the function's own equations), for a caller that reads the Jacobian of the
    whole jaxpr off it (``jacobian``): the rollout's loops then take the caller's tangents
    directly, with no Jacobian of their own to multiply."""
    jaxpr = closed.jaxpr
    if not any(_is_call(e, rollouts) for e in jaxpr.eqns):
        return closed
    sub: dict = {}
    eqns: list = []
    consts: list = []
    _inline(jaxpr.eqns, sub, eqns, fresh=False, rollouts=rollouts, consts=consts)
    outvars = [sub.get(v, v) if isinstance(v, core.Var) else v for v in jaxpr.outvars]
    constvars = list(jaxpr.constvars) + [v for v, _ in consts]
    return core.ClosedJaxpr(jaxpr.replace(constvars=constvars, eqns=eqns, outvars=outvars),
                            list(closed.consts) + [c for _, c in consts])


def _inline(eqns, sub: dict, out: list, fresh: bool, rollouts: bool = False,
            consts: list | None = None) -> None:
    """Append ``eqns`` to ``out`` with calls replaced by their equations; ``sub`` maps variables
    of this level to atoms of the result; ``fresh``: new variables (a call's body may be shared);
    a forward-mode call's constants become new constants of the result (``consts``)."""
    read = lambda v: sub.get(v, v) if isinstance(v, core.Var) else v  # noqa: E731
    for eqn in eqns:
        invars = [read(v) for v in eqn.invars]
        if _is_call(eqn, rollouts):
            called = eqn.params["jaxpr" if eqn.primitive.name != "custom_jvp_call" else "call_jaxpr"]
            inner = called.jaxpr
            local = dict(zip(inner.invars, invars))
            for cv, c in zip(inner.constvars, called.consts):
                local[cv] = core.Var(cv.aval)
                consts.append((local[cv], c))
            _inline(inner.eqns, local, out, fresh=True, rollouts=rollouts, consts=consts)
            for o, i in zip(eqn.outvars, inner.outvars):
                if not isinstance(o, core.DropVar):
                    sub[o] = local.get(i, i) if isinstance(i, core.Var) else i
            continue
        outs = eqn.outvars
        if fresh:
            outs = [v if isinstance(v, core.DropVar) else core.Var(v.aval) for v in eqn.outvars]
            sub.update((v, w) for v, w in zip(eqn.outvars, outs) if not isinstance(v, core.DropVar))
        out.append(eqn.replace(invars=invars, outvars=outs))


def _is_call(eqn, rollouts: bool = False) -> bool:
    """A jit call with no constants of its own (those are inlined), or with ``rollouts`` a call
    of ``forward_mode``'s custom jvp (marked by its function's name)."""
    if eqn.primitive.name == "custom_jvp_call":
        info = eqn.params["call_jaxpr"].jaxpr.debug_info
        return rollouts and info is not None and info.func_name == _MARK
    return eqn.primitive.name in ("pjit", "jit") and not eqn.params["jaxpr"].consts


def jacobian(closed, leaves: list, cols: list[int]):
    """``closed`` evaluated at ``leaves``, and the tangent of each output (P, *shape) for one
    unit tangent per scalar of the leaves in ``cols`` (None: the output does not depend on them)."""
    P = sum(int(np.size(leaves[i])) for i in cols)
    basis = np.eye(P)  # a constant, not ops to trace
    seeds, off = [None] * len(leaves), 0
    for i in cols:
        n = int(np.size(leaves[i]))
        seeds[i] = basis[:, off:off + n].reshape((P,) + jnp.shape(leaves[i])).astype(
            jnp.result_type(leaves[i]))
        off += n
    return _propagate(closed, leaves, seeds, P, _columns(closed.jaxpr, leaves, cols))


def _propagate(closed, leaves: list, seeds: list, P: int, reach: dict):
    """``closed`` evaluated at ``leaves`` with the tangents ``seeds`` ((P, *shape) or None per
    leaf) carried through: each stretch of equations between loops by one vmapped jvp, each loop
    by a new loop carrying the tangents (``_scan_columns``, ``_while``). ``reach``: the tangent
    columns that may reach each variable (``_columns``)."""
    jaxpr = closed.jaxpr
    env = dict(zip(jaxpr.constvars, closed.consts))
    tenv: dict = {}
    for v, x, t in zip(jaxpr.invars, leaves, seeds):
        env[v] = x
        if t is not None:
            tenv[v] = t
    needed = _needed_after(jaxpr)
    stretch: list = []
    for k, eqn in enumerate(jaxpr.eqns):
        if eqn.primitive.name not in ("scan", "while"):
            stretch.append(eqn)
            continue
        _stretch(stretch, env, tenv, needed[k - 1] if k else set())
        stretch = []
        if not any(v in tenv for v in eqn.invars if isinstance(v, core.Var)):
            _evaluate([eqn], env, needed[k])  # no tangent reaches it
        elif eqn.primitive.name == "scan":
            _scan_columns(eqn, env, tenv, P, sorted(_coarse(reach, eqn.invars)))
        else:
            _while(eqn, env, tenv, P)
    _stretch(stretch, env, tenv, needed[-1] if jaxpr.eqns else set())
    return _read(jaxpr.outvars, env, tenv)


def _columns(jaxpr, leaves, cols) -> dict:
    """Which tangent columns may reach each variable: a tuple of column sets per element for
    vectors and scalars (kept through splits, slices and reshapes, so the pieces of a flat
    vector of unknowns stay apart), else one set for the whole array."""
    reach: dict = {}
    off = 0
    for i, (v, x) in enumerate(zip(jaxpr.invars, leaves)):
        if i in cols:
            n = int(np.size(x))
            reach[v] = (tuple(frozenset([off + k]) for k in range(n)) if np.ndim(x) <= 1
                        else frozenset(range(off, off + n)))
            off += n
    return _spread(jaxpr, reach)


def _spread(jaxpr, reach: dict) -> dict:
    """``reach`` (columns per input variable) carried through ``jaxpr``'s equations."""
    for eqn in jaxpr.eqns:
        ins = [reach.get(v) if isinstance(v, core.Var) else None for v in eqn.invars]
        if all(r is None for r in ins):
            continue
        name, r = eqn.primitive.name, ins[0]
        outs = [v for v in eqn.outvars if not isinstance(v, core.DropVar)]
        if isinstance(r, tuple) and name == "split" and eqn.params["axis"] == 0:
            cuts = np.cumsum([0] + list(eqn.params["sizes"]))
            for v, a, b in zip(eqn.outvars, cuts[:-1], cuts[1:]):
                reach[v] = r[a:b]
        elif isinstance(r, tuple) and name == "slice" and len(r) == eqn.invars[0].aval.size \
                and eqn.invars[0].aval.ndim == 1 and not eqn.params["strides"]:
            reach[eqn.outvars[0]] = r[eqn.params["start_indices"][0]:eqn.params["limit_indices"][0]]
        elif isinstance(r, tuple) and name in ("reshape", "squeeze", "convert_element_type") \
                and eqn.outvars[0].aval.ndim <= 1:
            reach[eqn.outvars[0]] = r
        else:
            u = frozenset().union(*[_coarse(reach, [v]) for v in eqn.invars])
            reach.update((v, u) for v in outs)
    return reach


def _coarse(reach, atoms) -> frozenset:
    """The columns that may reach any of ``atoms``."""
    u: frozenset = frozenset()
    for v in atoms:
        r = reach.get(v) if isinstance(v, core.Var) else None
        if r is not None:
            u = u.union(*r) if isinstance(r, tuple) else u | r
    return u


def _scan_columns(eqn, env, tenv, P, used) -> None:
    """``_scan`` carrying only the tangent columns ``used`` that reach it (e.g. not a noise
    scale's), its tangents then padded back to all P columns with zeros."""
    if len(used) == P:
        return _scan(eqn, env, tenv, P)
    idx = np.asarray(used)
    runs = np.split(idx, np.flatnonzero(np.diff(idx) > 1) + 1)

    def take(t):  # the used columns by slices (no gather)
        parts = [jax.lax.slice_in_dim(t, int(r[0]), int(r[-1]) + 1) for r in runs]
        return jnp.concatenate(parts) if len(parts) > 1 else parts[0]

    sub = {v: take(tenv[v]) for v in eqn.invars if isinstance(v, core.Var) and v in tenv}
    _scan(eqn, env, sub, len(used))
    for v in eqn.outvars:
        if v not in sub or isinstance(v, core.DropVar):
            continue
        d, pieces, at, j = sub[v], [], 0, 0
        for run in runs:
            if run[0] > at:
                pieces.append(jnp.zeros((run[0] - at,) + d.shape[1:], d.dtype))
            pieces.append(d[j:j + len(run)])
            at, j = run[-1] + 1, j + len(run)
        if at < P:
            pieces.append(jnp.zeros((P - at,) + d.shape[1:], d.dtype))
        tenv[v] = jnp.concatenate(pieces) if len(pieces) > 1 else pieces[0]


def _needed_after(jaxpr) -> list[set]:
    """needed[k]: the variables read by equation k+1 onwards or output."""
    live = {v for v in jaxpr.outvars if isinstance(v, core.Var)}
    out = [set()] * len(jaxpr.eqns)
    for k in range(len(jaxpr.eqns) - 1, -1, -1):
        out[k] = set(live)
        live |= {v for v in jaxpr.eqns[k].invars if isinstance(v, core.Var)}
    return out


def _stretch(eqns, env, tenv, needed) -> None:
    """Evaluate loop-free equations, their tangents by one vmapped jvp of those that read a
    tangent (the others, e.g. constant masses, are evaluated plainly and get no tangent: a
    zero tangent would be carried into the next loop as if it were not known to be zero)."""
    if not eqns:
        return
    dep = {v for eqn in eqns for v in eqn.invars if isinstance(v, core.Var) and v in tenv}
    plain, diff = [], []
    for eqn in eqns:
        if any(isinstance(v, core.Var) and v in dep for v in eqn.invars):
            dep.update(eqn.outvars)
            diff.append(eqn)
        else:
            plain.append(eqn)
    _evaluate(plain, env, needed | {v for eqn in diff for v in eqn.invars
                                    if isinstance(v, core.Var)})
    if not diff:
        return
    fn, ins, outs = _function(diff, needed)
    prim = [env[v] for v in ins]
    dif = [k for k, v in enumerate(ins) if v in tenv]

    def f(*xs):
        args = list(prim)
        for k, x in zip(dif, xs):
            args[k] = x
        return fn(*args)

    res, dres = jax.vmap(lambda *t: jax.jvp(f, [prim[k] for k in dif], list(t)),
                         out_axes=(None, 0))(*[tenv[ins[k]] for k in dif])
    for v, r, d in zip(outs, res, dres):
        env[v] = r
        if _is_float(r):
            tenv[v] = d


def _function(eqns, needed):
    """(function of the inputs ``eqns`` read but do not define, those inputs, the outputs in
    ``needed``) of a list of loop-free equations."""
    defined, ins = set(), []
    for eqn in eqns:
        ins += [v for v in eqn.invars if isinstance(v, core.Var) and v not in defined
                and v not in ins]
        defined.update(eqn.outvars)
    outs = [v for eqn in eqns for v in eqn.outvars if v in needed]
    info = core.DebugInfo("forward_mode", "a stretch of the rollout", None, None)
    fn = core.jaxpr_as_fun(core.ClosedJaxpr(core.Jaxpr([], ins, outs, eqns, debug_info=info), []))
    return fn, ins, outs


def _evaluate(eqns, env, needed) -> None:
    """Evaluate equations no tangent reaches; only the values in ``needed`` are kept."""
    if eqns:
        fn, ins, outs = _function(eqns, needed)
        env.update(zip(outs, fn(*[env[v] for v in ins])))


def _scan_sizes(params) -> tuple[int, int]:
    """(constants, carries) of a scan equation: named in its params up to JAX 0.10; from 0.11 a
    flat tree ``ft_in`` packs (constants, carries, scanned inputs)."""
    if "num_consts" in params:
        return params["num_consts"], params["num_carry"]
    consts, carry, _ = params["ft_in"].unpack()
    return len(consts), len(carry)


def _tangent_carries(body, nc: int, nk: int, dc, dx, dk) -> list[int]:
    """The carries of a scan ``body`` (a jaxpr: constants, carries, scanned inputs) that a tangent
    reaches: those with one at the start (``dk``) and, to a fixed point, those the body computes
    from a constant (``dc``), scanned input (``dx``) or carry with one. The others stay exactly
    zero and are not carried (as JAX's own jvp of a scan finds, here by reading the jaxpr's
    dependencies rather than tracing the body again): a ball's velocity does not depend on its
    start height."""
    ins = body.invars
    seeds = {ins[k] for k in dc} | {ins[nc + nk + k] for k in dx}
    carried = set(dk)
    while True:
        reached = set(seeds) | {ins[nc + k] for k in carried}
        for eqn in body.eqns:  # coarse: every output of an equation that reads a reached input
            if eqn.primitive.name == "stop_gradient":  # (a contact solver's warm start)
                continue
            if any(isinstance(v, core.Var) and v in reached for v in eqn.invars):
                reached.update(v for v in eqn.outvars if not isinstance(v, core.DropVar))
        more = {k for k, v in enumerate(body.outvars[:nk])
                if isinstance(v, core.Var) and v in reached} - carried
        if not more:
            return sorted(carried)
        carried |= more


def _scan(eqn, env, tenv, P) -> None:
    """A scan with its tangents: a new scan carrying every float carry's P tangents, whose body
    is the vmapped jvp of the old one."""
    p = eqn.params
    nc, nk = _scan_sizes(p)
    ins, tans = _read(eqn.invars, env, tenv)
    consts, init, xs = ins[:nc], ins[nc:nc + nk], ins[nc + nk:]
    dc = [k for k in range(nc) if tans[k] is not None]
    dx = [k for k in range(len(xs)) if tans[nc + nk + k] is not None]
    # (pruned of a step's unread loads, e.g. torques)
    pruned = prune(inline_calls(p["jaxpr"]))[0]
    fk = _tangent_carries(pruned.jaxpr, nc, nk, dc, dx,
                          [k for k in range(nk) if tans[nc + k] is not None])
    fk = [k for k in fk if _is_float(init[k])]
    dinit = [tans[nc + k] if tans[nc + k] is not None
             else jnp.zeros((P,) + jnp.shape(init[k]), jnp.result_type(init[k])) for k in fk]
    dxs = [jnp.moveaxis(tans[nc + nk + k], 0, 1) for k in dx]  # (T, P, ...)
    body = core.jaxpr_as_fun(pruned)

    def step(carry, x):
        (c, dcarry), (xv, dxv) = carry, x

        def f(a, b, d):
            args_c, args_k, args_x = list(consts), list(c), list(xv)
            for k, v in zip(dc, a):
                args_c[k] = v
            for k, v in zip(fk, b):
                args_k[k] = v
            for k, v in zip(dx, d):
                args_x[k] = v
            return body(*args_c, *args_k, *args_x)

        prim = ([consts[k] for k in dc], [c[k] for k in fk], [xv[k] for k in dx])
        out, dout = jax.vmap(lambda ta, tb, td: jax.jvp(f, prim, (ta, tb, td)),
                             out_axes=(None, 0))([tans[k] for k in dc], dcarry, dxv)
        return (list(out[:nk]), [dout[k] for k in fk]), (out[nk:], dout[nk:])

    (cf, dcf), (ys, dys) = jax.lax.scan(step, (init, dinit), (xs, dxs), length=p["length"],
                                        reverse=p["reverse"], unroll=p["unroll"])
    douts = [None] * nk + [jnp.moveaxis(d, 1, 0) if _is_float(y) else None
                           for y, d in zip(ys, dys)]
    for k, d in zip(fk, dcf):
        douts[k] = d
    for v, o, d in zip(eqn.outvars, list(cf) + list(ys), douts):
        if isinstance(v, core.DropVar):
            continue
        env[v] = o
        if d is not None and _is_float(o):
            tenv[v] = d


def _while(eqn, env, tenv, P) -> None:
    """A while loop with its tangents: a new loop carrying the P tangents of every float carry a
    tangent reaches, whose body propagates them through the old body (``_propagate``: its own
    loops carried as here). The contact rollout under ``integrate.either`` is such a loop: JAX's
    jvp and vmap of it would trace its body, and the rollout's step inside, several times over
    to find the carries with tangents and those batched."""
    p = eqn.params
    cn, bn = p["cond_nconsts"], p["body_nconsts"]
    ins, tans = _read(eqn.invars, env, tenv)
    cconsts, bconsts, init = ins[:cn], ins[cn:cn + bn], ins[cn + bn:]
    nk = len(init)
    body = inline_calls(p["body_jaxpr"])
    fk = _tangent_carries(body.jaxpr, bn, nk, [k for k in range(bn) if tans[cn + k] is not None],
                          [], [k for k in range(nk) if tans[cn + bn + k] is not None])
    fk = [k for k in fk if _is_float(init[k])]
    dinit = [tans[cn + bn + k] if tans[cn + bn + k] is not None
             else jnp.zeros((P,) + jnp.shape(init[k]), jnp.result_type(init[k])) for k in fk]
    cond = core.jaxpr_as_fun(p["cond_jaxpr"])
    every = frozenset(range(P))

    def step(carry):
        c, dk = carry
        seeds = list(tans[cn:cn + bn]) + [None] * nk
        for k, d in zip(fk, dk):
            seeds[bn + k] = d
        reach = {v: every for v, t in zip(body.jaxpr.invars, seeds) if t is not None}
        outs, douts = _propagate(body, list(bconsts) + list(c), seeds, P,
                                 _spread(body.jaxpr, reach))
        return outs, [douts[k] if douts[k] is not None else jnp.zeros_like(d)
                      for k, d in zip(fk, dk)]

    final, dfinal = jax.lax.while_loop(lambda carry: cond(*cconsts, *carry[0])[0], step,
                                       (init, dinit))
    for k, (v, o) in enumerate(zip(eqn.outvars, final)):
        if not isinstance(v, core.DropVar):
            env[v] = o
            if k in fk:
                tenv[v] = dfinal[fk.index(k)]


def _read(atoms, env: dict, tenv: dict) -> tuple[list, list]:
    """(values, tangents or None) of ``atoms`` (an equation's inputs, a jaxpr's outputs): a
    literal's own value and no tangent, a variable's from ``env`` and ``tenv``."""
    literal = [isinstance(v, core.Literal) for v in atoms]
    return ([v.val if lit else env[v] for v, lit in zip(atoms, literal)],
            [None if lit else tenv.get(v) for v, lit in zip(atoms, literal)])


def _is_float(x) -> bool:
    return jnp.issubdtype(jnp.result_type(x), jnp.inexact)


def _zero_tangent(x):
    if _is_float(x):
        return jnp.zeros_like(x)
    return np.zeros(jnp.shape(x), dtype=jax.dtypes.float0)
