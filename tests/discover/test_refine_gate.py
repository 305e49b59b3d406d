"""refine's gate to the learned law, with the learning stubbed: the library's best refit is
handed over for the comparison, the law is only reported without ``allow_learned``, and with it
the next round's scene is the law's, labelled outside the library, data copied beside it."""
from __future__ import annotations

from types import SimpleNamespace

from physdsl.diagnose.refine import _beyond, _Loop
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
