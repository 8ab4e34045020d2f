"""Contact mechanics (paper §5): FFT boundary elements and Polonsky–Keer CG.

>>> scene = Scene(ds, modulus=1.0)          # doctest: +SKIP
>>> result = scene.solve(mean_pressure=0.01) # doctest: +SKIP
"""

from .curves import curve, gap_distribution, stiffness
from .models import ElasticHalfSpace, Model, PlasticCap
from .scene import Scene, contact
from .solve import solve

__all__ = ["Scene", "solve", "curve", "contact", "stiffness", "gap_distribution", "Model", "ElasticHalfSpace",
           "PlasticCap"]
