"""Input checks shared by the core: shapes and finiteness, with clear errors."""

from __future__ import annotations

import numpy as np

from .errors import InvalidInputError


def as_batch(values, last_dim: int, name: str) -> np.ndarray:
    """Return ``values`` as a float array of shape [..., last_dim], all finite.

    Raises InvalidInputError naming ``name`` on a wrong trailing dimension or
    on NaN/inf (with the flat index of the first bad sample).
    """
    try:
        arr = np.asarray(values, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InvalidInputError(f"{name}: not numeric ({exc})") from None
    if arr.ndim == 0 or arr.shape[-1] != last_dim:
        raise InvalidInputError(
            f"{name}: expected shape [..., {last_dim}], got {list(arr.shape)}"
        )
    finite = np.isfinite(arr)
    if not finite.all():
        bad = int(np.argmin(finite.all(axis=-1).reshape(-1)))
        raise InvalidInputError(f"{name}: non-finite value (NaN or inf) in sample {bad}")
    return arr


def first_violation(mask: np.ndarray) -> tuple[int, int]:
    """(flat sample index, leg index 0..5) of the first True in a [..., 6] mask."""
    flat = mask.reshape(-1, mask.shape[-1])
    sample = int(np.argmax(flat.any(axis=-1)))
    leg = int(np.argmax(flat[sample]))
    return sample, leg


def unit_vector(value, name: str) -> np.ndarray:
    """A (3,) vector normalised to unit length; InvalidInputError if zero or malformed.

    Args:
        value: the vector (3,), any non-zero length.
        name: the argument's name, for the error message.

    Returns:
        ``value`` / |value| (3,).

    Raises:
        InvalidInputError: ``value`` is not numeric, not finite, not of shape (3,), or has a norm < 1e-12.
    """
    vec = as_batch(value, 3, name)
    if vec.shape != (3,):
        raise InvalidInputError(f"{name}: expected one 3-vector, got shape {list(vec.shape)}")
    if safe_norm(vec) < 1e-12:
        raise InvalidInputError(f"{name}: must be a non-zero vector")
    scaled = vec / np.abs(vec).max()  # |vec|^2 of a finite vector may overflow (1e200) or underflow
    return scaled / np.linalg.norm(scaled)


def safe_norm(vec) -> float:
    """|vec| of a finite vector without overflow or underflow of its squares ([1e200, 0, 0] -> 1e200).

    Args:
        vec: a finite vector (n,).

    Returns:
        The Euclidean norm (inf only if the norm itself exceeds the float range).
    """
    vec = np.asarray(vec, dtype=float)
    scale = float(np.abs(vec).max()) if vec.size else 0.0
    if scale == 0.0 or not np.isfinite(scale):
        return scale
    with np.errstate(over="ignore"):
        return float(scale * np.linalg.norm(vec / scale))
