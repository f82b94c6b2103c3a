"""The supervised policy's inputs: per-row feature blocks and global features from observations.

The observation of a RowScale id (v3) has per-row features (width ``m_max``: the normalized
innovation, its running average, the receiver's ``row_cn0``, ``row_reported_sigma``, ...) and
global ones (NIS averages, covariance sizes, ``gnss_n_sv``, ``gnss_hdop``, ``imu_activity``, ...).
:class:`RowFeatures` splits them into ``rows (B, m_max, F_r)`` and ``glob (B, F_g)`` so that one
network with shared weights can be applied to each row.

**Left out**: the policy's own past actions (``log_row_scale``, ``log_process_scale``,
``previous_action``). Labels are collected under a behaviour policy (the regime oracle, or the
plain filter); under the oracle these features carry the previous step's true regimes, which a
model would learn to copy and then not have at run time (exposure bias). What they are needed for
is kept behaviour-independent instead:

* ``z_nom = z sqrt(s)``: the innovation brought back to the nominal ``R`` (``z = v / sqrt(S)``
  with ``S = H P H^T + s R`` under the applied scale ``s``; when ``R`` dominates ``S``,
  ``z_nom^2`` estimates ``R_true / R``, as in innovation-based adaptive estimation, Mehra 1970;
  Mohamed & Schwarz 1999), fed as ``sign(z_nom) log(1 + |z_nom|)``;
* four exponentially weighted averages of ``z_nom^2`` per row (forgetting factors
  :data:`FORGETTING`, Sage & Husa 1969's fading memory; rows not received keep theirs), as
  ``log10``: a noisy row's variance shows over several steps, not in one innovation. The one of
  ``b = 0.5`` is the per-row R-ratio estimate ``r_i`` of the tuned ``row_iae`` baseline
  (:class:`agents.baselines.row_scale.RowInnovationScale`, ``b = 0.5``) run on the same
  observations; ``0.99`` remembers a row's level over ~100 steps;
* ``received``: 1 where the row's innovation is not 0 (a row not received has 0).

Every other feature of the observation is used as it is, per row where it is in
:data:`ROW_FEATURES` with width ``m_max``, else global. The memory is a dict of ``(B, ...)``
arrays (reset per episode) so that data collection and the policy compute the same inputs.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from navgym.envs.features import FeatureSet

__all__ = ["EXCLUDED", "FORGETTING", "ROW_FEATURES", "RowFeatures"]

#: Observation features read per row when present with width ``m_max``.
ROW_FEATURES = ("innovation", "innovation_avg", "row_cn0", "row_reported_sigma", "row_elevation")
#: The policy's own past actions: never inputs (module docstring).
EXCLUDED = ("log_row_scale", "log_process_scale", "previous_action")
#: Forgetting factors ``b`` of the per-row averages ``r <- b r + (1 - b) z_nom^2``.
FORGETTING = (0.5, 0.7, 0.95, 0.99)
#: Derived per-row inputs, after the observation's own per-row features.
DERIVED = ("z_nominal", *(f"log_z2_avg_{b:g}" for b in FORGETTING), "received")


@dataclass(frozen=True)
class RowFeatures:
    """How observations of an env become ``(rows, glob)`` (see the module docstring).

    Attributes:
        m: rows (``m_max``).
        row_names: the observation's per-row features used, in input order (then :data:`DERIVED`).
        global_names: the global features used (scalar or vector), in input order.
        layout: ``{name: size}`` of every feature of the observation, to check an env against.
    """

    m: int
    row_names: tuple[str, ...]
    global_names: tuple[str, ...]
    layout: dict[str, int]
    _slices: dict[str, slice]

    @classmethod
    def of(cls, features: FeatureSet, m: int) -> RowFeatures:
        """The split of ``features`` (an env's ``observation_features``) for ``m`` rows."""
        slices = {n: features.index(n) for n in features.names}
        layout = {n: s.stop - s.start for n, s in slices.items()}
        for need in ("innovation", "log_row_scale"):
            if layout.get(need) != m:
                raise ValueError(f"the observation needs the per-row feature {need!r} of width {m}")
        rows = tuple(n for n in ROW_FEATURES if layout.get(n) == m)
        glob = tuple(n for n in features.names if n not in rows and n not in EXCLUDED)
        return cls(m, rows, glob, layout, slices)

    @property
    def n_row(self) -> int:
        """Inputs per row ``F_r``."""
        return len(self.row_names) + len(DERIVED)

    @property
    def n_global(self) -> int:
        """Global inputs ``F_g``."""
        return sum(self.layout[n] for n in self.global_names)

    @property
    def input_names(self) -> dict[str, list[str]]:
        """``{"row": [...], "global": [...]}`` names of the inputs (for manifests)."""
        return {"row": [*self.row_names, *DERIVED], "global": list(self.global_names)}

    def init_memory(self, B: int) -> dict[str, np.ndarray]:
        """Fresh per-episode memory: the averages of ``z_nom^2`` start at 1 (nominal)."""
        return {"z2": np.ones((B, len(FORGETTING), self.m))}

    def z_nominal(self, obs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(z_nom, received)`` ``(B, m)``: ``z_nom = z sqrt(s)`` (module docstring; 0 if not received)."""
        obs = np.asarray(obs, dtype=np.float64)
        z = obs[:, self._slices["innovation"]]
        return z * np.sqrt(10.0 ** obs[:, self._slices["log_row_scale"]]), z != 0.0

    def __call__(
        self, obs: np.ndarray, memory: dict[str, np.ndarray]
    ) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
        """``rows (B, m, F_r)``, ``glob (B, F_g)`` (float32) and the new memory from ``obs (B, d)``."""
        obs = np.asarray(obs, dtype=np.float64)
        s = self._slices
        z_nom, received = self.z_nominal(obs)
        b = np.asarray(FORGETTING)[None, :, None]
        z2 = np.where(
            received[:, None, :], b * memory["z2"] + (1.0 - b) * (z_nom * z_nom)[:, None, :], memory["z2"]
        )
        cols = [obs[:, s[n]] for n in self.row_names]
        cols += [np.sign(z_nom) * np.log1p(np.abs(z_nom)), *np.log10(np.maximum(z2, 1e-6)).transpose(1, 0, 2)]
        cols.append(received.astype(np.float64))
        rows = np.stack(cols, axis=-1)
        glob = np.concatenate([obs[:, s[n]] for n in self.global_names], axis=1)
        return rows.astype(np.float32), glob.astype(np.float32), {"z2": z2}

    def mismatch(self, layout: dict[str, int]) -> list[str]:
        """Names of the features whose presence or width differs between ``layout`` and this one."""
        names = list(dict.fromkeys([*self.layout, *layout]))
        return [n for n in names if self.layout.get(n) != layout.get(n)]
