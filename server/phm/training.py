"""Train a :class:`~server.phm.chain.PhmModel` on a design campaign (paper section 4.1-4.2).

1. Features of every flight: the campaign arrives with them (:mod:`server.campaigns` reads
   a campaign directory, :func:`server.campaigns.train_from_directory` trains on one).
2. Baselines and detection bands on the healthy design flights (leave-one-aircraft-out bands,
   see :mod:`server.phm.detection_model`).
3. Classifier: one seven-residual vector per faulty flight of the faulty actuator, from the
   detector's first alarm on (what the classifier sees at run time); split 70/30 by
   degradation pattern (each pattern is one aircraft's run; the separate verification
   campaign, on other aircraft, tests generalisation to unseen aircraft).
4. Measurement models of the particle filter, per progressive mode: the mode's own feature
   (paper Table 1) as a physical-unit residual, and a monotone polynomial h(severity) with
   its residual noise.
5. Sensor model (:mod:`server.phm.sensor_health`): healthy bands of every channel's
   signal-quality figures, and from the campaign's sensor study what a noisier sensor does
   to each feature.

Nothing of the verification campaign is read here.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterator
from dataclasses import asdict, dataclass, replace
from typing import Any

import numpy as np
from scipy.stats import spearmanr

from .chain import (
    GENERIC_FEATURES,
    OWN_FEATURE,
    PROGRESSIVE,
    ActuatorHealth,
    MeasurementSpec,
    PhmModel,
    classifier_vector,
    measurement_values,
    self_residuals,
    surface_of,
)
from .classification import train_classifier
from .classification.crosstalk import fit_crosstalk
from .dataset import Campaign, FlightRecord, Pattern, healthy_flights
from .detection import UNITS, DetectionResult, update_units
from .detection_model import fit_detection
from .features import FlightFeatures
from .prognosis import MeasurementModel, PrognoserConfig
from .prognosis.config import RATE_WEIGHTINGS, RateWeighting
from .prognosis.degradation import MIN_LEVEL_GAP
from .prognosis.hypotheses import RateHypothesis, band_names, fit_rate_hypotheses
from .season import SeasonalClimate, StressClock, day_of_year
from .sensor_health import fit_sensor_model

__all__ = ["TrainingConfig", "TRAINING", "training_rows", "fit_measurement_models",
           "sensor_study_pairs", "train_phm_model"]

Progress = Callable[[str, float], None]
@dataclass(frozen=True)
class TrainingConfig:
    """Tuned constants of training (reasons and the alternatives scored: docs/TUNING.md)."""

    #: [flights] design flights needed to fit a surface-specific measurement model
    min_surface_flights: int = 12
    #: [-] the rate prior's sd is the design runs' spread times this (few runs per mode say
    #: little about the tails)
    rate_prior_inflation: float = 2.0
    #: [-] forgetting factor of the log-level RLS per unit of its clock: memory about
    #: 1 / (1 - lambda) = 200 flights (or flights at the reference temperature)
    level_forgetting: float = 0.995
    #: [-] candidate shapes c of the exponential law (0.01: near-pure exponential; +-10:
    #: near-linear; -1.08 down to -10: growth that slows down, towards -c)
    growth_offsets: tuple[float, ...] = tuple(np.concatenate(
        [np.geomspace(0.01, 10.0, 61), -np.geomspace(1.08, 10.0, 31)]).tolist())
    #: [1/K] candidate temperature sensitivities of a mode's ageing (0: a flight clock;
    #: ln 2 / 10 K = 0.069 Montsinger's insulation rule, ln 2 / 15 K = 0.046 the grease rule)
    stress_betas: tuple[float, ...] = tuple(np.round(np.arange(0.0, 0.1001, 0.005), 4).tolist())
    #: [-] a wear mode whose feature resolves severity to this or better (residual sd over
    #: the slope of h at mid-life) is tuned on the log-level and replayed from the growth's
    #: onset: both need the feature to see the fault's first hundredths
    precise_wear_noise: float = 0.05
    #: [-] a mode ages on the stress clock only if that at least halves the flight clock's
    #: misfit
    stress_gain: float = 0.5
    #: noise law of the measurement models: "linear" (sigma grows with severity) or "constant"
    measurement_noise: str = "linear"
    #: [-] relative spread of one mode's rates between runs (spans U(170, 360) flights): the
    #: first-trial parameters' sd as a share of the rate at mid-life
    rate_spread: float = 0.35
    #: [-] bounds of the RLS's initial covariance P0: the floor keeps some adaptation
    prior_weight_bounds: tuple[float, float] = (1e-2, 1.0)
    #: [-] the mid-life rate bounds of a mode's filter are its slowest design run's rate over
    #: the slow margin and its fastest run's times the fast one: early increments, mostly
    #: noise, may not drive the law beyond them. A law held too slow predicts too long a
    #: life, the dangerous error, so the fast side has the room
    slow_rate_margin: float = 1.5
    fast_rate_margin: float = 4.0
    #: [-] prior probability that a fault's rate lies off the design's range: the weight of
    #: the rate prior's tail components (``PrognoserConfig.rate_prior_tail``)
    rate_prior_tail: float = 0.2
    #: [flights] the bank of rate hypotheses (``PrognoserConfig.rate_hypotheses``): the edges
    #: of its bands of fault-to-failure spans over the test station's envelope, ascending
    #: (fast, medium, slow); empty: the tail mixture of ``rate_prior_tail`` (docs/TUNING.md)
    rate_band_edges: tuple[float, ...] = (30.0, 100.0, 300.0, 1000.0)
    #: [-] each band's rate prior sd is its moments' times this (:mod:`.prognosis.hypotheses`)
    hypothesis_inflation: float = 1.0
    #: how the bank's hypotheses are weighed (``PrognoserConfig.rate_weighting``): each band by
    #: its evidence, its prior kept whole (docs/TUNING.md)
    rate_weighting: RateWeighting = "evidence"
    #: the long-term prediction's severity random walk: "filter", the filter's process noise;
    #: "design", the design runs' own flight-to-flight scatter about their fitted laws
    prediction_noise: str = "filter"
    #: [flights] the online guard's forecast horizon (0: no guard)
    guard_horizon: int = 10

    def __post_init__(self) -> None:
        if self.rate_weighting not in RATE_WEIGHTINGS:
            raise ValueError(f"rate_weighting must be one of {list(RATE_WEIGHTINGS)}, got "
                             f"{self.rate_weighting!r}")
        if self.prediction_noise not in ("filter", "design"):
            raise ValueError(f"prediction_noise must be 'filter' or 'design', got "
                             f"{self.prediction_noise!r}")
        for name in ("rate_prior_inflation", "rate_spread", "slow_rate_margin",
                     "fast_rate_margin", "hypothesis_inflation"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be finite and > 0, got {value!r}")
        band_names(self.rate_band_edges)  # refuses edges that make no bands
        for name in ("slow_rate_margin", "fast_rate_margin"):
            if getattr(self, name) < 1.0:
                raise ValueError(f"{name} must be >= 1, got {getattr(self, name)}")
        if not 0.0 < self.level_forgetting <= 1.0:
            raise ValueError(f"level_forgetting must be in (0, 1], got {self.level_forgetting}")
        low, high = self.prior_weight_bounds
        if not 0.0 < low <= high:
            raise ValueError(f"prior_weight_bounds must be 0 < low <= high, got "
                             f"{self.prior_weight_bounds}")


#: the configuration every model is trained with
TRAINING = TrainingConfig()


def _faulty_history(model: PhmModel, p: Pattern
                    ) -> Iterator[tuple[FlightRecord, DetectionResult, dict[str, float],
                                        ActuatorHealth]]:
    """The faulty actuator's detection, flight by flight from installation as in service (the
    aircraft's units judged together, :func:`~server.phm.detection.update_units`), with its
    physical residuals less its own offset and its state after the flight; only flights from
    the onset are yielded."""
    position = str(p.position)
    aircraft = {u: model.new_health(u) for u in UNITS}
    states = {u: h.detection for u, h in aircraft.items()}
    for r in p.flights:
        z = model.baseline.zscores(r.features)
        det = update_units(model.detector, states, z,
                           evidence=model.baseline.evidence_weights(r.features))[position]
        if p.onset_flight is not None and r.index < int(p.onset_flight):
            continue
        yield r, det, self_residuals(model.baseline, z, det), aircraft[position]


def training_rows(campaign: Campaign, model: PhmModel) -> dict[str, np.ndarray]:
    """Classifier rows as the chain will see them: the faulty actuator's classifier input
    (:func:`~server.phm.chain.classifier_vector`) on every flight from the detector's first
    alarm on (the classifier only runs after an alarm). Rows: X (n, 7), mode, pattern,
    aircraft, severity."""
    X, y, groups, aircraft, sev = [], [], [], [], []
    for p in campaign.patterns:
        if p.mode == "healthy" or p.position is None:
            continue
        for r, det, _, health in _faulty_history(model, p):
            if not det.alarm:
                continue
            X.append(classifier_vector(health.detection, p.position))
            y.append(p.mode)
            groups.append(p.id)
            aircraft.append(p.aircraft)
            sev.append(r.severity_norm)
    return {"X": np.asarray(X).reshape(-1, len(GENERIC_FEATURES)), "y": np.asarray(y),
            "groups": np.asarray(groups), "aircraft": np.asarray(aircraft),
            "severity": np.asarray(sev, dtype=np.float64)}


def _degradation_prior(campaign: Campaign, mode: str, training: TrainingConfig
                       ) -> tuple[tuple[float, float] | None, dict[str, Any]]:
    """First-trial parameters of the affine growth law dh/dk = a + b h of ``mode`` (paper 4.2:
    the RLS starts from first-trial values and tunes them online), from the true severity
    increments of the design fault-to-failure runs: a least-squares fit *per run*, then the
    median over runs. (One fit pooled over runs is biased towards b < 0: slow runs contribute
    many small increments at high severity, fast runs few large ones.) The median slope may be
    negative: winglet rod-end wear slows down as the partner drive takes the load."""
    fits, gaps, late = [], [], []
    for p in _fault_runs(campaign, mode):
        fl = _from_onset(p)
        end = [r for r in fl if r.severity_norm >= 0.8]
        if len(end) >= 2 and end[-1].index > end[0].index:  # the run's rate near failure
            late.append((end[-1].severity_norm - end[0].severity_norm)
                        / (end[-1].index - end[0].index))
        xs, ys = [], []
        for r0, r1 in zip(fl, fl[1:], strict=False):
            if r1.index > r0.index:
                xs.append(r0.severity_norm)
                ys.append((r1.severity_norm - r0.severity_norm) / (r1.index - r0.index))
                gaps.append(r1.index - r0.index)
        if len(xs) >= 3:
            X = np.column_stack([np.ones(len(xs)), np.asarray(xs)])
            coef, *_ = np.linalg.lstsq(X, np.asarray(ys), rcond=None)
            fits.append(coef)
    if len(fits) < 2:
        return None, {"error": "too few fault-to-failure runs"}
    a, b = (float(v) for v in np.median(np.asarray(fits), axis=0))
    a = max(a, 1e-5)
    mid = [f[0] + 0.5 * f[1] for f in fits]
    slow, fast = training.slow_rate_margin, training.fast_rate_margin
    bounds = (max(min(mid) / slow, 1e-5), max(mid) * fast)
    return (a, b), {"a_per_flight": a, "b_per_flight": b, "n_runs": len(fits),
                    "dk": float(np.median(gaps)), "mid_rate_bounds": list(bounds),
                    "late_rate_floor": (max(min(late) / slow, 1e-5) if late else None)}


def fit_climate(campaign: Campaign) -> SeasonalClimate | None:
    """Annual temperature cycle of each base from the design flights' ground temperatures
    (the ``temp_ground_c`` condition read from the log) and take-off dates."""
    bases, days, temps = [], [], []
    for p in campaign.patterns:
        for r in p.flights:
            if p.base is None or r.started_at is None:
                continue
            cond = next(iter(r.features.conditions.values()), {})
            bases.append(p.base)
            days.append(day_of_year(r.started_at))
            temps.append(float(cond.get("temp_ground_c", math.nan)))
    climate = SeasonalClimate.fit(bases, days, temps)
    return climate if climate.coefficients else None


def _from_onset(p: Pattern) -> list[FlightRecord]:
    """The flights of a design run from its fault's onset on, in flight order."""
    return sorted((r for r in p.flights if r.index >= int(p.onset_flight or 0)),
                  key=lambda r: r.index)


def _fault_runs(campaign: Campaign, mode: str, surface: str | None = None) -> list[Pattern]:
    """The design runs of ``mode`` (on ``surface``, "WL" or "WT", if given) with at least 4
    flights from the onset."""
    return [p for p in campaign.patterns if p.mode == mode and len(_from_onset(p)) >= 4
            and (surface is None or surface_of(str(p.position)) == surface)]


def _run_clocks(run: Pattern, climate: SeasonalClimate | None, ref_c: float | None,
                betas: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(true normalised severity (n,), stress since the onset (betas, n)) of one run."""
    fl = _from_onset(run)
    k = np.array([r.index for r in fl], dtype=int)
    sn = np.array([r.severity_norm for r in fl], dtype=float)
    stress = np.tile(k - k[0], (betas.size, 1)).astype(float)
    dated = [(r.index, r.started_at) for r in fl if r.started_at is not None]
    if climate is not None and climate.knows(run.base) and len(dated) >= 2:
        days = (dated[-1][1] - dated[0][1]).total_seconds() / 86400.0
        per_day = (dated[-1][0] - dated[0][0]) / days if days > 0 else None
        if per_day:
            for j, beta in enumerate(betas):
                clock = StressClock(climate, str(run.base), float(beta), ref_c,
                                    dated[0][1], dated[0][0], per_day)
                stress[j] = [clock.between(int(k[0]), int(i)) for i in k]
    return sn, stress


def _exponential_prior(campaign: Campaign, mode: str, climate: SeasonalClimate | None,
                       fleet_ref_c: float, training: TrainingConfig,
                       surface: str | None = None) -> dict[str, Any] | None:
    """:func:`_fit_exponential_law` with the stress referred to the fleet's mean temperature
    and to each base's own annual mean; the reference that leaves the smaller spread of rates
    between design runs (coefficient of variation) is kept: the prior on r is then tighter."""
    fits = [_fit_exponential_law(campaign, mode, climate, ref, training, surface)
            for ref in (fleet_ref_c, None)]
    found = [f for f in fits if f is not None]
    if not found:
        return None
    best = min(found, key=lambda f: f["rate_std"] / abs(f["rate"]))
    best["rate_cv_by_reference"] = {
        "fleet" if f["stress_ref_c"] is not None else "base": f["rate_std"] / abs(f["rate"])
        for f in found}
    return best


def _fit_exponential_law(campaign: Campaign, mode: str, climate: SeasonalClimate | None,
                         ref_c: float | None, training: TrainingConfig,
                         surface: str | None = None) -> dict[str, Any] | None:
    """Shape c, temperature sensitivity beta and rate prior of dh/dtau = r (h + c), tau the
    stress clock (:mod:`server.phm.season`), from the design runs' true severities.

    (c, beta) is the point of a grid that makes ln(h + c) most nearly a straight line in tau
    over the runs (mean 1 - R^2 of a per-run fit: scale-free, so shapes and clocks compare
    fairly); each run's slope there is its rate r. The prior is the runs' median r and their
    standard deviation; the rate bounds are the slowest and fastest run's mid-life rate
    r (0.5 + c) widened by ``training.slow_rate_margin`` and ``fast_rate_margin``, and with a
    bank of rate hypotheses every rate of its envelope (:func:`_envelope_bounds`).
    """
    betas = np.asarray(training.stress_betas)
    offsets = np.asarray(training.growth_offsets)
    patterns = _fault_runs(campaign, mode, surface)
    runs = [_run_clocks(p, climate, ref_c, betas) for p in patterns]
    if len(runs) < 2:
        return None
    misfit = np.zeros((betas.size, offsets.size))
    for sn, stress in runs:
        U = np.maximum(sn, 0.0)[:, np.newaxis] + offsets  # (n, c grid)
        # a saturating shape must stay below its asymptote over the whole run
        misfit[:, (offsets < 0) & (U.max(axis=0) > -MIN_LEVEL_GAP)] = np.inf
        Y = np.log(np.maximum(np.abs(U), MIN_LEVEL_GAP))
        Yc = Y - Y.mean(axis=0)
        for j, tau in enumerate(stress):
            X = np.column_stack([np.ones_like(tau), tau])
            coef, *_ = np.linalg.lstsq(X, Y, rcond=None)
            misfit[j] += ((Y - X @ coef) ** 2).sum(axis=0) / (Yc**2).sum(axis=0)
    jb, jc = (int(i) for i in np.unravel_index(int(np.argmin(misfit)), misfit.shape))
    if misfit[jb, jc] > training.stress_gain * misfit[0].min():  # temperature explains little
        jb, jc = 0, int(np.argmin(misfit[0]))
        ref_c = None
    beta, c = float(betas[jb]), float(offsets[jc])
    rates = np.array([np.polyfit(stress[jb], np.log(np.abs(np.maximum(sn, 0.0) + c)), 1)[0]
                      for sn, stress in runs])
    sign = 1.0 if c > 0 else -1.0  # r < 0 for a saturating shape: dh/dk = r (h + c) > 0
    r0 = sign * float(max(sign * np.median(rates), 1e-6))
    r_std = training.rate_prior_inflation * float(max(np.std(rates, ddof=1), 0.1 * abs(r0)))
    mid = rates * (0.5 + c)
    noise = _increment_noise(runs, int(jb), c, rates)
    bounds = (max(float(mid.min()) / training.slow_rate_margin, 1e-5),
              max(float(mid.max()) * training.fast_rate_margin, 2e-5))
    law: dict[str, Any] = {
        "growth_offset": c, "stress_beta_per_k": beta, "stress_ref_c": ref_c, "rate": r0,
        "rate_std": r_std, "n_runs": len(runs), "mid_rate_bounds": list(bounds),
        "increment_noise": noise, "misfit_flight_clock": float(misfit[0].min() / len(runs)),
        "misfit": float(misfit[jb, jc] / len(runs))}
    if training.rate_band_edges:
        spans = [float(p.failure_flight - p.onset_flight) for p in patterns
                 if p.failure_flight is not None and p.onset_flight is not None]
        if len(spans) == len(rates):
            law["hypotheses"] = [h.to_dict() for h in fit_rate_hypotheses(
                rates.tolist(), spans, band_names(training.rate_band_edges),
                inflation=training.hypothesis_inflation)]
            law["mid_rate_bounds"] = list(_envelope_bounds(bounds, rates * np.asarray(spans),
                                                           c, training))
    return law


def _envelope_bounds(bounds: tuple[float, float], rho: np.ndarray, c: float,
                     training: TrainingConfig) -> tuple[float, float]:
    """The mid-life rate ``bounds`` widened to every rate the bank's envelope admits: the
    design runs' rho = r x span (about the same for every run of a mode,
    :mod:`.prognosis.hypotheses`) over the envelope's longest and shortest span, at mid-life
    (r (0.5 + c)), with the margins.
    The runs' own bounds hold the design's spans only: a surface whose design runs were all
    slow (the shipped design's two wingtip screw-wear runs) would otherwise clip every faster
    fault's rate in propagation and prediction, its RUL then too long."""
    edges = training.rate_band_edges
    mid_rho = np.abs(rho * (0.5 + c))
    low = float(mid_rho.min()) / max(edges) / training.slow_rate_margin
    high = float(mid_rho.max()) / min(edges) * training.fast_rate_margin
    return min(bounds[0], max(low, 1e-5)), max(bounds[1], high)


def _increment_noise(runs: list[tuple[np.ndarray, np.ndarray]], jb: int, c: float,
                     rates: np.ndarray) -> float:
    """The design runs' flight-to-flight scatter about their own laws [1/sqrt(clock unit)]:
    the rms of (dh - r (h + c) dtau) / sqrt(dtau) over every run's consecutive flights, each
    run with its own rate r (the spread of rates between runs is the prior's, not this)."""
    terms = []
    for (sn, stress), r in zip(runs, rates, strict=True):
        h, tau = np.maximum(sn, 0.0), stress[jb]
        dtau = np.diff(tau)
        ok = dtau > 0
        resid = np.diff(h)[ok] - r * (h[:-1][ok] + c) * dtau[ok]
        terms.append(resid**2 / dtau[ok])
    pooled = np.concatenate(terms) if terms else np.empty(0)
    return float(np.sqrt(pooled.mean())) if pooled.size else math.nan


def _level_config(base: PrognoserConfig, law: dict[str, Any], training: TrainingConfig
                  ) -> PrognoserConfig:
    """The filter of a mode whose rate is tuned on the log-level of ``law`` (its shape c, rate
    prior and mid-life rate bounds, from :func:`_fit_exponential_law`)."""
    config = replace(base, rate_basis="exponential", growth_offset=law["growth_offset"],
                     initial_theta=(0.0, law["rate"]), initial_rate_std=law["rate_std"],
                     rls_forgetting=training.level_forgetting,
                     rate_bounds=tuple(law["mid_rate_bounds"]),
                     rate_prior_tail=0.0 if law.get("hypotheses") else training.rate_prior_tail,
                     rate_hypotheses=tuple(RateHypothesis.from_dict(h)
                                           for h in law.get("hypotheses") or ()),
                     rate_weighting=training.rate_weighting if law.get("hypotheses")
                     else "predictive",
                     prediction_noise_std=_prediction_noise(law, training),
                     guard_horizon=training.guard_horizon)
    return config


def _prediction_noise(law: dict[str, Any], training: TrainingConfig) -> float | None:
    """The prediction's random walk of a mode: None (the filter's) unless training learns it
    from the design runs."""
    noise = law.get("increment_noise")
    if training.prediction_noise != "design" or noise is None or not noise > 0:
        return None
    return float(noise)


def _prior_weight(theta: tuple[float, float], noise_in_severity: float, dk: float,
                  training: TrainingConfig) -> float:
    """Initial RLS covariance P0 that weighs the first-trial parameters against the data.

    The RLS regresses severity increments y = dh/dk on [1, h]; one increment over ``dk``
    flights has noise about sqrt(2) sigma_h / dk. Patterns of one mode differ in rate by about
    35 % (fault-to-failure spans of U(170, 360) flights), so sigma_theta = 0.35 x the rate at
    mid-life. P0 = sigma_theta^2 / sigma_y^2, clipped to [0.01, 1]: a precise feature (TTS)
    lets the data re-tune the law at once, a noisy one (wear backlash) leans on the prior. The
    floor keeps some adaptation: the RLS sees increments of the *filtered* severity, less noisy
    than one measurement.
    """
    rate = theta[0] + 0.5 * theta[1]
    sigma_theta = training.rate_spread * rate
    sigma_y = math.sqrt(2.0) * noise_in_severity / max(dk, 1.0)
    low, high = training.prior_weight_bounds
    return float(np.clip(sigma_theta**2 / max(sigma_y**2, 1e-30), low, high))


def _reference_temperature(campaign: Campaign, climate: SeasonalClimate | None) -> float:
    """Mean climatological temperature of the design flights [degC]: a flight there adds one
    unit of stress, so stress and flights are of the same order."""
    temps = [float(climate.temperature(str(p.base), day_of_year(r.started_at)))
             for p in campaign.patterns if climate is not None and climate.knows(p.base)
             for r in p.flights if r.started_at is not None]
    return round(float(np.mean(temps)), 2) if temps else 0.0


def fit_measurement_models(campaign: Campaign, phm: PhmModel,
                           base_config: PrognoserConfig | None = None,
                           climate: SeasonalClimate | None = None,
                           training: TrainingConfig = TRAINING) -> tuple[
        dict[str, MeasurementSpec], dict[str, Any]]:
    """Per progressive mode: h(severity) of the mode's own feature (paper Table 1), fitted on
    the physical-unit residuals of the faulty actuator, less its own offset, over its design
    fault-to-failure runs (``phm`` supplies baseline and detector); each mode's filter from
    ``training``'s constants."""
    base_config = base_config or PrognoserConfig()
    ref_c = _reference_temperature(campaign, climate)
    specs: dict[str, MeasurementSpec] = {}
    report: dict[str, Any] = {}
    for mode in PROGRESSIVE:
        feature = OWN_FEATURE[mode]
        triples = [(r.severity_norm, measurement_values(res, str(p.position)).get(feature),
                    surface_of(str(p.position)))
                   for p in campaign.patterns if p.mode == mode and p.position
                   for r, _, res, _ in _faulty_history(phm, p)]
        triples = [t for t in triples if t[1] is not None]
        pairs = [(sn, v) for sn, v, _ in triples]
        if len(pairs) < 6:
            continue
        s = np.array([a for a, _ in pairs])
        v = np.array([b for _, b in pairs])
        try:
            model = MeasurementModel.fit(s, v, noise=training.measurement_noise)
        except ValueError as exc:  # no monotone relation: no prognosis for this mode
            report[mode] = {"feature": feature, "error": str(exc)}
            continue
        by_surface = {}
        for surface in ("WL", "WT"):
            sub = [(sn, v) for sn, v, srf in triples if srf == surface and v is not None]
            if len(sub) >= training.min_surface_flights:
                try:
                    by_surface[surface] = MeasurementModel.fit(
                        [a for a, _ in sub], [b for _, b in sub], noise=training.measurement_noise)
                except ValueError:
                    pass
        resid = v - model.predict(s)  # the residuals' sd over the whole life
        spread = float(np.sqrt(resid @ resid / (s.size - len(model.coefficients))))
        noise_sev = float(spread / max(abs(float(model.derivative(
            np.array([0.5]))[0])), 1e-12))
        law = _exponential_prior(campaign, mode, climate, ref_c, training)
        thermal = law is not None and law["stress_beta_per_k"] > 0
        precise_wear = law is not None and not thermal and noise_sev <= training.precise_wear_noise
        surface_configs: dict[str, PrognoserConfig] = {}
        if thermal or precise_wear:
            assert law is not None  # both read it: for the type checker
            prior = law
            # dh/dtau = r (h + c), r tuned on the log-level: a thermally driven mode on the
            # season's stress clock, a precisely measured wear mode on flights (near-linear c)
            config = _level_config(base_config, law, training)
            if precise_wear:
                # a worn winglet drive hands its load to its partner and its wear slows down;
                # the lone wingtip drive's does not: one shape per surface where runs allow
                for surface in ("WL", "WT"):
                    own = _exponential_prior(campaign, mode, climate, ref_c, training, surface)
                    if own is not None and own["stress_beta_per_k"] == 0.0:
                        surface_configs[surface] = _level_config(base_config, own, training)
                        prior.setdefault("by_surface", {})[surface] = {
                            k: own[k] for k in ("growth_offset", "rate", "rate_std", "n_runs",
                                                "mid_rate_bounds", "increment_noise")}
        else:
            theta, prior = _degradation_prior(campaign, mode, training)
            prior["stress"] = law
            config = base_config
            if theta is not None:
                # a growth that slows down (b < 0: a worn winglet drive hands its load to its
                # partner) keeps its negative slope in the prediction's parameter draws, and
                # never drops below the slowest design run's rate near failure (over the
                # margin): draws
                # whose slope stops short of the threshold would run to the horizon
                floor = prior.get("late_rate_floor") if theta[1] < 0 else None
                config = replace(base_config, initial_theta=theta, monotone_rate=theta[1] >= 0,
                                 min_rate=base_config.min_rate if floor is None else floor,
                                 rls_initial_cov=_prior_weight(theta, noise_sev, prior["dk"],
                                                                        training),
                                 rate_bounds=tuple(prior["mid_rate_bounds"]))
                prior["rls_initial_cov"] = config.rls_initial_cov
        specs[mode] = MeasurementSpec(feature, model, config, by_surface,
                                      float(prior.get("stress_beta_per_k", 0.0)),
                                      prior.get("stress_ref_c"), precise_wear,
                                      prognoser_by_surface=surface_configs)
        prior["replay_from_onset"] = precise_wear
        rho = spearmanr(s, v).statistic
        report[mode] = {"feature": feature, "spearman": float(rho),
                        "noise_std": model.noise_std, "noise_slope": model.noise_slope,
                        "residual_sd": spread, "n_flights": len(pairs),
                        "coefficients": list(model.coefficients),
                        "noise_in_severity": noise_sev,
                        "degradation_prior": prior,
                        "surface_noise_std": {k: m.noise_std for k, m in by_surface.items()}}
    return specs, report


def sensor_study_pairs(campaign: Campaign
                       ) -> list[tuple[str, str, FlightFeatures, FlightFeatures]]:
    """``(sensor, study pattern, study flight, twin flight)`` of the design campaign's sensor
    study, the flights paired by index with those of the twin healthy pattern."""
    twins = {p.id: p for p in campaign.patterns}
    pairs = []
    for study in campaign.sensor_study:
        info = study.sensor_study or {}
        twin = twins.get(str(info.get("twin")))
        if twin is None:
            continue
        by_index = {r.index: r for r in twin.flights}
        pairs += [(str(info["sensor"]), study.id, r.features, by_index[r.index].features)
                  for r in study.flights if r.index in by_index]
    return pairs


def fault_spans(campaign: Campaign) -> dict[str, list[int]]:
    """Per progressive mode, the shortest and longest onset-to-failure span of the campaign's
    runs [flights]: the range of lives the prognosis was fitted on."""
    spans: dict[str, list[int]] = {}
    for p in campaign.patterns:
        if p.mode in PROGRESSIVE and p.onset_flight is not None and p.failure_flight is not None:
            spans.setdefault(p.mode, []).append(p.failure_flight - p.onset_flight)
    return {m: [min(v), max(v)] for m, v in sorted(spans.items())}


def train_phm_model(campaign: Campaign, *, seed: int = 0, progress: Progress | None = None,
                    training: TrainingConfig = TRAINING) -> tuple[PhmModel, dict[str, Any]]:
    """Fit the whole chain on a design campaign whose features are computed; return the
    model and a JSON-safe report. ``training``: the constants the prognosis is derived with
    (the default is every model's; others serve tuning, ``bench/adaptation.py``)."""

    def tick(stage: str, frac: float) -> None:
        if progress is not None:
            progress(stage, frac)

    t_feat = time.perf_counter()
    tick("detection", 0.5)
    detection = fit_detection(campaign)
    t_det = time.perf_counter()
    tick("classifier", 0.6)
    bare = PhmModel(detection.baseline, detection.detector, None, {}, PrognoserConfig())
    rows = training_rows(campaign, bare)
    classifier, clf_report = train_classifier(
        rows["X"], rows["y"], rows["groups"], feature_names=list(GENERIC_FEATURES), seed=seed,
        progress=lambda st, f: tick(f"classifier:{st}", 0.6 + 0.3 * f))
    t_clf = time.perf_counter()
    tick("measurement", 0.9)
    climate = fit_climate(campaign)
    specs, meas_report = fit_measurement_models(
        campaign, bare, PrognoserConfig(), climate, training)
    study = sensor_study_pairs(campaign)
    sensors = fit_sensor_model([f for _, seq in healthy_flights(campaign) for f in seq],
                               study, detection.baseline)
    crosstalk = fit_crosstalk(rows["X"], rows["y"])
    model = PhmModel(detection.baseline, detection.detector, classifier, specs,
                     PrognoserConfig(), climate, sensors, crosstalk)
    t_end = time.perf_counter()
    tick("done", 1.0)
    n_flights = sum(len(p.flights) for p in campaign.patterns)
    report = {
        "campaign": {"kind": campaign.kind, "seed": campaign.seed,
                     "patterns": len(campaign.patterns), "flights": n_flights,
                     "aircraft": sorted({p.aircraft for p in campaign.patterns}),
                     "spans_flights": fault_spans(campaign)},
        "seed": seed,
        "training": asdict(training),
        "classifier": clf_report,
        "measurement": meas_report,
        "sensors": {"fitted": sensors is not None, "study_pairs": len(study),
                    "sensitivity": sensors is not None and sensors.sensitivity is not None},
        "detector": {"windows": list(detection.detector.windows),
                     "alarm_confidence": detection.detector.alarm_confidence,
                     "false_alarm_rate": detection.detector.false_alarm_rate,
                     "design_false_alarms": detection.design_false_alarms},
        "timings_s": {"detection": t_det - t_feat, "classifier": t_clf - t_det,
                      "measurement": t_end - t_clf, "total": t_end - t_feat},
    }
    return model, report
