"""GpsIns: tightly coupled GPS/INS on a land vehicle or ship (Carvalho et al. 1997).

One estimation problem, one folder: ``vehicle`` (truth), ``episodes`` (the episodes simulated
at reset, with the v2 events), ``models`` (the filter's pseudo-range models), ``epoch_kernel``,
``gdop_kernel`` and ``pseudorange_kernel`` (compiled loops), ``features`` (its observation
features), ``platform`` (the :class:`~navgym.envs.protocols.Platform`), ``env`` and ``env_v2``
(the environment classes and card) and ``env_ids`` (its registry entries).
"""
