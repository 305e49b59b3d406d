"""Beyond the library: a learned residual force where no library effect explains the misfit,
distilled into a law by sparse regression and written as .phys text (docs/diagnosis.md,
"Beyond the library")."""
from . import law_effect  # noqa: F401 - registers the distilled_law physics
from .beyond import Beyond, beyond_library

__all__ = ["Beyond", "beyond_library"]
