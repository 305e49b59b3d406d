"""refine's gate to the learned law, with the learning stubbed: the library's best refit is
handed over for the comparison, the law is only reported without ``allow_learned``, and with it
the next round's scene is the law's, labelled outside the library, data copied beside it."""
from __future__ import annotations

from types import SimpleNamespace

import pytest

from physdsl.diagnose.refine import _beside, _beyond, _Loop, half_explained
from physdsl.discover.beyond import Beyond

LAW_SCENE = "# the law's scene text\n"


def _setup(tmp_path, allow):
    (tmp_path / "user").mkdir()
    user = tmp_path / "user" / "scene.phys"
    user.write_text("scene s {}\n")
    (tmp_path / "user" / "data.csv").write_text("t,body,x,y,z\n")
    res = Beyond("ball", "body", 3.0, 1.1, None, None, True, "outside the library: ...",
                 law={"terms": ["v_sqrt_speed"], "rms": 1.0, "log_z": None, "in_library": False},
                 scene_text=LAW_SCENE)
    seen = []

    def beyond(model, idata, report, outdir, library, echo):
        seen.append(library)
        return res

    loop = _Loop(tmp_path / "out", user, {}, lambda s: None, beyond=beyond, allow_learned=allow)
    now = SimpleNamespace(idata=None, report=SimpleNamespace(rms_sigma=3.0, consistent=False),
                          elpd=1.0, log_z=None)
    rows = [SimpleNamespace(rms_after=None, key="wind@ball", log_evidence=None),
            SimpleNamespace(rms_after=2.5, key="quadratic_drag@ball", log_evidence=10.0),
            SimpleNamespace(rms_after=2.9, key="linear_drag@ball", log_evidence=8.0)]
    current = tmp_path / "out" / "round-0" / "scene.phys"
    return loop, now, SimpleNamespace(ranking=rows), current, seen


def test_without_the_flag_the_law_is_reported_not_added(tmp_path):
    loop, now, diag, current, seen = _setup(tmp_path, allow=False)
    out = _beyond(loop, 0, current, None, now, diag)
    assert isinstance(out, str) and "not added: pass --allow-learned" in out
    assert seen == [{"effect": "quadratic_drag@ball", "rms": 2.5, "log_z": 10.0}]
    assert not (tmp_path / "out" / "round-1").exists() and loop.rounds == []


def test_with_the_flag_the_next_round_is_the_law_labelled_outside_the_library(tmp_path):
    loop, now, diag, current, _ = _setup(tmp_path, allow=True)
    nxt = _beyond(loop, 0, current, None, now, diag)
    assert nxt == tmp_path / "out" / "round-1" / "scene.phys"
    assert nxt.read_text() == LAW_SCENE and (nxt.parent / "data.csv").exists()
    assert loop.change["action"] == "learned"
    assert loop.change["added"] == {"effect": "distilled_law", "target": "ball",
                                    "outside_library": True, "terms": ["v_sqrt_speed"]}
    assert loop.rounds[-1].verdict == "outside the library: ..."


def _winner(before, after, consistent=False):
    return SimpleNamespace(rms_before=before, rms_after=after, consistent_after=consistent,
                           key="constant_force@bob", log_evidence=-40.0)


def test_a_force_is_learned_beside_a_winner_only_where_it_half_explains():
    # the cubic spring's round 1: constant force 4.26σ -> 2.59σ removes 67% of RMS² - 1
    assert half_explained(1, _winner(4.26, 2.59))
    assert not half_explained(0, _winner(4.26, 2.59))  # the library's first word
    assert not half_explained(1, _winner(4.26, 2.59, consistent=True))  # no systematic residual
    assert not half_explained(1, _winner(5.62, 1.3))  # removes 96%: the library is getting there
    assert not half_explained(1, _winner(1.0, 0.9))  # nothing left to explain
    assert half_explained(2, _winner(3.0, 2.9))


def _beside_setup(tmp_path, allow, library_wins=False, winner=None):
    loop, now, diag, current, seen = _setup(tmp_path, allow)
    w = winner or _winner(3.0, 2.5)
    diag.winner = w
    res = loop.beyond(None, None, None, None, None, None)
    res.library_wins = library_wins
    seen.clear()
    return loop, now, diag, current, seen, w


@pytest.mark.parametrize("allow", [False, True])
def test_beside_the_winner_the_law_enters_only_with_the_flag_and_the_evidence(tmp_path, allow):
    loop, now, diag, current, seen, w = _beside_setup(tmp_path, allow)
    out = _beside(loop, 1, current, None, now, diag)
    # the library's side of the comparison is the winner, not the lowest RMS of the ranking
    assert seen == [{"effect": "constant_force@bob", "rms": 2.5, "log_z": -40.0}]
    if allow:
        assert out == tmp_path / "out" / "round-2" / "scene.phys"
        assert out.read_text() == LAW_SCENE and loop.change["action"] == "learned"
    else:
        assert isinstance(out, str) and "not added: pass --allow-learned" in out
        assert not (tmp_path / "out" / "round-2").exists() and loop.rounds == []


def test_beside_the_winner_a_tie_keeps_the_library_effect(tmp_path):
    loop, now, diag, current, seen, _ = _beside_setup(tmp_path, True, library_wins=True)
    out = _beside(loop, 1, current, None, now, diag)
    assert isinstance(out, str) and "not added" not in out
    assert not (tmp_path / "out" / "round-2").exists() and loop.rounds == []


def test_no_training_where_the_winner_explains_the_round(tmp_path):
    loop, now, diag, current, seen, _ = _beside_setup(tmp_path, True, winner=_winner(5.62, 1.3))
    assert _beside(loop, 1, current, None, now, diag) is None and seen == []
