"""The Quadrotor's GNSS fix model as an element-wise model (filters.core.models.ElementwiseModel)."""

import numpy as np

from navgym.quadrotor.models import M_ROWS, GnssFixModel
from tests.navgym.elementwise import assert_view_equals_copy


def test_the_fix_model_on_the_state_major_points_gives_the_copy_paths_moments():
    assert_view_equals_copy(GnssFixModel(np.diag(np.linspace(1.0, 4.0, M_ROWS))), n=15)
