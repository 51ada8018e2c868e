"""Train a :class:`~server.phm.chain.PhmModel` on a design campaign (paper section 4.1-4.2).

1. Features of every flight (cached beside the manifest).
2. Baselines and detection bands on the healthy design flights (leave-one-aircraft-out bands,
   see :mod:`server.phm.evaluate_detection`).
3. Classifier: one seven-residual vector per faulty flight of the faulty actuator, from the
   flight the fault is established (normalised severity >= ``min_severity`` for progressive
   modes, every post-onset flight for SE/BDO); split 70/30 by degradation pattern and aircraft.
4. Measurement models of the particle filter, per progressive mode: the generic feature with
   the strongest rank correlation to severity on the design flights (chosen here, on design
   data only), and a monotone polynomial h(severity) with its residual noise.

Nothing of the verification campaign is read here.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from typing import Any

import numpy as np
from scipy.stats import spearmanr

from .chain import GENERIC_FEATURES, PROGRESSIVE, MeasurementSpec, PhmModel, classifier_vector
from .classification import train_classifier
from .evaluate_detection import Campaign, fit_detection, load_campaign
from .prognosis import MeasurementModel, PrognoserConfig

__all__ = ["training_rows", "fit_measurement_models", "train_phm_model"]

Progress = Callable[[str, float], None]


def training_rows(campaign: Campaign, baseline: Any, *, min_severity: float = 0.2
                  ) -> dict[str, np.ndarray]:
    """Classifier rows of a campaign: X (n, 7), mode, pattern, aircraft, severity."""
    X, y, groups, aircraft, sev = [], [], [], [], []
    for p in campaign.patterns:
        if p.mode == "healthy" or p.position is None:
            continue
        for r in p.flights:
            if p.onset_flight is not None and r.index < int(p.onset_flight):
                continue
            if p.mode in PROGRESSIVE and r.severity_norm < min_severity:
                continue
            X.append(classifier_vector(baseline.zscores(r.features), p.position))
            y.append(p.mode)
            groups.append(p.id)
            aircraft.append(p.aircraft)
            sev.append(r.severity_norm)
    return {"X": np.asarray(X).reshape(-1, len(GENERIC_FEATURES)), "y": np.asarray(y),
            "groups": np.asarray(groups), "aircraft": np.asarray(aircraft),
            "severity": np.asarray(sev, dtype=np.float64)}


def fit_measurement_models(campaign: Campaign, baseline: Any) -> tuple[
        dict[str, MeasurementSpec], dict[str, Any]]:
    """Per progressive mode: pick the feature most rank-correlated with severity, fit h."""
    specs: dict[str, MeasurementSpec] = {}
    report: dict[str, Any] = {}
    for mode in PROGRESSIVE:
        rows = [(r.severity_norm, classifier_vector(baseline.zscores(r.features), p.position))
                for p in campaign.patterns if p.mode == mode and p.position
                for r in p.flights
                if p.onset_flight is None or r.index >= int(p.onset_flight)]
        if len(rows) < 6:
            continue
        s = np.array([r[0] for r in rows])
        Z = np.array([r[1] for r in rows])
        rhos = {}
        for j, name in enumerate(GENERIC_FEATURES):
            if np.ptp(Z[:, j]) > 0:
                rho = spearmanr(s, Z[:, j]).statistic
                rhos[name] = float(rho) if np.isfinite(rho) else 0.0
        if not rhos:
            continue
        best = max(rhos, key=lambda k: abs(rhos[k]))
        j = GENERIC_FEATURES.index(best)
        model = MeasurementModel.fit(s, Z[:, j])
        specs[mode] = MeasurementSpec(best, model)
        report[mode] = {"feature": best, "spearman": rhos[best], "noise_std": model.noise_std,
                        "n_flights": len(rows), "all_spearman": rhos}
    return specs, report


def train_phm_model(design_dir: str | os.PathLike[str], *, seed: int = 0,
                    jobs: int | None = None, progress: Progress | None = None
                    ) -> tuple[PhmModel, dict[str, Any]]:
    """Fit the whole chain on a design campaign; return the model and a JSON-safe report."""

    def tick(stage: str, frac: float) -> None:
        if progress is not None:
            progress(stage, frac)

    t0 = time.perf_counter()
    tick("features", 0.0)
    campaign = load_campaign(design_dir, jobs=jobs or (os.cpu_count() or 1))
    t_feat = time.perf_counter()
    tick("detection", 0.5)
    detection = fit_detection(campaign)
    t_det = time.perf_counter()
    tick("classifier", 0.6)
    rows = training_rows(campaign, detection.baseline)
    classifier, clf_report = train_classifier(
        rows["X"], rows["y"], rows["groups"], feature_names=list(GENERIC_FEATURES), seed=seed,
        aircraft=rows["aircraft"], progress=lambda st, f: tick(f"classifier:{st}", 0.6 + 0.3 * f))
    t_clf = time.perf_counter()
    tick("measurement", 0.9)
    specs, meas_report = fit_measurement_models(campaign, detection.baseline)
    model = PhmModel(detection.baseline, detection.detector, classifier, specs,
                     PrognoserConfig())
    t_end = time.perf_counter()
    tick("done", 1.0)
    n_flights = sum(len(p.flights) for p in campaign.patterns)
    report = {
        "campaign": {"dir": str(design_dir), "kind": campaign.kind, "seed": campaign.seed,
                     "patterns": len(campaign.patterns), "flights": n_flights,
                     "aircraft": sorted({p.aircraft for p in campaign.patterns})},
        "seed": seed,
        "classifier": clf_report,
        "measurement": meas_report,
        "detector": {"windows": list(detection.detector.windows),
                     "alarm_confidence": detection.detector.alarm_confidence},
        "timings_s": {"features": t_feat - t0, "detection": t_det - t_feat,
                      "classifier": t_clf - t_det, "measurement": t_end - t_clf,
                      "total": t_end - t0},
    }
    return model, report
