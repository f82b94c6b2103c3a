"""The Robot2d fix-and-compass model as an element-wise model (filters.core.models.ElementwiseModel)."""

import numpy as np

from navgym.robot2d.models import FixCompassModel
from tests.navgym.elementwise import assert_view_equals_copy


def test_the_fix_compass_model_on_the_state_major_points_gives_the_copy_paths_moments():
    assert_view_equals_copy(FixCompassModel(np.diag([4.0, 4.0, 9.0, 9.0, 0.01])), n=3)
