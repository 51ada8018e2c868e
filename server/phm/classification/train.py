"""The training driver: split by pattern, fit on ~70 %, verify on the held-out ~30 %."""

from __future__ import annotations

import time
from collections.abc import Callable, Hashable, Mapping, Sequence
from typing import Any

import numpy as np

from ._common import as_2d, json_scalar
from .config import CLASSIFIER_DEFAULTS
from .estimator import FaultClassifier
from .report import calibration_report, confusion
from .split import split_by_group

__all__ = ["Progress", "train_classifier"]

#: progress callback: (stage name, overall fraction done in [0, 1])
Progress = Callable[[str, float], None]


def train_classifier(X: np.ndarray, y: Sequence[Hashable] | np.ndarray,
                     groups: Sequence[Hashable] | np.ndarray, *, feature_names: Sequence[str],
                     seed: int, test_fraction: float = CLASSIFIER_DEFAULTS.test_fraction,
                     aircraft: Sequence[Hashable] | np.ndarray | None = None,
                     params: Mapping[str, Any] | None = None,
                     progress: Progress | None = None) -> tuple[FaultClassifier, dict[str, Any]]:
    """Fit on ~70 % of the patterns, verify on the other ~30 % (paper section 4.2).

    Parameters
    ----------
    X : array-like of shape (n_samples, n_features)
        One feature vector per faulty flight.
    y : array-like of shape (n_samples,)
        Fault mode of each flight.
    groups : array-like of shape (n_samples,)
        Degradation-pattern id of each flight.
    feature_names : sequence of str, length n_features
    seed : int
        Seed of the split and of the calibration folds.
    test_fraction : float, default 0.3
    aircraft : array-like of shape (n_samples,), optional
        Aircraft of each flight; when given, no aircraft is on both sides (see
        :func:`split_by_group`).
    params : mapping, optional
        Hyper-parameters of :class:`FaultClassifier` (``random_state`` defaults to ``seed``).
    progress : callable(stage, fraction), optional
        Called with a stage name (``"split"``, ``"fit"``, ``"verify"``, ``"done"``) and the
        overall fraction done in [0, 1].

    Returns
    -------
    model : FaultClassifier
        Fitted on the training side.
    report : dict
        JSON-safe: ``seed``, ``test_fraction``, ``n_train``/``n_test`` rows,
        ``train_groups``/``test_groups`` (sorted ids), ``confusion`` on the test side (see
        :func:`confusion`; columns ``model.classes_``), ``train_accuracy``, ``calibration``
        (test mean confidence, accuracy, log-loss, Brier), ``calibration_fit``
        (``model.calibration_``) and ``timings_s`` (split, fit, verify, total).
    """

    def tick(stage: str, frac: float) -> None:
        if progress is not None:
            progress(stage, float(min(max(frac, 0.0), 1.0)))

    t0 = time.perf_counter()
    X = as_2d(X)
    y_arr, g = np.asarray(y), np.asarray(groups)
    if y_arr.shape != (X.shape[0],) or g.shape != (X.shape[0],):
        raise ValueError("y and groups must have one entry per row of X")
    tick("split", 0.0)
    tr, te = split_by_group(g, y=y_arr, aircraft=aircraft, test_fraction=test_fraction,
                            seed=seed)
    if te.size == 0:
        raise ValueError("the split left no test rows; need at least two groups per class")
    t_split = time.perf_counter()
    tick("fit", 0.05)
    hp = {"random_state": seed, **(dict(params) if params else {})}
    model = FaultClassifier(**hp)
    model.fit(X[tr], y_arr[tr], g[tr], feature_names=feature_names,
              progress=lambda f: tick("fit", 0.05 + 0.85 * f))
    t_fit = time.perf_counter()
    tick("verify", 0.9)
    y_hat = model.predict(X[te])
    P = model.predict_proba(X[te])
    index = {c: i for i, c in enumerate(model.classes_.tolist())}
    known = np.array([v in index for v in y_arr[te].tolist()], dtype=bool)
    yi_te = np.array([index[v] for v in y_arr[te][known].tolist()], dtype=np.intp)
    all_classes = model.classes_.tolist() + sorted(
        {v for v in y_arr[te].tolist() if v not in index}, key=str)
    conf = confusion(y_arr[te], y_hat, all_classes)
    t_end = time.perf_counter()
    report: dict[str, Any] = {
        "seed": seed,
        "test_fraction": test_fraction,
        "n_train": int(tr.size),
        "n_test": int(te.size),
        "train_groups": sorted({json_scalar(v) for v in g[tr].tolist()}, key=str),
        "test_groups": sorted({json_scalar(v) for v in g[te].tolist()}, key=str),
        "classes": [json_scalar(c) for c in model.classes_.tolist()],
        "confusion": conf,
        "accuracy": conf["accuracy"],
        "train_accuracy": model.score(X[tr], y_arr[tr]),
        "calibration": calibration_report(P[known], yi_te) if yi_te.size else None,
        "calibration_fit": dict(model.calibration_),
        "timings_s": {"split": t_split - t0, "fit": t_fit - t_split, "verify": t_end - t_fit,
                      "total": t_end - t0},
    }
    tick("done", 1.0)
    return model, report
