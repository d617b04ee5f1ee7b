"""Symmetric 3×3 tensors stored in icefem's Voigt order: xx yy zz yz xz xy.

Every function takes an array of shape [..., 6] (one row per element) and works row by row.
The off-diagonal entries are tensor components (not engineering shear strains), so a row
``[xx, yy, zz, yz, xz, xy]`` is the matrix ``[[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]]``.
Results have the unit of the input (Pa for stress, dimensionless for strain).
"""

import numpy as np

# Row-major positions of the 3×3 matrix in the Voigt row.
_MATRIX_INDEX = [0, 5, 4, 5, 1, 3, 4, 3, 2]


def to_tensor(voigt):
    """Voigt rows [..., 6] → symmetric matrices [..., 3, 3]."""
    v = np.asarray(voigt, dtype=float)
    if v.shape[-1] != 6:
        raise ValueError(f"expected Voigt rows of 6 values, got shape {v.shape}")
    return v[..., _MATRIX_INDEX].reshape(v.shape[:-1] + (3, 3))


def von_mises(voigt):
    """Von Mises equivalent stress √(3/2 s:s), s the deviator, per row (unit of the input)."""
    v = np.asarray(voigt, dtype=float)
    xx, yy, zz, yz, xz, xy = np.moveaxis(v, -1, 0)
    return np.sqrt(
        0.5 * ((xx - yy) ** 2 + (yy - zz) ** 2 + (zz - xx) ** 2) + 3.0 * (yz**2 + xz**2 + xy**2)
    )


def principal_max(voigt):
    """Largest principal value (eigenvalue) per row (unit of the input); positive = tension."""
    return np.linalg.eigvalsh(to_tensor(voigt))[..., -1]


def frobenius_norm(voigt):
    """Frobenius norm √(A:A) per row, the off-diagonal entries counted twice."""
    v = np.asarray(voigt, dtype=float)
    return np.sqrt(np.sum(v[..., :3] ** 2, axis=-1) + 2.0 * np.sum(v[..., 3:] ** 2, axis=-1))
