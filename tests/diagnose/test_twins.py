"""Twins (candidates whose score columns coincide at the off value) are refitted on their own
where their representative's refit did not explain the misfit: they act alike only at zero
strength (a sliding ball is slowed alike by quadratic drag and by sliding friction until the
friction has spun it up to rolling)."""
from __future__ import annotations

import numpy as np

from physdsl.diagnose.diagnosis import Ranked
from physdsl.diagnose.ordering import doubtful_twin, mark_twins


def _rows():
    rows = [Ranked(0, "effect", e, t, s, 0.0, 1) for e, t, s in
            [("quadratic_drag", "ball", 9.0), ("contact_friction", "floor,ball", 9.0),
             ("contact_friction", "floor,*", 9.0), ("constant_force", "ball", 8.0)]]
    d = np.array([1.0, 0.0])
    mark_twins(rows, {"quadratic_drag@ball": d, "contact_friction@floor,ball": -d,
                      "contact_friction@floor,*": d, "constant_force@ball": np.array([0.6, 0.8])})
    return rows


def test_a_twin_of_another_law_is_refitted_where_its_representative_left_a_pattern():
    rows = _rows()
    drag, friction, material, push = rows
    assert friction.same_as == "quadratic_drag@ball" and push.same_as is None
    assert not doubtful_twin(friction, rows)  # the representative is not refitted yet
    drag.rms_after, drag.consistent_after = 6.8, False  # its refit left systematic residuals
    assert doubtful_twin(friction, rows)
    drag.rms_after, drag.consistent_after = 0.98, True  # it explains the misfit: one refit serves
    assert not doubtful_twin(friction, rows)
    drag.consistent_after, drag.note = False, "refit failed: Matrix is not positive definite"
    assert not doubtful_twin(friction, rows)  # a failed refit says nothing of the twins


def test_a_twin_of_the_same_law_stays_skipped():
    """A material candidate and its pair (one law, one coefficient) are one refit whatever it gives."""
    rows = [Ranked(0, "effect", "contact_friction", t, 9.0, 0.0, 1) for t in ("floor,*", "floor,a")]
    mark_twins(rows, {"contact_friction@floor,*": np.array([1.0]), "contact_friction@floor,a": np.array([1.0])})
    rows[0].rms_after, rows[0].consistent_after = 5.0, False
    assert rows[1].same_as == "contact_friction@floor,*" and not doubtful_twin(rows[1], rows)
