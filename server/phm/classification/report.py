"""Verification figures: confusion matrices, per-class rates and probability calibration."""

from __future__ import annotations

from collections.abc import Hashable, Sequence
from typing import Any

import numpy as np

from ._common import json_scalar

__all__ = ["confusion", "calibration_report"]


def confusion(y_true: Sequence[Hashable] | np.ndarray, y_pred: Sequence[Hashable] | np.ndarray,
              classes: Sequence[Hashable] | np.ndarray) -> dict[str, Any]:
    """Confusion matrix and per-class rates (JSON-safe).

    Parameters
    ----------
    y_true, y_pred : array-like of shape (n_samples,)
    classes : sequence of labels
        Row/column order; every label in ``y_true`` and ``y_pred`` must be in it.

    Returns
    -------
    dict
        ``classes``; ``counts`` (n_classes, n_classes) ints, rows = true class, columns =
        predicted; ``rates`` the row-normalised counts (a row with no samples is all 0);
        ``support`` per true class; ``precision`` = TP / predicted and ``recall`` = TP / support
        per class (``None`` when the denominator is 0); ``accuracy`` (total, ``None`` when
        empty); ``balanced_accuracy`` (mean recall over classes with support); ``n``.
    """
    yt, yp = np.asarray(y_true), np.asarray(y_pred)
    if yt.shape != yp.shape or yt.ndim != 1:
        raise ValueError("y_true and y_pred must be 1-D arrays of the same length")
    cls = list(np.asarray(classes).tolist())
    index = {c: i for i, c in enumerate(cls)}
    if len(index) != len(cls):
        raise ValueError("classes contains duplicates")
    k = len(cls)
    counts = np.zeros((k, k), dtype=np.int64)
    try:
        ti = np.array([index[v] for v in yt.tolist()], dtype=np.intp)
        pi = np.array([index[v] for v in yp.tolist()], dtype=np.intp)
    except KeyError as exc:
        raise ValueError(f"label {exc.args[0]!r} not in classes") from None
    np.add.at(counts, (ti, pi), 1)
    support = counts.sum(axis=1)
    predicted = counts.sum(axis=0)
    tp = np.diag(counts)
    rates = np.where(support[:, None] > 0, counts / np.maximum(support, 1)[:, None], 0.0)
    recall = [float(tp[i] / support[i]) if support[i] else None for i in range(k)]
    precision = [float(tp[i] / predicted[i]) if predicted[i] else None for i in range(k)]
    n = int(counts.sum())
    rec = [r for r in recall if r is not None]
    return {
        "classes": [json_scalar(c) for c in cls],
        "counts": counts.tolist(),
        "rates": rates.tolist(),
        "support": support.tolist(),
        "precision": precision,
        "recall": recall,
        "accuracy": float(tp.sum() / n) if n else None,
        "balanced_accuracy": float(np.mean(rec)) if rec else None,
        "n": n,
    }


def calibration_report(P: np.ndarray, yi: np.ndarray) -> dict[str, float]:
    """Mean confidence vs accuracy, log-loss and Brier score of probabilities ``P``."""
    pred = np.argmax(P, axis=1)
    rows = np.arange(yi.size)
    onehot = np.zeros_like(P)
    onehot[rows, yi] = 1.0
    return {
        "mean_confidence": float(np.mean(P[rows, pred])),
        "accuracy": float(np.mean(pred == yi)),
        "log_loss": float(-np.mean(np.log(np.clip(P[rows, yi], 1e-300, None)))),
        "brier": float(np.mean(np.sum((P - onehot) ** 2, axis=1))),
    }
