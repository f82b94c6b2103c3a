"""navgym: Gymnasium environments for learning-assisted GNSS/INS navigation.

Importing ``navgym`` registers its environments (idempotently). It needs neither torch nor
stable-baselines3; those are used by :mod:`agents` only.
"""

from navgym._malloc import tune_malloc as _tune_malloc
from navgym.envs.registration import register_all as _register_all

__version__ = "0.1.0"

_tune_malloc()
_register_all()
