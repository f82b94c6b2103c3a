"""Known answer: pykalman's ``robot.mat`` filtered means and covariances (MATLAB reference)."""

from pathlib import Path

import numpy as np
import pytest
import scipy.io

from filters import GaussianState, LinearGaussianModel, kalman

pykalman = pytest.importorskip("pykalman")


def test_kf_reproduces_robot_mat():
    data = scipy.io.loadmat(Path(pykalman.__file__).parent / "datasets" / "data" / "robot.mat")
    A, C, Q, R = data["A"], data["C"], data["Q"], data["R"]
    b = data["b"].T  # (T-1, 5) transition offsets
    d = data["d"][:, 0]
    y = data["y"].T  # (T-1, 2): observation t is y[t-1]; t = 0 has none
    x_filt = data["xfilt"].T
    V_filt = np.asarray([v for v in data["Vfilt"][0]])
    model = LinearGaussianModel(A, C, Q, R, control_matrix=np.eye(5))
    state = GaussianState(data["x0"][:, 0][None], data["P_0"][None])
    np.testing.assert_allclose(state.m[0], x_filt[0], rtol=1e-10)
    for t in range(1, x_filt.shape[0]):
        state = kalman.predict(state, model, u=b[t - 1][None])
        state, info = kalman.update(state, (y[t - 1] - d)[None], model)
        assert info.healthy.all()
        np.testing.assert_allclose(state.m[0], x_filt[t], rtol=1e-8, atol=1e-8)
        np.testing.assert_allclose(state.P[0], V_filt[t], rtol=1e-8, atol=1e-8)
