"""Iridium: a vehicle positioned by Iridium geolocation fixes alone (Benzerrouk 2014, §2.7d, eq. 83).

One estimation problem, one folder: ``constellation`` (the 66 satellites, visibility),
``sensors`` (the fixes' CEP radius and errors), ``models`` (constant-velocity transition, the fix
as a virtual beacon), ``platform`` (the :class:`~navgym.envs.protocols.Platform`) and ``env`` (the
environment classes and card; registered at v2 only).
"""
