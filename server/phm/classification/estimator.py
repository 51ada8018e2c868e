"""The fitted model: standardisation, one-vs-rest linear SVM and temperature calibration.

``z = (x - mean) / scale`` (a :class:`sklearn.preprocessing.StandardScaler` fitted on the
training flights; a missing feature ``NaN`` is set to ``z = 0``, the training mean), then one-vs-
rest linear SVM decision values ``d_k = w_k . z + b_k`` (:class:`sklearn.svm.LinearSVC`, primal
solver), predicted class ``argmax_k d_k``, and calibrated probabilities by temperature scaling
``p_k = exp(T d_k) / sum_j exp(T d_j)``, ``T`` fitted on out-of-fold decision values (group
folds, :func:`~.split.calibration_folds`).

The softmax answers "which one mode": its probabilities compete. Each mode also gets a
probability of its own, "is this mode present", that does not: ``q_k = 1 / (1 + exp(-(a_k d_k
+ b_k)))`` (Platt's sigmoid on the mode's one-vs-rest decision value, a regularised logistic
regression of "row is mode k" on the same out-of-fold ``d_k``). Two modes at once can each
have a high ``q`` (:meth:`FaultClassifier.mode_proba`; the set of modes present,
:mod:`~.modes`).

Prediction is plain numpy over the stored arrays (scaler mean/scale, ``coef_``, ``intercept_``,
``temperature_``), so a model written with :meth:`FaultClassifier.to_dict` and read back with
:meth:`FaultClassifier.from_dict` predicts bit-identically. JSON floats round-trip exactly
(``repr`` of a float64). Never pickle.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Hashable, Mapping, Sequence
from typing import Any

import numpy as np
from scipy.optimize import minimize_scalar
from scipy.special import expit
from sklearn.exceptions import NotFittedError
from sklearn.linear_model import LogisticRegression
from sklearn.preprocessing import StandardScaler
from sklearn.svm import LinearSVC

from ._common import as_2d, json_scalar, mixed
from .config import CLASSIFIER_DEFAULTS, ClassifierConfig
from .split import calibration_folds

__all__ = ["CLASSIFIER_FORMAT", "FaultClassifier"]

CLASSIFIER_FORMAT = "ema-fault-classifier/1"

_D = CLASSIFIER_DEFAULTS


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


def _fit_temperature(D: np.ndarray, yi: np.ndarray,
                     config: ClassifierConfig = CLASSIFIER_DEFAULTS) -> float:
    """Temperature minimising the log-loss; bounded Brent search on ``log T`` (deterministic)
    within ``[temperature_min, temperature_max]``."""
    bounds = (math.log(config.temperature_min), math.log(config.temperature_max))
    res = minimize_scalar(lambda lt: _nll_temperature(D, yi, lt), bounds=bounds,
                          method="bounded", options={"xatol": config.temperature_xatol})
    return float(math.exp(res.x))


def _fit_mode_calibration(D: np.ndarray, yi: np.ndarray,
                          config: ClassifierConfig = CLASSIFIER_DEFAULTS) -> np.ndarray:
    """Per mode ``k``, Platt's ``(a_k, b_k)`` on the rows where ``d_k`` is known: a logistic
    regression of ``yi == k`` on ``d_k``; shape ``(n_classes, 2)``. A mode on every row or on
    none (nothing to tell apart) gets slope 0 and the log-odds of its share."""
    out = np.zeros((D.shape[1], 2))
    for k in range(D.shape[1]):
        ok = np.isfinite(D[:, k])
        target = yi[ok] == k
        if target.all() or not target.any():
            share = (target.sum() + 0.5) / (target.size + 1.0)
            out[k] = 0.0, math.log(share / (1.0 - share))
            continue
        fit = LogisticRegression(C=config.mode_calibration_C).fit(D[ok, k:k + 1], target)
        out[k] = float(fit.coef_[0, 0]), float(fit.intercept_[0])
    return out


def _fit_scaler(X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """StandardScaler (NaN-aware); an all-NaN feature gets mean 0, scale 1."""
    with np.errstate(invalid="ignore", divide="ignore"):  # an all-NaN column is handled below
        sc = StandardScaler().fit(X)
    mean = np.where(np.isfinite(sc.mean_), sc.mean_, 0.0).astype(np.float64)
    scale = np.where(np.isfinite(sc.scale_) & (sc.scale_ > 0), sc.scale_, 1.0).astype(np.float64)
    return mean, scale


def _feature_names(names: Sequence[str] | None, n: int) -> list[str]:
    if names is None:
        return [f"x{i}" for i in range(n)]
    out = [str(f) for f in names]
    if len(out) != n:
        raise ValueError(f"{len(out)} feature names for {n} features")
    return out


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
    mode_calibration_ : ndarray of shape (n_classes, 2) or None
        Each mode's Platt slope and intercept ``(a_k, b_k)`` on its decision value (None for a
        document written before they were kept: :meth:`mode_proba` then refuses).
    error_floor_ : float
        ``e = (errors + 1) / (n + 2)`` of the out-of-fold predictions (Laplace's rule of
        succession: the posterior mean error rate under a uniform prior). The probabilities
        keep that much mass off the leading class, ``P' = (1 - e) P + e (1 - P) / (K - 1)``:
        a classifier right on all of a few hundred held-out rows has shown an error rate below
        about 1 %, not zero, so it may not claim 100 %. The order of the classes is unchanged.
    calibration_ : dict
        How ``T`` was fitted: ``source`` ("out-of-fold" or "in-sample"), ``n_splits``,
        ``n_samples`` and the out-of-fold ``log_loss`` and ``accuracy``.
    n_samples_ : int
        Number of training rows.
    """

    def __init__(self, *, C: float = _D.C, cv: int = _D.cv,
                 class_weight: str | None = _D.class_weight, tol: float = _D.tol,
                 max_iter: int = _D.max_iter, random_state: int | None = _D.random_state
                 ) -> None:
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
        X = as_2d(X)
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
        kw: dict[str, Any] = dict(C=float(self.C), tol=float(self.tol), max_iter=int(self.max_iter),
                  class_weight=self.class_weight, random_state=self.random_state)

        # out-of-fold decision values for the temperature
        folds = calibration_folds(yi, g, int(self.cv), self.random_state)
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
        mode_calibration = _fit_mode_calibration(D_cal, y_cal)
        errors = int(np.sum(np.argmax(D_cal, axis=1) != y_cal))
        error_floor = (errors + 1.0) / (y_cal.size + 2.0)

        self.classes_ = classes
        self.feature_names_in_ = np.asarray(names, dtype=object)
        self.n_features_in_ = int(X.shape[1])
        self.mean_ = mean
        self.scale_ = scale
        self.coef_ = coef
        self.intercept_ = icpt
        self.temperature_ = temperature
        self.mode_calibration_: np.ndarray | None = mode_calibration
        self.error_floor_ = float(error_floor)
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
        X = as_2d(X)
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

    def raw_log_proba(self, X: np.ndarray) -> np.ndarray:
        """``log softmax(temperature_ * d)``: the evidence before the error floor (what the
        chain sums over flights, so its decision is the SVM's)."""
        return _log_softmax(self.temperature_ * self.decision_function(X))

    def apply_error_floor(self, P: np.ndarray) -> np.ndarray:
        """``(1 - e) P + e (1 - P) / (K - 1)``: ``error_floor_`` kept off the leading class."""
        P = np.asarray(P, dtype=np.float64)
        e, k = self.error_floor_, P.shape[-1]
        return (1.0 - e) * P + e * (1.0 - P) / (k - 1)

    def predict_log_proba(self, X: np.ndarray) -> np.ndarray:
        """Log of :meth:`predict_proba`, shape (n_samples, n_classes)."""
        with np.errstate(divide="ignore"):
            return np.log(self.apply_error_floor(np.exp(self.raw_log_proba(X))))

    def predict_proba(self, X: np.ndarray) -> np.ndarray:
        """Calibrated class probabilities: ``softmax(temperature_ * d)``, with ``error_floor_``
        of their mass kept off the leading class.

        Parameters
        ----------
        X : array-like of shape (n_samples, n_features)

        Returns
        -------
        P : ndarray of shape (n_samples, n_classes)
            Rows sum to 1; column order is ``classes_``.
        """
        return np.exp(self.predict_log_proba(X))

    def mode_proba_from_decision(self, D: np.ndarray) -> np.ndarray:
        """Each mode's own probability of being present, ``sigmoid(a_k d_k + b_k)``, from
        decision values ``D`` (n_samples, n_classes); rows need not sum to 1."""
        cal = getattr(self, "mode_calibration_", None)
        if cal is None:
            raise NotFittedError("this classifier keeps no per-mode calibration (a document "
                                 "written before it was fitted): retrain it")
        return expit(cal[:, 0] * np.asarray(D, dtype=np.float64) + cal[:, 1])

    def mode_proba(self, X: np.ndarray) -> np.ndarray:
        """Each mode's own probability of being present (see the module docstring),
        shape (n_samples, n_classes), column order ``classes_``."""
        return self.mode_proba_from_decision(self.decision_function(X))

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
            "classes": [json_scalar(c) for c in self.classes_.tolist()],
            "feature_names": [str(f) for f in self.feature_names_in_],
            "scaler_mean": self.mean_.tolist(),
            "scaler_scale": self.scale_.tolist(),
            "coef": self.coef_.tolist(),
            "intercept": self.intercept_.tolist(),
            "temperature": float(self.temperature_),
            **({} if self.mode_calibration_ is None
               else {"mode_calibration": self.mode_calibration_.tolist()}),
            "error_floor": float(self.error_floor_),
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
        model.classes_ = np.asarray(classes, dtype=object if mixed(classes) else None)
        model.feature_names_in_ = np.asarray(list(d["feature_names"]), dtype=object)
        model.n_features_in_ = len(model.feature_names_in_)
        model.mean_ = np.asarray(d["scaler_mean"], dtype=np.float64)
        model.scale_ = np.asarray(d["scaler_scale"], dtype=np.float64)
        model.coef_ = np.asarray(d["coef"], dtype=np.float64).reshape(len(classes), -1)
        model.intercept_ = np.asarray(d["intercept"], dtype=np.float64)
        model.temperature_ = float(d["temperature"])
        model.mode_calibration_ = (None if d.get("mode_calibration") is None else
                                   np.asarray(d["mode_calibration"], dtype=np.float64))
        # a document written before the floor was kept: none (its probabilities as they were)
        model.error_floor_ = float(d.get("error_floor", 0.0))
        model.calibration_ = dict(d["calibration"])
        model.n_samples_ = int(d["n_samples"])
        k, n = model.coef_.shape
        cal = model.mode_calibration_
        if (model.mean_.shape != (n,) or model.scale_.shape != (n,)
                or model.intercept_.shape != (k,) or n != model.n_features_in_
                or (cal is not None and (cal.shape != (k, 2) or not np.isfinite(cal).all()))):
            raise ValueError("inconsistent array shapes in classifier document")
        return model
