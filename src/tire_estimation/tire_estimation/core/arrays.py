"""Array type aliases shared by every module: float64 and int64 NumPy arrays."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

#: a float64 array of any shape
F64 = NDArray[np.float64]
#: an int64 array of any shape (e.g. stamps in ns)
I64 = NDArray[np.int64]
