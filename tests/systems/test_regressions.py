"""Regression: cases where the property test on randomised true parameters once found a guarantee violation.

Both examples transport o1 with r1 and r2 from p2 to p4 with randomised true masses and frictions; an earlier
version clipped a wall by 2.8 cm (the point-world map's hole images were not point-like enough) or let α̂
decrease numerically.
"""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent))
from test_transitions import _property  # noqa: E402

CASE = ("transport", "o1", ("r1", "r2"))
MASS = [1.1762157458337872, 1.1510996763531536, 0.6415685955359947, 2.3789094079426203]


@pytest.mark.parametrize("scales", [[1.15625, 0.25, 1.5, 1.0], [1.5, 0.25, 1.5, 1.0]])
def test_randomised_transport_p2_p4(scales):
    _property(CASE, MASS, scales, 288, 5)
