"""Contact mechanics (paper §5): FFT boundary elements and Polonsky–Keer CG.

>>> scene = Scene(ds, modulus=1.0)          # doctest: +SKIP
>>> result = scene.solve(mean_pressure=0.01) # doctest: +SKIP
"""

from .curves import contact, curve, gap_distribution, stiffness
from .scene import Scene
from .solve import solve

__all__ = ["Scene", "solve", "curve", "contact", "stiffness", "gap_distribution"]
