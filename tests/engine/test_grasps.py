"""engine.tools.grasps: the candidates ``handover grasps`` lists, from Python."""

from __future__ import annotations

import numpy as np
import pytest

from handover.engine.errors import UsageError
from handover.engine.tools.grasps import DEFAULT_GRIPPER, list_grasps


def test_listing_is_best_quality_first(builtin_kb):
    listing = list_grasps(builtin_kb, "knife")
    quality = listing.candidates.quality[listing.order]
    assert len(listing.order) == len(listing.candidates) > 0
    assert np.all(np.diff(quality) <= 0)
    data = listing.to_dict(limit=3)
    assert [g["id"] for g in data["grasps"]] == [int(k) for k in listing.order[:3]]
    assert data["count"] == len(listing.candidates)
    assert data["gripper"]["id"] == DEFAULT_GRIPPER and data["mesh"]["object"] == "knife"
    assert "seconds" not in data["stats"]


@pytest.mark.parametrize("step", [0.0, -5.0, 361.0])
def test_bad_roll_step_is_a_usage_error(builtin_kb, step):
    with pytest.raises(UsageError, match="roll-step-deg"):
        list_grasps(builtin_kb, "knife", roll_step_deg=step)
