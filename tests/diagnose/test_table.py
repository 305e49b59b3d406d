"""The diagnosis table's p-values: an underflowed p shows its order of magnitude, not 0."""
import numpy as np

from physdsl.diagnose.diagnosis import Ranked, p_value_text
from physdsl.diagnose.score import chi2_logsf


def _ranked(statistic, dof=1):
    log_p = float(chi2_logsf(statistic, dof))
    return Ranked(rank=1, kind="effect", effect="linear_drag", target="ball", statistic=statistic,
                  p_value=float(np.exp(log_p)), dof=dof, log_p=log_p)


def test_underflowed_p_values_show_their_magnitude():
    assert p_value_text(_ranked(7.5)) == "0.0062"
    assert _ranked(1658.1).p_value == 0.0
    text = p_value_text(_ranked(1658.1))  # chi2(1) tail at 1658: about 1e-363
    assert text.startswith("<1e-") and 355 < int(text[4:]) < 370, text
