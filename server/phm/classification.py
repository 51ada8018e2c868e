"""Fault classification: a linear SVM over the feature vector (paper section 4.2, Figure 22).

Time base: one feature vector per faulty flight (flights after detection) per monitored
aircraft, e.g. the 19 residual features ``<unit>.F_*`` of :mod:`server.phm.features` (each
standardised against its healthy baseline, dimensionless). Labels are the fault modes (``TTS``,
``DMD``, ``SE``, ``BDO``, ``MTEL``, ``MTWEAR``, ``REWEAR`` in the campaign manifest), but the class
list is learned from ``y``; any hashable, JSON-safe labels (strings, ints) work.

Model
-----
``z = (x - mean) / scale`` (a :class:`sklearn.preprocessing.StandardScaler` fitted on the
training flights; a missing feature ``NaN`` is set to ``z = 0``, the training mean), then one-vs-
rest linear SVM decision values ``d_k = w_k . z + b_k`` (:class:`sklearn.svm.LinearSVC`, primal
solver), predicted class ``argmax_k d_k``, and calibrated probabilities by temperature scaling

    p_k = exp(T d_k) / sum_j exp(T d_j).

The temperature ``T`` is fitted by minimising the log-loss of *out-of-fold* decision values
(group folds, so a degradation pattern is never scored by a model that saw it). Temperature
scaling (Guo et al., 2017) was chosen over a per-class bias or a multinomial logistic regression on
the decision values because (i) it has one parameter, while the effective sample size of the
calibration set is the number of degradation patterns (tens), not the number of flights (flights
of one pattern are strongly correlated), and (ii) it is monotone, so ``argmax predict_proba ==
predict`` always and the calibration never changes the SVM's decision.

Prediction is plain numpy over the stored arrays (scaler mean/scale, ``coef_``, ``intercept_``,
``temperature_``), so a model written with :meth:`FaultClassifier.to_dict` and read back with
:meth:`FaultClassifier.from_dict` predicts bit-identically. JSON floats round-trip exactly
(``repr`` of a float64). Never pickle.

Determinism: ``LinearSVC(dual=False)`` uses liblinear's primal trust-region Newton solver, which
draws no random numbers; the folds use ``random_state``. The same data and ``random_state``
give the same JSON.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Hashable, Mapping, Sequence
from typing import Any

import numpy as np
from scipy.optimize import minimize_scalar
from sklearn.exceptions import NotFittedError
from sklearn.model_selection import StratifiedGroupKFold, StratifiedKFold
from sklearn.preprocessing import StandardScaler
from sklearn.svm import LinearSVC

__all__ = [
    "CLASSIFIER_FORMAT",
    "FAULT_MODES",
    "FaultClassifier",
    "Progress",
    "confusion",
    "split_by_group",
    "train_classifier",
]

CLASSIFIER_FORMAT = "ema-fault-classifier/1"
#: the fault modes of the campaign manifest (the classifier itself learns its classes from y)
FAULT_MODES: tuple[str, ...] = ("TTS", "DMD", "SE", "BDO", "MTEL", "MTWEAR", "REWEAR")
#: progress callback: (stage name, overall fraction done in [0, 1])
Progress = Callable[[str, float], None]

_LOG_T_BOUNDS = (math.log(1e-2), math.log(1e2))


# ------------------------------------------------------------------------------------------------
# numpy kernels (shared by the trained and the loaded model)
# ------------------------------------------------------------------------------------------------


def _standardise(X: np.ndarray, mean: np.ndarray, scale: np.ndarray) -> np.ndarray:
    Z = (X - mean) / scale
    Z[np.isnan(Z)] = 0.0
    return Z


def _log_softmax(S: np.ndarray) -> np.ndarray:
    """Row-wise log-softmax; ``-inf`` entries (classes unavailable) get probability 0."""
    m = np.max(S, axis=1, keepdims=True)
    E = np.exp(S - m)
    return S - m - np.log(np.sum(E, axis=1, keepdims=True))


def _ovr_to_columns(coef: np.ndarray, intercept: np.ndarray, n_classes: int
                    ) -> tuple[np.ndarray, np.ndarray]:
    """LinearSVC gives one row for 2 classes; expand to one (antisymmetric) row per class."""
    if n_classes == 2 and coef.shape[0] == 1:
        return np.vstack([-coef, coef]), np.concatenate([-intercept, intercept])
    return coef, intercept


def _fit_linear(Z: np.ndarray, yi: np.ndarray, *, C: float, tol: float,
                max_iter: int, class_weight: str | None, random_state: int | None
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Fit LinearSVC on the integer labels present in ``yi``.

    Returns ``(coef (k, d), intercept (k,), present (k,) class indices)`` for the ``k``
    classes present in ``yi``.
    """
    present = np.unique(yi)
    if present.size < 2:
        raise ValueError("need at least two classes to fit the classifier")
    svc = LinearSVC(C=C, loss="squared_hinge", penalty="l2", dual=False, tol=tol,
                    max_iter=max_iter, class_weight=class_weight, random_state=random_state)
    svc.fit(Z, yi)
    coef, intercept = _ovr_to_columns(np.asarray(svc.coef_, dtype=np.float64),
                                      np.asarray(svc.intercept_, dtype=np.float64),
                                      present.size)
    return coef, intercept, present


def _nll_temperature(D: np.ndarray, yi: np.ndarray, log_t: float) -> float:
    """Mean negative log-likelihood of ``softmax(exp(log_t) D)`` at the true classes."""
    L = _log_softmax(math.exp(log_t) * D)
    return float(-np.mean(L[np.arange(yi.size), yi]))


def _fit_temperature(D: np.ndarray, yi: np.ndarray) -> float:
    """Temperature minimising the log-loss; bounded Brent search on ``log T`` (deterministic)."""
    res = minimize_scalar(lambda lt: _nll_temperature(D, yi, lt), bounds=_LOG_T_BOUNDS,
                          method="bounded", options={"xatol": 1e-6})
    return float(math.exp(res.x))


# ------------------------------------------------------------------------------------------------
# estimator
# ------------------------------------------------------------------------------------------------


class FaultClassifier:
    """Standardised linear SVM (one-vs-rest) with temperature-calibrated probabilities.

    Parameters
    ----------
    C : float, default 1.0
        SVM regularisation (larger = less regularised), on standardised features.
    cv : int, default 5
        Number of group folds for the out-of-fold decision values used to fit the temperature
        (reduced to the number of groups when fewer).
    class_weight : {None, "balanced"}, default None
        Passed to :class:`sklearn.svm.LinearSVC`.
    tol : float, default 1e-6
        Solver tolerance.
    max_iter : int, default 10000
        Solver iteration limit.
    random_state : int or None, default 0
        Seed of the calibration folds (the primal SVM solver draws no random numbers).

    Attributes
    ----------
    classes_ : ndarray of shape (n_classes,)
        Class labels, sorted (``numpy.unique`` of ``y``).
    feature_names_in_ : ndarray of str, shape (n_features,)
    n_features_in_ : int
    mean_ : ndarray of shape (n_features,)
        Scaler mean (NaN-aware; 0 for an all-NaN feature).
    scale_ : ndarray of shape (n_features,)
        Scaler standard deviation (1 for a constant or all-NaN feature).
    coef_ : ndarray of shape (n_classes, n_features)
        One-vs-rest weights on standardised features (for two classes, ``coef_[0] = -coef_[1]``).
    intercept_ : ndarray of shape (n_classes,)
    temperature_ : float
        Softmax temperature ``T`` (multiplies the decision values).
    calibration_ : dict
        How ``T`` was fitted: ``source`` ("out-of-fold" or "in-sample"), ``n_splits``,
        ``n_samples`` and the out-of-fold ``log_loss`` and ``accuracy``.
    n_samples_ : int
        Number of training rows.
    """

    def __init__(self, *, C: float = 1.0, cv: int = 5, class_weight: str | None = None,
                 tol: float = 1e-6, max_iter: int = 10000, random_state: int | None = 0) -> None:
        self.C = C
        self.cv = cv
        self.class_weight = class_weight
        self.tol = tol
        self.max_iter = max_iter
        self.random_state = random_state

    # -- fitting ---------------------------------------------------------------------------------
    def _validate_params(self) -> None:
        if not (self.C > 0 and math.isfinite(self.C)):
            raise ValueError(f"C must be positive, got {self.C!r}")
        if int(self.cv) < 2:
            raise ValueError(f"cv must be >= 2, got {self.cv!r}")
        if self.class_weight not in (None, "balanced"):
            raise ValueError("class_weight must be None or 'balanced'")

    def fit(self, X: np.ndarray, y: Sequence[Hashable] | np.ndarray,
            groups: Sequence[Hashable] | np.ndarray | None = None, *,
            feature_names: Sequence[str] | None = None,
            progress: Callable[[float], None] | None = None) -> FaultClassifier:
        """Fit scaler, SVM and temperature.

        Parameters
        ----------
        X : array-like of shape (n_samples, n_features)
            Feature vectors; ``NaN`` marks a missing feature (imputed with the training mean).
        y : array-like of shape (n_samples,)
            Fault-mode labels.
        groups : array-like of shape (n_samples,), optional
            Degradation-pattern id of each row; the calibration folds never split a group.
            Without groups, rows are folded individually (optimistic when rows are correlated).
        feature_names : sequence of str, optional
            Names of the ``n_features`` columns (default ``x0, x1, ...``).
        progress : callable(fraction), optional
            Called with the fraction of the fit done (folds, then the final fit).

        Returns
        -------
        self : FaultClassifier
        """
        self._validate_params()
        X = _as_2d(X)
        y_arr = np.asarray(y)
        if y_arr.ndim != 1 or y_arr.shape[0] != X.shape[0]:
            raise ValueError(f"y must have shape ({X.shape[0]},), got {y_arr.shape}")
        if X.shape[0] == 0:
            raise ValueError("cannot fit on zero samples")
        if np.isinf(X).any():
            raise ValueError("X contains infinite values")
        names = _feature_names(feature_names, X.shape[1])
        classes, yi = np.unique(y_arr, return_inverse=True)
        if classes.size < 2:
            raise ValueError("need at least two classes to fit the classifier")
        g = None if groups is None else np.asarray(groups)
        if g is not None and g.shape != (X.shape[0],):
            raise ValueError(f"groups must have shape ({X.shape[0]},), got {g.shape}")
        n_cls = classes.size
        kw = dict(C=float(self.C), tol=float(self.tol), max_iter=int(self.max_iter),
                  class_weight=self.class_weight, random_state=self.random_state)

        # out-of-fold decision values for the temperature
        folds = _calibration_folds(yi, g, int(self.cv), self.random_state)
        n_steps = len(folds) + 1
        if folds:
            D = np.full((X.shape[0], n_cls), -np.inf)
            keep = np.zeros(X.shape[0], dtype=bool)
            for i, (tr, te) in enumerate(folds):
                mean, scale = _fit_scaler(X[tr])
                coef, icpt, present = _fit_linear(_standardise(X[tr], mean, scale), yi[tr],
                                                  **kw)
                D[np.ix_(te, present)] = _standardise(X[te], mean, scale) @ coef.T + icpt
                # a row whose class was absent from the fold's training set cannot be scored
                keep[te] = np.isin(yi[te], present)
                if progress is not None:
                    progress((i + 1) / n_steps)
            D_cal, y_cal = D[keep], yi[keep]
            source = "out-of-fold"
        # final model on all rows
        mean, scale = _fit_scaler(X)
        Z = _standardise(X, mean, scale)
        coef, icpt, _ = _fit_linear(Z, yi, **kw)
        if not folds or y_cal.size == 0:
            D_cal, y_cal = Z @ coef.T + icpt, yi
            source = "in-sample"
        temperature = _fit_temperature(D_cal, y_cal)

        self.classes_ = classes
        self.feature_names_in_ = np.asarray(names, dtype=object)
        self.n_features_in_ = int(X.shape[1])
        self.mean_ = mean
        self.scale_ = scale
        self.coef_ = coef
        self.intercept_ = icpt
        self.temperature_ = temperature
        self.n_samples_ = int(X.shape[0])
        oof_pred = np.argmax(D_cal, axis=1)
        self.calibration_ = {
            "method": "temperature",
            "source": source,
            "n_splits": len(folds),
            "n_samples": int(y_cal.size),
            "log_loss": _nll_temperature(D_cal, y_cal, math.log(temperature)),
            "accuracy": float(np.mean(oof_pred == y_cal)),
        }
        if progress is not None:
            progress(1.0)
        return self

    # -- use ------------------------------------------------------------------------------------
    def _check(self, X: np.ndarray) -> np.ndarray:
        if not hasattr(self, "coef_"):
            raise NotFittedError("FaultClassifier is not fitted yet; call fit or from_dict")
        X = _as_2d(X)
        if X.shape[1] != self.n_features_in_:
            raise ValueError(f"X has {X.shape[1]} features, but FaultClassifier expects "
                             f"{self.n_features_in_}")
        if np.isinf(X).any():
            raise ValueError("X contains infinite values")
        return X

    def decision_function(self, X: np.ndarray) -> np.ndarray:
        """One-vs-rest decision values ``d = coef_ z + intercept_``.

        Parameters
        ----------
        X : array-like of shape (n_samples, n_features)

        Returns
        -------
        D : ndarray of shape (n_samples, n_classes)
            Column ``k`` belongs to ``classes_[k]`` (also for two classes).
        """
        X = self._check(X)
        return _standardise(X, self.mean_, self.scale_) @ self.coef_.T + self.intercept_

    def predict(self, X: np.ndarray) -> np.ndarray:
        """Most likely fault mode, ``classes_[argmax d]``, shape (n_samples,)."""
        D = self.decision_function(X)
        return self.classes_[np.argmax(D, axis=1)]

    def predict_log_proba(self, X: np.ndarray) -> np.ndarray:
        """Log of :meth:`predict_proba`, shape (n_samples, n_classes)."""
        return _log_softmax(self.temperature_ * self.decision_function(X))

    def predict_proba(self, X: np.ndarray) -> np.ndarray:
        """Calibrated class probabilities ``softmax(temperature_ * d)``.

        Parameters
        ----------
        X : array-like of shape (n_samples, n_features)

        Returns
        -------
        P : ndarray of shape (n_samples, n_classes)
            Rows sum to 1; column order is ``classes_``.
        """
        return np.exp(self.predict_log_proba(X))

    def score(self, X: np.ndarray, y: Sequence[Hashable] | np.ndarray) -> float:
        """Accuracy on ``(X, y)``."""
        return float(np.mean(self.predict(X) == np.asarray(y)))

    # -- persistence ----------------------------------------------------------------------------
    def get_params(self, deep: bool = True) -> dict[str, Any]:
        """Hyper-parameters (scikit-learn protocol)."""
        return {"C": self.C, "cv": self.cv, "class_weight": self.class_weight, "tol": self.tol,
                "max_iter": self.max_iter, "random_state": self.random_state}

    def set_params(self, **params: Any) -> FaultClassifier:
        """Set hyper-parameters (scikit-learn protocol)."""
        for k, v in params.items():
            if k not in self.get_params():
                raise ValueError(f"invalid parameter {k!r} for FaultClassifier")
            setattr(self, k, v)
        return self

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe document (``json.dumps`` works directly); exact round trip."""
        if not hasattr(self, "coef_"):
            raise NotFittedError("FaultClassifier is not fitted yet")
        return {
            "format": CLASSIFIER_FORMAT,
            "version": 1,
            "params": self.get_params(),
            "classes": [_json_scalar(c) for c in self.classes_.tolist()],
            "feature_names": [str(f) for f in self.feature_names_in_],
            "scaler_mean": self.mean_.tolist(),
            "scaler_scale": self.scale_.tolist(),
            "coef": self.coef_.tolist(),
            "intercept": self.intercept_.tolist(),
            "temperature": float(self.temperature_),
            "calibration": dict(self.calibration_),
            "n_samples": self.n_samples_,
        }

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> FaultClassifier:
        """Rebuild a fitted classifier from :meth:`to_dict` output."""
        if d.get("format") != CLASSIFIER_FORMAT or d.get("version") != 1:
            raise ValueError(f"not a {CLASSIFIER_FORMAT} (version 1) document")
        model = cls(**dict(d["params"]))
        classes = list(d["classes"])
        model.classes_ = np.asarray(classes, dtype=object if _mixed(classes) else None)
        model.feature_names_in_ = np.asarray(list(d["feature_names"]), dtype=object)
        model.n_features_in_ = len(model.feature_names_in_)
        model.mean_ = np.asarray(d["scaler_mean"], dtype=np.float64)
        model.scale_ = np.asarray(d["scaler_scale"], dtype=np.float64)
        model.coef_ = np.asarray(d["coef"], dtype=np.float64).reshape(len(classes), -1)
        model.intercept_ = np.asarray(d["intercept"], dtype=np.float64)
        model.temperature_ = float(d["temperature"])
        model.calibration_ = dict(d["calibration"])
        model.n_samples_ = int(d["n_samples"])
        k, n = model.coef_.shape
        if (model.mean_.shape != (n,) or model.scale_.shape != (n,)
                or model.intercept_.shape != (k,) or n != model.n_features_in_):
            raise ValueError("inconsistent array shapes in classifier document")
        return model


# ------------------------------------------------------------------------------------------------
# helpers
# ------------------------------------------------------------------------------------------------


def _as_2d(X: Any) -> np.ndarray:
    X = np.asarray(X, dtype=np.float64)
    if X.ndim != 2:
        raise ValueError(f"X must be 2-D (n_samples, n_features), got shape {X.shape}")
    return X


def _feature_names(names: Sequence[str] | None, n: int) -> list[str]:
    if names is None:
        return [f"x{i}" for i in range(n)]
    out = [str(f) for f in names]
    if len(out) != n:
        raise ValueError(f"{len(out)} feature names for {n} features")
    return out


def _fit_scaler(X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """StandardScaler (NaN-aware); an all-NaN feature gets mean 0, scale 1."""
    with np.errstate(invalid="ignore", divide="ignore"):  # an all-NaN column is handled below
        sc = StandardScaler().fit(X)
    mean = np.where(np.isfinite(sc.mean_), sc.mean_, 0.0).astype(np.float64)
    scale = np.where(np.isfinite(sc.scale_) & (sc.scale_ > 0), sc.scale_, 1.0).astype(np.float64)
    return mean, scale


def _calibration_folds(yi: np.ndarray, groups: np.ndarray | None, cv: int,
                       random_state: int | None) -> list[tuple[np.ndarray, np.ndarray]]:
    """Stratified (group) folds; empty when fewer than two folds are possible."""
    shuffle = random_state is not None
    if groups is not None:
        n_splits = min(cv, np.unique(groups).size)
        if n_splits < 2:
            return []
        splitter: Any = StratifiedGroupKFold(n_splits=n_splits, shuffle=shuffle,
                                             random_state=random_state if shuffle else None)
        splits = splitter.split(np.zeros((yi.size, 1)), yi, groups)
    else:
        n_splits = min(cv, int(np.bincount(yi).min()))
        if n_splits < 2:
            return []
        splitter = StratifiedKFold(n_splits=n_splits, shuffle=shuffle,
                                   random_state=random_state if shuffle else None)
        splits = splitter.split(np.zeros((yi.size, 1)), yi)
    return [(tr, te) for tr, te in splits if np.unique(yi[tr]).size >= 2 and te.size]


def _json_scalar(v: Any) -> Any:
    if isinstance(v, bool | int | float | str) or v is None:
        return v
    if isinstance(v, np.generic):
        return v.item()
    return str(v)


def _mixed(values: list[Any]) -> bool:
    return len({type(v) for v in values}) > 1


# ------------------------------------------------------------------------------------------------
# split, confusion, training
# ------------------------------------------------------------------------------------------------


def _union_units(groups: np.ndarray, aircraft: np.ndarray | None) -> np.ndarray:
    """Split unit of each row: the group, or the connected component of groups that share an
    aircraft (so neither a group nor an aircraft can appear on both sides)."""
    _, gi = np.unique(groups, return_inverse=True)
    if aircraft is None:
        return gi
    _, ai = np.unique(aircraft, return_inverse=True)
    n_g = int(gi.max()) + 1
    parent = list(range(n_g + int(ai.max()) + 1))

    def find(a: int) -> int:
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return a

    for g_, a_ in zip(gi.tolist(), ai.tolist(), strict=True):
        ra, rb = find(g_), find(n_g + a_)
        if ra != rb:
            parent[max(ra, rb)] = min(ra, rb)
    roots = np.array([find(g_) for g_ in gi.tolist()])
    return np.unique(roots, return_inverse=True)[1]


def split_by_group(groups: Sequence[Hashable] | np.ndarray, *,
                   y: Sequence[Hashable] | np.ndarray | None = None,
                   aircraft: Sequence[Hashable] | np.ndarray | None = None,
                   test_fraction: float = 0.3, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Train/test split by degradation pattern; no group on both sides.

    The split unit is the group (pattern id); with ``aircraft`` it is the connected component of
    patterns sharing an aircraft, so no aircraft appears on both sides either. With ``y`` the
    split is stratified: the units of each class (its majority label) are shuffled and
    ``round(test_fraction * n)`` of them, at least 1 and at most ``n - 1``, go to the test side,
    so every class with at least two units has units on both sides (a class with a single
    unit stays in training). Without ``y`` the same rule is applied to all units at once.

    Parameters
    ----------
    groups : array-like of shape (n_samples,)
        Pattern id of each row.
    y : array-like of shape (n_samples,), optional
        Class labels for stratification.
    aircraft : array-like of shape (n_samples,), optional
        Aircraft (tail) of each row.
    test_fraction : float, default 0.3
        Fraction of the units per class held out, in (0, 1).
    seed : int
        Seed of the shuffle (``numpy.random.default_rng``).

    Returns
    -------
    train_idx, test_idx : ndarray of int, sorted
        Row indices of the two sides; together they are ``arange(n_samples)``.
    """
    if not 0.0 < test_fraction < 1.0:
        raise ValueError(f"test_fraction must be in (0, 1), got {test_fraction!r}")
    g = np.asarray(groups)
    if g.ndim != 1:
        raise ValueError("groups must be 1-D")
    n = g.size
    if n == 0:
        return np.zeros(0, dtype=np.intp), np.zeros(0, dtype=np.intp)
    a = None if aircraft is None else np.asarray(aircraft)
    if a is not None and a.shape != g.shape:
        raise ValueError("aircraft must have the same shape as groups")
    unit = _union_units(g, a)
    n_units = int(unit.max()) + 1
    if y is None:
        unit_class = np.zeros(n_units, dtype=np.intp)
    else:
        y_arr = np.asarray(y)
        if y_arr.shape != g.shape:
            raise ValueError("y must have the same shape as groups")
        _, yi = np.unique(y_arr, return_inverse=True)
        counts = np.zeros((n_units, int(yi.max()) + 1), dtype=np.intp)
        np.add.at(counts, (unit, yi), 1)
        unit_class = np.argmax(counts, axis=1)  # majority label (ties: lowest class index)
    rng = np.random.default_rng(seed)
    test_unit = np.zeros(n_units, dtype=bool)
    for c in np.unique(unit_class):
        members = np.flatnonzero(unit_class == c)
        k = members.size
        if k < 2:
            continue
        n_test = min(max(int(round(test_fraction * k)), 1), k - 1)
        test_unit[rng.permutation(members)[:n_test]] = True
    is_test = test_unit[unit]
    return np.flatnonzero(~is_test), np.flatnonzero(is_test)


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
        "classes": [_json_scalar(c) for c in cls],
        "counts": counts.tolist(),
        "rates": rates.tolist(),
        "support": support.tolist(),
        "precision": precision,
        "recall": recall,
        "accuracy": float(tp.sum() / n) if n else None,
        "balanced_accuracy": float(np.mean(rec)) if rec else None,
        "n": n,
    }


def _calibration_report(P: np.ndarray, yi: np.ndarray) -> dict[str, float]:
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


def train_classifier(X: np.ndarray, y: Sequence[Hashable] | np.ndarray,
                     groups: Sequence[Hashable] | np.ndarray, *, feature_names: Sequence[str],
                     seed: int, test_fraction: float = 0.3,
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
    X = _as_2d(X)
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
        "train_groups": sorted({_json_scalar(v) for v in g[tr].tolist()}, key=str),
        "test_groups": sorted({_json_scalar(v) for v in g[te].tolist()}, key=str),
        "classes": [_json_scalar(c) for c in model.classes_.tolist()],
        "confusion": conf,
        "accuracy": conf["accuracy"],
        "train_accuracy": model.score(X[tr], y_arr[tr]),
        "calibration": _calibration_report(P[known], yi_te) if yi_te.size else None,
        "calibration_fit": dict(model.calibration_),
        "timings_s": {"split": t_split - t0, "fit": t_fit - t_split, "verify": t_end - t_fit,
                      "total": t_end - t0},
    }
    tick("done", 1.0)
    return model, report
