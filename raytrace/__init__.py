"""Single scattering in homogeneous participating media lit by point lights (Pegoraro & Parker 2009)."""

__version__ = "0.1.0"
