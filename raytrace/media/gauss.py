"""The Gauss–Legendre pair the adaptive rules compare: 10 and 20 nodes on [-1, 1] (a panel is accepted
where the two agree; docs/error_bounds.md, "quadrature")."""
import numpy as np

N10, W10 = np.polynomial.legendre.leggauss(10)
N20, W20 = np.polynomial.legendre.leggauss(20)
