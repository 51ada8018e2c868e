"""Reading an RUL distribution's JSON document (:meth:`RulDistribution.to_dict`, the one
shape an RUL has from the filter to the page) without rebuilding the distribution."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

__all__ = ["rul_quantile", "rul_point"]


def rul_quantile(doc: Mapping[str, Any] | None, level: float) -> float | None:
    """The RUL [flight] at quantile ``level`` (a fraction, 0.05 for 5 %); None when the
    document has no such level or the quantile lies beyond the prediction horizon."""
    if not doc:
        return None
    for q, v in doc.get("quantiles") or ():
        if math.isclose(float(q), level):
            return None if v is None else float(v)
    return None


def rul_point(doc: Mapping[str, Any] | None, estimate: str = "median") -> float | None:
    """The point estimate ``"median"`` or ``"mode"`` (the most probable RUL) [flight]; None
    beyond the horizon."""
    if not doc:
        return None
    if estimate == "median":
        return rul_quantile(doc, 0.5)
    if estimate == "mode":
        v = doc.get("most_probable")
        return None if v is None else float(v)
    raise ValueError(f"estimate must be 'median' or 'mode', not {estimate!r}")
