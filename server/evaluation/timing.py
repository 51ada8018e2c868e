"""Timing of the real chain calls (time.perf_counter), for the paper's section 5.1 figures.

:class:`ChainTimer` wraps, for the duration of :meth:`ChainTimer.instrument`, the methods the
chain calls (baseline z-scores, detector update, classifier, particle-filter update and
long-term prediction, and the RLS step inside the update) with accumulating timers, so the
figures are the mean per call over a real evaluation run, not a synthetic benchmark.

Feature extraction is timed separately by :func:`feature_timing`: the evaluation reads cached
features, so a few flights of the campaign are re-read and their features recomputed.
Per 80 Hz step figures are per-flight times divided by the flight's number of 80 Hz steps
(800 Hz samples / 10): the batch is amortised, the paper times one step at a time.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from server.campaigns import Location
    from server.phm.chain import PhmModel

__all__ = ["ChainTimer", "feature_timing", "timing_summary"]


class ChainTimer:
    """Accumulated wall time and call counts per key."""

    def __init__(self) -> None:
        self.total: dict[str, float] = {}
        self.calls: dict[str, int] = {}

    def add(self, key: str, seconds: float) -> None:
        self.total[key] = self.total.get(key, 0.0) + seconds
        self.calls[key] = self.calls.get(key, 0) + 1

    @contextmanager
    def span(self, key: str) -> Iterator[None]:
        t0 = time.perf_counter()
        try:
            yield
        finally:
            self.add(key, time.perf_counter() - t0)

    def _wrap(self, fn: Callable[..., Any], key: str) -> Callable[..., Any]:
        def timed(*args: Any, **kwargs: Any) -> Any:
            t0 = time.perf_counter()
            try:
                return fn(*args, **kwargs)
            finally:
                self.add(key, time.perf_counter() - t0)

        return timed

    @contextmanager
    def instrument(self) -> Iterator[ChainTimer]:
        """Patch the chain's timed calls in this process; restore them on exit."""
        from server.phm.baselines import FleetBaseline
        from server.phm.classification import FaultClassifier
        from server.phm.detection import judge
        from server.phm.prognosis import filter as pf_module

        targets: list[tuple[Any, str, str]] = [
            (FleetBaseline, "zscores", "zscores"),
            (judge, "observe", "detector"),  # a unit's judgement of one flight
            (FaultClassifier, "predict_log_proba", "classifier"),
            (pf_module.ParticleFilterPrognoser, "update", "pf_update"),
            (pf_module.ParticleFilterPrognoser, "predict", "pf_predict"),
            (pf_module, "rls_update", "rls"),
        ]
        saved = [(obj, name, obj.__dict__[name]) for obj, name, _ in targets]
        try:
            for obj, name, key in targets:
                setattr(obj, name, self._wrap(getattr(obj, name), key))
            yield self
        finally:
            for obj, name, orig in saved:
                setattr(obj, name, orig)

    def to_dict(self) -> dict[str, dict[str, float]]:
        return {k: {"total_s": self.total[k], "calls": self.calls[k]} for k in self.total}

    @staticmethod
    def merge(parts: Sequence[Mapping[str, Mapping[str, float]]]) -> dict[str, dict[str, Any]]:
        out: dict[str, dict[str, Any]] = {}
        for part in parts:
            for k, v in part.items():
                acc = out.setdefault(k, {"total_s": 0.0, "calls": 0})
                acc["total_s"] += float(v["total_s"])
                acc["calls"] += int(v["calls"])
        return out


def feature_timing(campaign_dir: Location, *, n_flights: int = 6
                   ) -> dict[str, Any]:
    """Mean time to read a flight file and to compute its features (3 EMAs, 20 features).

    The flights are spread evenly over the manifest's list (deterministic choice).
    """
    from server.campaigns import campaign_store, decode_log, read_manifest
    from server.phm.features import FeatureConfig
    from server.phm.recording import log_features

    root = campaign_store(campaign_dir)  # a directory or s3://bucket/prefix
    manifest = read_manifest(root)
    files = [(fl["file"], fl.get("ground_temp_c")) for p in manifest["patterns"]
             for fl in p["flights"] if fl.get("file")]  # a streamed flight kept no file
    if not files:
        return {}
    step = max(len(files) // n_flights, 1)
    chosen = files[::step][:n_flights]
    cfg = FeatureConfig()
    t_read = t_feat = 0.0
    steps = 0
    for f, ground in chosen:
        t0 = time.perf_counter()
        log = decode_log(root.read(f), f)
        t1 = time.perf_counter()
        log_features(log, config=cfg, ground_temp_c=ground)
        t2 = time.perf_counter()
        t_read += t1 - t0
        t_feat += t2 - t1
        steps += max(len(next(iter(log.channels.values()))) // 10, 1)
    n = len(chosen)
    return {"flights": n, "read_per_flight_ms": 1e3 * t_read / n,
            "features_per_flight_ms": 1e3 * t_feat / n, "steps_80hz_mean": steps / n}


def timing_summary(chain: Mapping[str, Any], feat: Mapping[str, Any] | None,
                   model: PhmModel) -> dict[str, Any]:
    """The evaluation's ``timing`` figures: mean ms per chain call (:class:`ChainTimer`), the
    particle filter's cycle and the RLS share, the features' time (:func:`feature_timing`)
    per 80 Hz step, beside the paper's."""
    def mean_ms(key: str) -> float | None:
        c = chain.get(key)
        return 1e3 * c["total_s"] / c["calls"] if c and c["calls"] else None

    out: dict[str, Any] = {
        "calls": {k: v["calls"] for k, v in chain.items()},
        "chain_per_flight_ms": mean_ms("chain"),
        "zscores_per_flight_ms": mean_ms("zscores"),
        "detector_update_ms": mean_ms("detector"),
        "classifier_ms": mean_ms("classifier"),
        "pf_update_ms": mean_ms("pf_update"),
        "rls_ms": mean_ms("rls"),
        "pf_predict_ms": mean_ms("pf_predict"),
        "n_particles": model.prognoser.n_particles,
    }
    upd, rls, pred = out["pf_update_ms"], out["rls_ms"], out["pf_predict_ms"]
    if upd and pred and rls is not None:
        out["pf_cycle_ms"] = upd + pred
        out["rls_share_pct"] = 100.0 * rls / (upd + pred)
        out["rls_share_of_update_pct"] = 100.0 * rls / upd
    det_flight = None
    if out["zscores_per_flight_ms"] is not None and out["detector_update_ms"] is not None:
        per_flight_units = chain["detector"]["calls"] / max(chain["zscores"]["calls"], 1)
        det_flight = out["zscores_per_flight_ms"] + out["detector_update_ms"] * per_flight_units
        out["detection_per_flight_ms"] = det_flight
    if feat is not None:
        out["features"] = dict(feat)
        steps = feat.get("steps_80hz_mean")
        if steps:
            out["features_per_step_ms"] = feat["features_per_flight_ms"] / steps
            out["read_per_step_ms"] = feat["read_per_flight_ms"] / steps
            if det_flight is not None:
                out["detection_per_step_ms"] = det_flight / steps
                out["features_detection_per_step_ms"] = (
                    feat["features_per_flight_ms"] + det_flight) / steps
    out["paper"] = {"features_detection_per_step_ms": 11.3, "pf_cycle_ms": 7.4,
                    "rls_share_pct": 2.25}
    return out
