"""Fault classification: a linear SVM over the feature vector (paper section 4.2, Figure 22).

Time base: one feature vector per faulty flight (flights after detection) per monitored
aircraft, e.g. the 20 residual features ``<unit>.F_*`` of :mod:`server.phm.features` (each
standardised against its healthy baseline, dimensionless). Labels are the fault modes (``TTS``,
``DMD``, ``SE``, ``BDO``, ``MTEL``, ``MTWEAR``, ``REWEAR`` in the campaign manifest,
:data:`server.vocabulary.FAULT_MODES`), but the class list is learned from ``y``; any hashable,
JSON-safe labels (strings, ints) work.

Model
-----
``z = (x - mean) / scale`` (a :class:`sklearn.preprocessing.StandardScaler` fitted on the
training flights; a missing feature ``NaN`` is set to ``z = 0``, the training mean), then one-vs-
rest linear SVM decision values ``d_k = w_k . z + b_k`` (:class:`sklearn.svm.LinearSVC`, primal
solver), predicted class ``argmax_k d_k``, and calibrated probabilities by temperature scaling

    p_k = exp(T d_k) / sum_j exp(T d_j).

The temperature ``T`` is fitted by minimising the log-loss of *out-of-fold* decision values
(group folds, so a degradation pattern is never scored by a model that saw it). Temperature
scaling (Guo et al., 2017) is used rather than a per-class bias or a multinomial logistic
regression on the decision values because (i) it has one parameter, while the effective sample
size of the calibration set is the number of degradation patterns (tens), not the number of
flights (flights of one pattern are strongly correlated), and (ii) it is monotone, so ``argmax
predict_proba == predict`` always and the calibration never changes the SVM's decision.

Each mode also has a probability of its own, ``q_k = sigmoid(a_k d_k + b_k)`` (Platt's scaling
of its one-vs-rest decision value on the same out-of-fold values): "is this mode present",
not "which one mode". The softmax decides the leading mode; ``q`` lets a second mode present at
once join it (:mod:`.modes`).

Prediction is plain numpy over the stored arrays (scaler mean/scale, ``coef_``, ``intercept_``,
``temperature_``), so a model written with :meth:`FaultClassifier.to_dict` and read back with
:meth:`FaultClassifier.from_dict` predicts bit-identically. JSON floats round-trip exactly
(``repr`` of a float64). Never pickle.

Determinism: ``LinearSVC(dual=False)`` uses liblinear's primal trust-region Newton solver, which
draws no random numbers; the folds use ``random_state``. The same data and ``random_state``
give the same JSON.

Modules
-------
:mod:`.config`     :class:`ClassifierConfig`, the hyper-parameters and their defaults
:mod:`.estimator`  :class:`FaultClassifier` (scaler + LinearSVC + temperature), to/from dict
:mod:`.modes`      the set of modes present: the leading one and every other at its threshold
:mod:`.confirmation` when the leading mode is confirmed
:mod:`.split`      :func:`split_by_group` (train/verify by pattern) and the calibration folds
:mod:`.report`     :func:`confusion` and the probability-calibration report
:mod:`.train`      :func:`train_classifier`, the split-fit-verify driver
"""

from server.vocabulary import FAULT_MODES

from .config import CLASSIFIER_DEFAULTS, ClassifierConfig
from .estimator import CLASSIFIER_FORMAT, FaultClassifier
from .report import calibration_report, confusion
from .split import calibration_folds, split_by_group
from .train import Progress, train_classifier

__all__ = [
    "CLASSIFIER_DEFAULTS",
    "CLASSIFIER_FORMAT",
    "FAULT_MODES",
    "ClassifierConfig",
    "FaultClassifier",
    "Progress",
    "calibration_folds",
    "calibration_report",
    "confusion",
    "split_by_group",
    "train_classifier",
]
