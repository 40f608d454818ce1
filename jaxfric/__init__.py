"""jaxfric: differentiable dynamic friction models in JAX.

Units are SI everywhere: time s, position m, velocity m/s, force N. Importing jaxfric turns
on JAX's float64 mode (see `jaxfric._config` for why and how to opt out).
"""

from . import (
    _config,  # noqa: F401  (x64 policy: must run before any array is made)
    data as data,
    effects as effects,
    export as export,
    motion as motion,
    paper as paper,
)
from ._config import (
    enable_compilation_cache as enable_compilation_cache,
    x64_enabled as x64_enabled,
)
from ._models._base import AbstractFrictionModel as AbstractFrictionModel, SimResult as SimResult
from ._models.gms import GMS as GMS, GMSState as GMSState
from ._models.lugre import LuGre as LuGre, LuGreState as LuGreState
from ._models.tustin import Tustin as Tustin
from ._models.two_state import TwoState as TwoState, TwoStateState as TwoStateState
from ._normalized_shape import NormalizedPaperShape as NormalizedPaperShape
from ._serialize import (
    load_model as load_model,
    model_from_dict as model_from_dict,
    model_to_dict as model_to_dict,
    save_model as save_model,
)
from ._shapes import (
    AbstractShape as AbstractShape,
    PaperShape as PaperShape,
    PowerShape as PowerShape,
)
from ._simulate import (
    simulate as simulate,
    simulate_many as simulate_many,
    StackOverflowWarning as StackOverflowWarning,
)
from ._stribeck import Stribeck as Stribeck
from .motion import reversal_bound as reversal_bound


__version__ = "0.1.0"
