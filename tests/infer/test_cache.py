"""The persistent compilation cache (physdsl/cache.py), across separate processes.

A scene is compiled and rolled out in fresh Python processes sharing one cache folder: the
second process of the same scene adds no entry (every program came from the folder, its trace
too: physdsl/traces.py) and gives the same numbers; other measurements of the same shape add
none either (data are arguments, not constants); an added effect adds entries and gives its
own, correct numbers (no stale hit). Nothing here is timed.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

from .conftest import write_trajectory_csv

TRACES = "PHYSDSL_TRACE_CACHE"  # on in these processes
CLI = "import sys; from physdsl.cli import main; sys.exit(main())"

BALLISTIC = """\
scene toss {
  world {
    timestep: 1 ms
    integrator: rk4
  }
  body ball {
    shape: sphere(radius: 5 cm)
    mass: 200 g
    position: (0, 0, 1) m
    velocity ~ normal((3, 0, 4) m/s, 1 m/s)
    angular_velocity: (0, 0, 0) rad/s
  }
EFFECT  observe ball.position from "data.csv" where body == "ball" { noise: 10 mm }
}
"""
DRAG = "  effect linear_drag on ball { coefficient: 0.3 kg/s }\n"
TIMES = np.linspace(0.0, 0.5, 11)
V0 = np.array([3.2, 0.4, 4.3])
G, M, C = 9.81, 0.2, 0.3

# Compile the scene given as argv[1] and print its prediction at velocity V0 (JSON).
ROLLOUT = """\
import json, sys
import numpy as np
from physdsl.compile import compile
model = compile(sys.argv[1])
pred = model.predict({"ball.velocity": np.array(json.loads(sys.argv[2]))})["ball.position"]
print(json.dumps(np.asarray(pred).tolist()))
"""


def _scene(folder: Path, effect: str = "", seed: int = 0) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    noise = np.random.default_rng(seed).normal(0.0, 0.01, (len(TIMES), 3))
    write_trajectory_csv(folder / "data.csv", TIMES, noise + [0.0, 0.0, 1.0])
    scene = folder / "scene.phys"
    scene.write_text(BALLISTIC.replace("EFFECT", effect))
    return scene


def _rollout(scene: Path, cache: Path | str | None, **more_env: str) -> np.ndarray:
    env = {k: v for k, v in os.environ.items() if k not in ("PHYSDSL_CACHE_DIR", TRACES)}
    env.update(more_env, **({} if cache is None else {"PHYSDSL_CACHE_DIR": str(cache)}))
    done = subprocess.run([sys.executable, "-c", ROLLOUT, str(scene), json.dumps(V0.tolist())],
                          env=env, capture_output=True, text=True, timeout=300, check=False)
    assert done.returncode == 0, done.stderr
    return np.array(json.loads(done.stdout.strip().splitlines()[-1]))


def _entries(cache: Path) -> set[str]:
    return {p.name for p in cache.iterdir() if p.name.endswith("-cache")}


def _traces(cache: Path) -> set[str]:
    """The traced programs kept (the suite runs without them: tests/conftest.py)."""
    return {p.name for p in (cache / "traces").glob("*.trace")}


def _ballistic(t):
    return np.array([0.0, 0.0, 1.0]) + np.outer(t, V0) - 0.5 * G * np.outer(t**2, [0, 0, 1])


def _linear_drag(t):
    """x(t) under m x'' = -c x' + m g (closed form)."""
    tau = M / C
    decay = 1.0 - np.exp(-t / tau)
    vz_inf = -G * tau
    x = np.outer(tau * decay, V0[:2])
    z = 1.0 + vz_inf * t + tau * (V0[2] - vz_inf) * decay
    return np.column_stack([x, z])


def test_second_process_reuses_cache_and_other_data_hit_it(tmp_path):
    cache = tmp_path / "cache"
    first = _rollout(_scene(tmp_path / "a"), cache)
    after_first, traced = _entries(cache), _traces(cache)
    assert after_first, "the first process wrote no compiled program"
    assert traced, "the first process kept no traced program"
    np.testing.assert_allclose(first, _ballistic(TIMES), atol=1e-9)

    second = _rollout(_scene(tmp_path / "a"), cache)
    assert _entries(cache) == after_first  # every program came from the folder
    assert _traces(cache) == traced
    np.testing.assert_array_equal(second, first)

    other_data = _rollout(_scene(tmp_path / "b", seed=1), cache)
    assert _entries(cache) == after_first  # the measurements are not constants of a program
    assert _traces(cache) == traced
    np.testing.assert_array_equal(other_data, first)

    untraced = _rollout(_scene(tmp_path / "a"), cache, **{TRACES: "off"})
    np.testing.assert_array_equal(untraced, first)  # the same numbers as jit's own trace


def _infer(scene: Path, cache: Path, out: Path) -> str:
    """``physdsl infer --backend map`` in a fresh process (traces kept); its summary table."""
    env = {k: v for k, v in os.environ.items() if k != TRACES}
    done = subprocess.run([sys.executable, "-c", CLI, "--cache-dir", str(cache), "infer",
                           str(scene), "--backend", "map", "-o", str(out)], env=env,
                          capture_output=True, text=True, timeout=600, check=False)
    assert done.returncode == 0, done.stderr
    return (out / "summary.csv").read_text()


def test_a_second_infer_traces_nothing_and_writes_the_same_summary(tmp_path):
    """Every program of a whole ``infer`` (fit, Laplace, posterior pass, intervals) is named the
    same in the next process: it loads them all, and its numbers are the first's."""
    cache, scene = tmp_path / "cache", _scene(tmp_path / "a")
    first = _infer(scene, cache, tmp_path / "out1")
    traced = _traces(cache)
    assert len(traced) >= 3  # the Gauss-Newton program, the rollout, the posterior pass, ...
    assert _infer(scene, cache, tmp_path / "out2") == first
    assert _traces(cache) == traced


def test_added_effect_is_a_new_entry_not_a_stale_hit(tmp_path):
    cache = tmp_path / "cache"
    plain = _rollout(_scene(tmp_path / "plain"), cache)
    before, traced = _entries(cache), _traces(cache)
    drag = _rollout(_scene(tmp_path / "drag", effect=DRAG), cache)
    assert _entries(cache) - before, "the scene with drag found all its programs cached"
    assert _traces(cache) - traced, "the scene with drag found its trace kept"
    np.testing.assert_allclose(plain, _ballistic(TIMES), atol=1e-9)
    np.testing.assert_allclose(drag, _linear_drag(TIMES), atol=1e-8)
    assert np.max(np.abs(drag - plain)) > 0.05  # 0.3 kg/s on 200 g for 0.5 s: centimetres


def test_default_folder_is_the_user_cache_and_off_writes_nothing(tmp_path):
    user_cache = tmp_path / "xdg"
    _rollout(_scene(tmp_path / "a"), "off", XDG_CACHE_HOME=str(user_cache))
    assert not user_cache.exists()
    _rollout(_scene(tmp_path / "a"), None, XDG_CACHE_HOME=str(user_cache))
    assert _entries(user_cache / "physdsl" / "jax")


def test_entries_are_written_atomically(tmp_path, monkeypatch):
    """A writer that dies before the rename leaves no entry (and no temporary file) behind, so
    the next process compiles and writes it instead of reading a truncated one."""
    import physdsl.cache  # noqa: F401 - installs the atomic writes
    from jax._src import lru_cache

    cache = lru_cache.LRUCache(str(tmp_path), max_size=-1)
    cache.put("k1", b"x" * 1000)
    assert cache.get("k1") == b"x" * 1000

    def dies(*_):
        raise KeyboardInterrupt

    monkeypatch.setattr(os, "replace", dies)
    try:
        cache.put("k2", b"y" * 1000)
    except KeyboardInterrupt:
        pass
    assert cache.get("k2") is None
    assert sorted(p.name for p in tmp_path.iterdir()) == ["k1-cache"]
