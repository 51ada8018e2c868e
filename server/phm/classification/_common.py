"""Small helpers shared by the classification modules (array checks, JSON-safe scalars)."""

from __future__ import annotations

from typing import Any

import numpy as np


def as_2d(X: Any) -> np.ndarray:
    X = np.asarray(X, dtype=np.float64)
    if X.ndim != 2:
        raise ValueError(f"X must be 2-D (n_samples, n_features), got shape {X.shape}")
    return X


def json_scalar(v: Any) -> Any:
    if isinstance(v, bool | int | float | str) or v is None:
        return v
    if isinstance(v, np.generic):
        return v.item()
    return str(v)


def mixed(values: list[Any]) -> bool:
    return len({type(v) for v in values}) > 1
