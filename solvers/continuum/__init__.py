"""Continuum solvers: scikit-fem (heat; static elasticity and modes) and FiPy (heat).

FiPy reads its solver suite from FIPY_SOLVERS when it is first imported; this package defaults it to
scipy (set before any module of the package imports FiPy), unless the user chose another.
"""

import os

os.environ.setdefault("FIPY_SOLVERS", "scipy")
