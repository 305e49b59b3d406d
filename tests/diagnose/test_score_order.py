"""Candidates whose score tests are equal up to rounding are ordered by name, so which one is
refitted first does not change between runs (issue 14: a constant force and a sensor gain scored
1037.6 to the digit, and the round's winner differed between two runs)."""
from __future__ import annotations

from physdsl.diagnose.candidates import Candidate
from physdsl.diagnose.score import ScoreResult
from physdsl.diagnose.screening import score_order


def _scored(kind, name, target, statistic, log_p):
    c = Candidate(kind, name, (target,))
    return c, ScoreResult(c.key, statistic, None, 1, 0.0, 1.0, None, log_p)


def test_equal_scores_keep_the_same_order_whatever_the_rounding():
    strongest = _scored("effect", "quadratic_drag", "ball", 2000.0, -990.0)
    force = lambda eps: _scored("effect", "constant_force", "bob", 1037.6 * (1 + eps), -515.0 * (1 + eps))
    gain = lambda eps: _scored("sensor", "gain", "bob_pos", 1037.6 * (1 + eps), -515.0 * (1 + eps))
    weak = _scored("effect", "linear_drag", "ball", 3.0, -2.0)
    # the two equal candidates, each time with the rounding the other way round
    a = score_order([weak, gain(1e-13), force(0.0), strongest])
    b = score_order([force(1e-13), weak, strongest, gain(0.0)])
    keys = lambda rs: [c.key for c, _ in rs]
    assert keys(a) == keys(b) == ["quadratic_drag@ball", "constant_force@bob", "gain@bob_pos",
                                  "linear_drag@ball"]


def test_a_real_difference_still_decides():
    force = _scored("effect", "constant_force", "bob", 1037.6, -515.0)
    gain = _scored("sensor", "gain", "bob_pos", 1040.0, -516.2)  # 0.2% apart: not rounding
    assert [c.key for c, _ in score_order([force, gain])] == ["gain@bob_pos", "constant_force@bob"]
