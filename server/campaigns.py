"""Campaign directories (contract ``ema-campaign/1``, written by ``sim-worker campaign``):
read into :class:`server.phm.dataset.Campaign` with every flight's features.

Layout: ``DIR/manifest.json`` (the campaign's aircraft, patterns and every flight's ground
truth) and ``DIR/flights/<tail>/<flight>.parquet`` (flight logs, format ``ema-flightlog/1``).
Every flight log is decoded and checked by :mod:`server.flightlog`, exactly as an upload is,
then its features are computed by the service's own :func:`server.phm.features.flight_features`
and cached beside the manifest in ``phm_features.json`` (keyed by file, valid for one feature
version and configuration).
"""

from __future__ import annotations

import json
import os
import time
from collections.abc import Callable, Mapping
from concurrent.futures import ProcessPoolExecutor
from datetime import datetime
from pathlib import Path
from typing import Any

import numpy as np

from server.flightlog import FlightLogError, check_coherence, read_parquet, read_parquet_metadata
from server.phm.chain import PhmModel
from server.phm.dataset import Campaign, FlightRecord, Pattern
from server.phm.features import (
    FEATURE_VERSION,
    FeatureConfig,
    FeatureSummary,
    FlightFeatures,
    flight_features,
)
from server.phm.training import train_phm_model

__all__ = ["CAMPAIGN_FORMAT", "FEATURE_CACHE", "CampaignError", "read_manifest",
           "read_flight_channels", "read_started_at", "load_campaign", "train_from_directory"]

CAMPAIGN_FORMAT = "ema-campaign/1"
FEATURE_CACHE = "phm_features.json"


class CampaignError(ValueError):
    """A campaign directory that breaks its contract (manifest or a flight log)."""


def read_manifest(directory: str | os.PathLike[str]) -> dict[str, Any]:
    root = Path(directory)
    try:
        manifest = json.loads((root / "manifest.json").read_text())
    except (OSError, ValueError) as exc:
        raise CampaignError(f"{root}: no readable manifest.json ({exc})") from None
    if not isinstance(manifest, dict) or manifest.get("format") != CAMPAIGN_FORMAT:
        raise CampaignError(f"{root}: not an {CAMPAIGN_FORMAT} manifest")
    return manifest


def read_flight_channels(path: str | os.PathLike[str]) -> dict[str, np.ndarray]:
    """All channels of a flight-log file as float64 arrays, after the same decoding and
    coherence checks as an upload (the file's own serials stand for the installed ones)."""
    try:
        log = read_parquet(Path(path).read_bytes())
        issues = check_coherence(log, fleet_serials=dict(log.metadata.actuator_serials))
    except FlightLogError as exc:
        issues = exc.issues
    if issues:
        raise CampaignError(f"{path}: " + "; ".join(i.message for i in issues))
    return {n: np.asarray(v, dtype=np.float64) for n, v in log.channels.items()}


def read_started_at(path: str | os.PathLike[str]) -> datetime | None:
    """Take-off time (UTC) of a flight-log file, from its metadata only."""
    meta = read_parquet_metadata(Path(path))
    return None if meta is None else meta.started_at


def _features_of(args: tuple[str, float | None, FeatureConfig]) -> dict[str, Any]:
    path, ground, cfg = args
    return flight_features(read_flight_channels(path), config=cfg,
                           ground_temp_c=ground).to_dict()


def _features_from_dict(d: Mapping[str, Any]) -> FlightFeatures:
    summ = {k: FeatureSummary(float(v["value"]), float(v["dispersion"]), int(v["n_valid"]))
            for k, v in d["summaries"].items()}
    cond = {p: {k: float(v) for k, v in c.items()} for p, c in d["conditions"].items()}
    return FlightFeatures(summ, cond)


def _cached_features(root: Path, manifest: Mapping[str, Any], cfg: FeatureConfig, jobs: int,
                     cache: bool) -> dict[str, Any]:
    """Features of every flight by file name: from the cache, the missing ones computed."""
    cache_path = root / FEATURE_CACHE
    cfg_key = f"{FEATURE_VERSION} {cfg!r}"
    cached: dict[str, Any] = {}
    if cache and cache_path.exists():
        doc = json.loads(cache_path.read_text())
        if doc.get("config") == cfg_key:
            cached = doc["flights"]
    todo = [(fl["file"], fl.get("ground_temp_c")) for pat in manifest["patterns"]
            for fl in pat["flights"] if fl["file"] not in cached]
    if not todo:
        return cached
    args = [(str(root / f), g, cfg) for f, g in todo]
    if jobs > 1:
        with ProcessPoolExecutor(max_workers=jobs) as ex:
            results = list(ex.map(_features_of, args, chunksize=4))
    else:
        results = [_features_of(a) for a in args]
    for (f, _), r in zip(todo, results, strict=True):
        cached[f] = r
    if cache:
        tmp = cache_path.with_suffix(".tmp")
        tmp.write_text(json.dumps({"config": cfg_key, "flights": cached}))
        tmp.replace(cache_path)
    return cached


def _record(root: Path, fl: Mapping[str, Any], features: Mapping[str, Any]) -> FlightRecord:
    return FlightRecord(str(fl["flight"]), int(fl["index"]), float(fl.get("severity", 0.0)),
                        float(fl.get("severity_norm", 0.0)),
                        None if fl.get("true_rul_flights") is None
                        else float(fl["true_rul_flights"]),
                        fl.get("ground_temp_c"), _features_from_dict(features),
                        read_started_at(root / fl["file"]))


def load_campaign(directory: str | os.PathLike[str], *, config: FeatureConfig | None = None,
                  jobs: int = 1, cache: bool = True) -> Campaign:
    """Read a campaign manifest and the features of every flight (cached with ``cache``)."""
    root = Path(directory)
    manifest = read_manifest(root)
    cached = _cached_features(root, manifest, config or FeatureConfig(), jobs, cache)
    bases = {str(a.get("tail")): a.get("base") for a in manifest.get("aircraft", [])}
    patterns = []
    for pat in manifest["patterns"]:
        recs = [_record(root, fl, cached[fl["file"]])
                for fl in sorted(pat["flights"], key=lambda f: int(f["index"]))]
        patterns.append(Pattern(str(pat["id"]), str(pat["aircraft"]), str(pat["mode"]),
                                pat.get("position"), pat.get("onset_flight"),
                                pat.get("failure_flight"), recs, bases.get(str(pat["aircraft"]))))
    return Campaign(str(manifest.get("kind")), int(manifest.get("seed", 0)), patterns,
                    list(manifest.get("aircraft", [])))


def train_from_directory(design_dir: str | os.PathLike[str], *, seed: int = 0,
                         jobs: int | None = None,
                         progress: Callable[[str, float], None] | None = None
                         ) -> tuple[PhmModel, dict[str, Any]]:
    """Read a design campaign (features computed or taken from the cache) and train the
    chain on it (:func:`server.phm.training.train_phm_model`); the report gains the
    campaign's directory and the time spent on features."""
    if progress is not None:
        progress("features", 0.0)
    t0 = time.perf_counter()
    campaign = load_campaign(design_dir, jobs=jobs or (os.cpu_count() or 1))
    features_s = time.perf_counter() - t0
    model, report = train_phm_model(campaign, seed=seed, progress=progress)
    report["campaign"] = {"dir": str(design_dir), **report["campaign"]}
    timings = report["timings_s"]
    report["timings_s"] = {"features": features_s, **timings,
                           "total": timings["total"] + features_s}
    return model, report
