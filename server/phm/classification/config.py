"""Hyper-parameters of the fault classifier and of its training (one frozen record).

:data:`CLASSIFIER_DEFAULTS` holds the defaults of :class:`~.estimator.FaultClassifier`'s
keyword parameters, of its temperature search and of the verification split of
:func:`~.train.train_classifier`.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["ClassifierConfig", "CLASSIFIER_DEFAULTS"]


@dataclass(frozen=True)
class ClassifierConfig:
    """Tuning of the standardised linear SVM, its calibration and its train/verify split."""

    #: -, SVM regularisation on standardised features (larger = less regularised); liblinear's
    #: default, on z-scored features
    C: float = 1.0
    #: group folds of the out-of-fold decision values the temperature is fitted on (fewer when
    #: there are fewer groups): a pattern is never scored by a model that saw it
    cv: int = 5
    #: None or "balanced", passed to LinearSVC: None weighs the rows as sampled, "balanced"
    #: reweights each class inversely to its row count
    class_weight: str | None = None
    #: -, liblinear's stopping tolerance: tight, so that the weights (and the JSON) do not
    #: depend on where the solver happened to stop
    tol: float = 1e-6
    #: solver iterations allowed, far more than the primal Newton solver needs
    max_iter: int = 10000
    #: seed of the calibration folds (the primal solver draws no random numbers)
    random_state: int | None = 0
    #: -, smallest and largest softmax temperature searched (bounded Brent search on log T):
    #: two decades either side of 1 hold any useful scaling of the decision values
    temperature_min: float = 1e-2
    temperature_max: float = 1e2
    #: -, absolute tolerance of that search on log T
    temperature_xatol: float = 1e-6
    #: -, inverse L2 penalty on the slope of each mode's own calibration (Platt's sigmoid on
    #: its one-vs-rest decision value, :mod:`~.estimator`): out-of-fold values that separate a
    #: mode perfectly would otherwise fit an infinite slope, a claim of 0 or 1 that a fault
    #: beside another one (never in the training rows) would inherit. scikit-learn's default
    mode_calibration_C: float = 1.0
    #: -, fraction of the degradation patterns (per class) held out for verification: the
    #: paper's 70 % / 30 % split
    test_fraction: float = 0.3


#: the defaults used throughout the package
CLASSIFIER_DEFAULTS = ClassifierConfig()
