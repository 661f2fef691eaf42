"""What a participating medium is: coefficients and transmittance (`medium.py`), phase functions
(`phase.py`) and their series (`legendre_moments.py`), and the exponential-integral machinery of
the closed form (`expint.py`). How the air-light is computed lives in `raytrace.methods`."""
from .medium import Medium

__all__ = ["Medium"]
