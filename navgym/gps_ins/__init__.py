"""GpsIns: tightly coupled GPS/INS on a land vehicle or ship (Carvalho et al. 1997).

One estimation problem, one folder: ``vehicle`` (truth), ``models`` (the filter's pseudo-range
models), ``epoch_kernel`` and ``pseudorange_kernel`` (compiled loops), ``platform`` (the
:class:`~navgym.envs.protocols.Platform`) and ``env`` (the environment classes and card).
"""
