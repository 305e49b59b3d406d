"""Built-in backends; importing this package registers them."""
from . import hmc, map, numpyro_nuts, rmh  # noqa: F401
