"""Every registered id reproduces its stored traces (``traces.py``) to rounding.

The traces were recorded before the platform skeleton refactoring; a change that alters an id's
observations, rewards, episode ends or position errors fails here (re-record only with a
version bump of the ids it changes).
"""

import numpy as np
import pytest

from navgym.envs.registration import ENVIRONMENTS
from tests.navgym.envs import traces


@pytest.mark.parametrize("env_id", [e[0] for e in ENVIRONMENTS])
def test_traces_equal_to_rounding(env_id):
    ref = np.load(traces.path(env_id))
    new = traces.run(env_id)
    assert set(new) == set(ref.files)
    for key, a in new.items():
        b = ref[key]
        assert a.shape == b.shape, key
        if key.endswith(("terminated", "truncated")):
            np.testing.assert_array_equal(a, b, err_msg=key)
        elif key.endswith("obs"):
            np.testing.assert_allclose(a, b, rtol=1e-5, atol=1e-6, err_msg=key)
        else:
            np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-9, err_msg=key)
