"""navgym: Gymnasium environments for learning-assisted GNSS/INS navigation.

Importing ``navgym`` registers its environments (idempotently) and changes no process-wide
setting. It needs neither torch nor stable-baselines3; those are used by :mod:`agents` only.

:func:`tune_malloc` raises glibc's mmap/trim thresholds, which makes batched NumPy filter steps
several times faster here (:mod:`navgym._malloc`); it is process-wide, so it is opt-in: call it,
or set ``NAVGYM_MALLOPT=1`` to have ``import navgym`` call it. The benchmark commands call it.
"""

import os as _os
from importlib.metadata import PackageNotFoundError as _PackageNotFoundError
from importlib.metadata import version as _version

from navgym._malloc import tune_malloc
from navgym.envs.registration import register_all as _register_all

# The installed distribution's version (``version`` in pyproject.toml); "0+unknown" for a
# source tree on sys.path that is not installed.
try:
    __version__ = _version("navgym")
except _PackageNotFoundError:
    __version__ = "0+unknown"
__all__ = ["__version__", "tune_malloc"]

if _os.environ.get("NAVGYM_MALLOPT", "") not in ("", "0"):
    tune_malloc()
_register_all()
