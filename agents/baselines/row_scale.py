"""RowScale baselines (``*RowScale-v3`` envs): classical row weighting and Q scaling from observations.

The RowScale task (:class:`navgym.envs.tasks.RowScaleTask`) applies one multiplier ``s_i`` to
each measurement row's noise and a scale ``s_q`` to the motion states' process noise; a baseline
computes the scales and :meth:`RowScaleTask.actions_of` maps them to the action (clipped into the
task's ranges). The classical methods here are those a receiver or a post-processing package
applies, reading only the observation:

* from the filter's own statistics (the v2 rules, per row): :class:`RowScaleConstant` (tuned
  constants; ``plain``: every scale 1), :class:`RowChiSquareExclusion` (RAIM-like chi-square test
  and exclusion of the worst rows), :class:`RowInnovationScale` (a per-row innovation-based
  adaptive estimate of R, Mehra 1970 / Mohamed & Schwarz 1999, with a Sage-Husa forgetting
  factor);
* from the **context** a receiver and an IMU report (v3 observations; see the platform cards):
  :class:`CN0Weighting` (the SIGMA-epsilon model ``sigma_i^2 = C 10^(-C/N0_i / 10)``, Hartinger &
  Brunner 1999), :class:`ElevationWeighting` (``sigma_i^2 = a^2 + b^2 / sin^2 el_i``, RTKLIB
  manual eq. E.6.24), :class:`CN0MaskExclusion` (a C/N0 mask, then the chi-square test and
  exclusion on the rows left), :class:`ReportedAccuracyWeighting` (the receiver's own accuracy
  figure per fix, ``sigma_i^2 = c sigma_reported,i^2``), each with an IMU threshold on ``s_q``:
  the motion states' process noise is raised to ``s_q_high`` while the IMU statistic named by
  the platform exceeds ``imu_threshold`` times the feature's upper bound (vibration, manoeuvre),
  else ``s_q_low``. The threshold is a fraction of the bound so that one tuning grid serves
  platforms whose IMU statistics have different units (rad/s on Robot2d, m/s^2 elsewhere).

**Where the context is.** The context baselines read per-row observation features of a fixed
name, which the v3 platforms provide (a feature the env does not have makes the baseline refuse
the env at construction, naming it): :data:`CN0_FEATURE` (each row's reported C/N0 [dB-Hz], 0 on
rows not received), :data:`ELEVATION_FEATURE` (each row's elevation [deg]),
:data:`REPORTED_SIGMA_FEATURE` (each row's reported standard deviation [m]) and
:data:`IMU_FEATURE` (the IMU statistic that rises under vibration and manoeuvres). Rows without a
context value (a compass row, a row not received) keep ``s_i = 1``.

**Timing.** As for every baseline reading the observation, the scales chosen from step k's
observation apply at step k + 1; the reset observation gets the baseline's rule on its context
(the context is a sensor reading, present at reset) and ``s_q_low``.
"""

from __future__ import annotations

import numpy as np

from agents.baselines.base import BaselinePolicy
from filters.innovation_adaptive import chi_square_exclusion
from navgym.envs.base import NavigationAPI
from navgym.envs.tasks import RowScaleTask

__all__ = [
    "CN0_FEATURE",
    "ELEVATION_FEATURE",
    "IMU_FEATURE",
    "REPORTED_SIGMA_FEATURE",
    "CN0MaskExclusion",
    "CN0Weighting",
    "ElevationWeighting",
    "ReportedAccuracyWeighting",
    "RowChiSquareExclusion",
    "RowInnovationScale",
    "RowScaleBaseline",
    "RowScaleConstant",
]

#: Per-row reported C/N0 [dB-Hz] (0 where the row is not received).
CN0_FEATURE = "row_cn0"
#: Per-row elevation [deg] (0 where the row is not received or has none).
ELEVATION_FEATURE = "row_elevation"
#: Per-row reported standard deviation [m] (0 where the receiver reports none).
REPORTED_SIGMA_FEATURE = "row_reported_sigma"
#: The IMU statistic that rises under vibration and manoeuvres.
IMU_FEATURE = "imu_activity"


class RowScaleBaseline(BaselinePolicy):
    """Base of the RowScale baselines: ``scales (B, m)`` and ``s_q (B,)`` mapped to the action.

    Subclasses write :meth:`scales`. The process-noise scale is the IMU threshold rule of the
    module docstring when the subclass declares ``imu_threshold`` among its parameters, else
    the parameter ``s_q``.
    """

    task = "RowScale"

    def setup(self, env: NavigationAPI) -> None:
        task = env.task
        if not isinstance(task, RowScaleTask):
            raise ValueError(f"{type(self).__name__} serves RowScale tasks (v3)")
        self.row_task = task
        self.m = int(task.m_max)
        missing = [f for f in self.context if f not in self.features.names]
        if missing:
            raise ValueError(
                f"{type(self).__name__} reads the context features {list(self.context)}; this env's "
                f"observation has no {missing} (the v3 ids of platforms with that context have them)"
            )
        for k in ("s_q", "s_q_low", "s_q_high", "s_excl", "c"):
            if k in self.params and (self.params[k] <= 0).any():
                raise ValueError(f"{k} must be > 0")

    def scales(self, obs: np.ndarray, memory: dict, fresh: np.ndarray) -> tuple[np.ndarray, dict]:
        """``s_i (B, m)`` and the new memory."""
        raise NotImplementedError

    def process_scale(self, obs: np.ndarray) -> np.ndarray:
        """``s_q (B,)``: the IMU threshold rule or the constant ``s_q``."""
        B = obs.shape[0]
        if "imu_threshold" not in self.params:
            return self.param("s_q", B)
        bound = float(self.features.high[self.features.index(IMU_FEATURE)][0])
        high = self.col(obs, IMU_FEATURE) > self.param("imu_threshold", B) * bound
        return np.where(high, self.param("s_q_high", B), self.param("s_q_low", B))

    def act(self, obs, memory, fresh):
        s, memory = self.scales(obs, memory, fresh)
        scales = np.column_stack([s, self.process_scale(obs)])
        return self.row_task.actions_of(scales), memory

    # ---------------------------------------------------------------------------- helpers
    def z_nominal(self, obs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Innovations brought back to the nominal R, ``z_i sqrt(s_i,applied)``, and the rows received.

        ``innovation`` holds ``v_i / sqrt(S_ii)`` with ``S_ii = (H P H^T)_ii + s_i R_ii`` under the
        scale applied at that step (``log_row_scale``); when ``R`` dominates, ``z_i^2 s_i``
        estimates ``R_true,ii / R_ii`` (as :mod:`agents.baselines.noise_scale` does for one scale).
        """
        z = self.block(obs, "innovation")
        s = 10.0 ** self.block(obs, "log_row_scale")
        return z * np.sqrt(s), z != 0.0

    def received(self, obs: np.ndarray, feature: str) -> np.ndarray:
        """``(B, m)`` rows whose context ``feature`` is reported (non-zero)."""
        return self.block(obs, feature) != 0.0


class RowScaleConstant(RowScaleBaseline):
    """The same ``s_r`` on every row and a constant ``s_q`` (``plain``: both 1)."""

    name = "constant"
    defaults = {"s_r": 1.0, "s_q": 1.0}

    def setup(self, env: NavigationAPI) -> None:
        super().setup(env)
        if (self.params["s_r"] <= 0).any():
            raise ValueError("s_r must be > 0")

    def scales(self, obs, memory, fresh):
        B = obs.shape[0]
        return np.repeat(self.param("s_r", B)[:, None], self.m, axis=1), memory


class RowChiSquareExclusion(RowScaleBaseline):
    """RAIM-like chi-square test of the rows' de-normalized innovations; failing rows get ``s_excl``.

    Each step: :func:`filters.innovation_adaptive.chi_square_exclusion` of ``z_nom`` (with
    ``S = I``) tests ``sum z_nom,i^2`` against the chi-square ``1 - alpha`` quantile with ``n``
    degrees of freedom and excludes the row with the largest ``z_nom^2`` while it fails (at most
    two, one row always kept). Excluded rows get ``s_excl`` at the next step, the others 1;
    ``s_q`` constant. Parameters: ``alpha`` in (0, 1), ``s_excl > 0``, ``s_q > 0``.
    """

    name = "chi_square"
    defaults = {"alpha": 0.01, "s_excl": 1e4, "s_q": 1.0}

    def setup(self, env: NavigationAPI) -> None:
        super().setup(env)
        a = self.params["alpha"]
        if ((a <= 0) | (a >= 1)).any():
            raise ValueError("alpha must lie in (0, 1)")

    def excluded(self, obs: np.ndarray, rows: np.ndarray | None = None) -> np.ndarray:
        """``(B, m)`` rows the chi-square test excludes among ``rows`` (default: every received row)."""
        z, used = self.z_nominal(obs)
        used = used if rows is None else used & rows
        # one call with each episode's alpha, the innovations whitened (S = I)
        return chi_square_exclusion(z, None, used, alpha=self.params["alpha"]).excluded

    def scales(self, obs, memory, fresh):
        B = obs.shape[0]
        s = np.where(self.excluded(obs), self.param("s_excl", B)[:, None], 1.0)
        return np.where(fresh[:, None], 1.0, s), memory


class RowInnovationScale(RowScaleBaseline):
    """Per-row innovation-based adaptive R with a Sage-Husa forgetting factor (the v2 rule per row).

    For each received row ``x_i = z_nom,i^2`` (``z_nom`` as in :meth:`RowScaleBaseline.z_nominal`)
    estimates ``R_true,ii / R_ii`` (Mehra 1970; Mohamed & Schwarz 1999, eq. 20-22); the estimate
    ``r_i <- (1 - d) r_i + d x_i`` with ``d = 1 - b`` (Sage & Husa 1969's fading memory; rows not
    received keep theirs) sets ``s_i = clip(beta r_i, 0.3, 1e4)``. Parameters: ``b`` in [0, 1),
    ``beta > 0``, ``s_q > 0``.
    """

    name = "row_iae"
    defaults = {"b": 0.9, "beta": 1.0, "s_q": 1.0}

    def setup(self, env: NavigationAPI) -> None:
        super().setup(env)
        b = self.params["b"]
        if ((b < 0) | (b >= 1)).any() or (self.params["beta"] <= 0).any():
            raise ValueError("b must lie in [0, 1) and beta be > 0")

    def init_memory(self, B: int) -> dict[str, np.ndarray]:
        return {"r": np.ones((B, self.m))}

    def scales(self, obs, memory, fresh):
        B = obs.shape[0]
        z, used = self.z_nominal(obs)
        used = used & ~fresh[:, None]
        d = 1.0 - self.param("b", B)[:, None]
        r = np.where(used, (1.0 - d) * memory["r"] + d * z * z, memory["r"])
        return np.clip(self.param("beta", B)[:, None] * r, 0.3, 1e4), {"r": r}


class _ImuRule(RowScaleBaseline):
    """A context baseline whose ``s_q`` is the IMU threshold rule (module docstring)."""

    context: tuple[str, ...] = (IMU_FEATURE,)


class CN0Weighting(_ImuRule):
    """C/N0 weighting of each row, the SIGMA-epsilon model (Hartinger & Brunner 1999).

    ``sigma_i^2 = C 10^(-C/N0_i / 10)``: relative to the nominal ``R_ii`` (the variance at a
    reference C/N0 ``cn0_ref``), ``s_i = 10^((cn0_ref - C/N0_i) / 10)``; rows without a C/N0
    keep 1. Parameters: ``cn0_ref`` [dB-Hz], and the IMU rule's ``imu_threshold``,
    ``s_q_low``, ``s_q_high``.
    """

    name = "cn0_weighting"
    context = (CN0_FEATURE, IMU_FEATURE)
    defaults = {"cn0_ref": 45.0, "imu_threshold": 1e9, "s_q_low": 1.0, "s_q_high": 1.0}

    def scales(self, obs, memory, fresh):
        B = obs.shape[0]
        cn0 = self.block(obs, CN0_FEATURE)
        s = 10.0 ** ((self.param("cn0_ref", B)[:, None] - cn0) / 10.0)
        return np.where(cn0 != 0.0, s, 1.0), memory


class ElevationWeighting(_ImuRule):
    """Elevation weighting of each row (RTKLIB manual, eq. E.6.24): ``sigma^2 = a^2 + b^2 / sin^2 el``.

    Relative to the nominal ``R_ii`` taken as the variance at zenith ``a^2 + b^2``:
    ``s_i = c (1 + k^2 / sin^2 el_i) / (1 + k^2)`` with ``k = b / a``; rows without an elevation
    keep 1; ``sin el`` is floored at ``sin 5 deg``. Parameters: ``k >= 0``, ``c > 0`` and the IMU
    rule's.
    """

    name = "elevation_weighting"
    context = (ELEVATION_FEATURE, IMU_FEATURE)
    defaults = {"k": 1.0, "c": 1.0, "imu_threshold": 1e9, "s_q_low": 1.0, "s_q_high": 1.0}

    def scales(self, obs, memory, fresh):
        B = obs.shape[0]
        el = self.block(obs, ELEVATION_FEATURE)
        k2 = self.param("k", B)[:, None] ** 2
        sin = np.maximum(np.sin(np.deg2rad(el)), np.sin(np.deg2rad(5.0)))
        s = self.param("c", B)[:, None] * (1.0 + k2 / sin**2) / (1.0 + k2)
        return np.where(el != 0.0, s, 1.0), memory


class CN0MaskExclusion(RowChiSquareExclusion):
    """A C/N0 mask, then chi-square fault detection and exclusion on the rows left.

    Rows whose C/N0 is below ``mask_dbhz`` get ``s_excl``; the chi-square test and exclusion of
    :class:`RowChiSquareExclusion` runs on the others (excluded ones get ``s_excl`` too); the
    IMU rule sets ``s_q``. Parameters: ``mask_dbhz`` [dB-Hz], ``alpha``, ``s_excl`` and the IMU
    rule's.
    """

    name = "cn0_mask_fde"
    context = (CN0_FEATURE, IMU_FEATURE)
    defaults = {
        "mask_dbhz": 30.0,
        "alpha": 0.01,
        "s_excl": 1e4,
        "imu_threshold": 1e9,
        "s_q_low": 1.0,
        "s_q_high": 1.0,
    }

    def scales(self, obs, memory, fresh):
        B = obs.shape[0]
        cn0 = self.block(obs, CN0_FEATURE)
        weak = (cn0 != 0.0) & (cn0 < self.param("mask_dbhz", B)[:, None])
        bad = weak | (self.excluded(obs, rows=~weak) & ~fresh[:, None])
        return np.where(bad, self.param("s_excl", B)[:, None], 1.0), memory


class ReportedAccuracyWeighting(_ImuRule):
    """Each fix weighted by the receiver's own accuracy figure: ``sigma_i^2 = c sigma_reported,i^2``.

    ``s_i = c sigma_reported,i^2 / sigma_nominal,i^2`` with ``sigma_nominal`` absorbed in ``c``
    [1/m^2] (tuned); rows without a reported figure keep 1. Parameters: ``c > 0`` and the IMU
    rule's.
    """

    name = "reported_accuracy"
    context = (REPORTED_SIGMA_FEATURE, IMU_FEATURE)
    defaults = {"c": 1.0, "imu_threshold": 1e9, "s_q_low": 1.0, "s_q_high": 1.0}

    def scales(self, obs, memory, fresh):
        B = obs.shape[0]
        sig = self.block(obs, REPORTED_SIGMA_FEATURE)
        return np.where(sig != 0.0, self.param("c", B)[:, None] * sig * sig, 1.0), memory
