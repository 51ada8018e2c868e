"""Campaign directories (contract ``ema-campaign/1``, written by ``sim-worker campaign`` or
streamed by ``hmsm campaign``): read into :class:`server.phm.dataset.Campaign` with every
flight's features.

Layout: ``DIR/manifest.json`` (the campaign's aircraft, patterns and every flight's ground
truth), ``DIR/flights/<tail>/<flight>.parquet`` (flight logs, format ``ema-flightlog/1``) and
``DIR/phm_features.json`` (every flight's features by flight id, valid while the feature code
gives the same outputs on the canary flights, :mod:`server.feature_canary`); DIR a local
directory or an S3 prefix ``s3://bucket/prefix`` (:class:`server.campaign_store.CampaignStore`,
at ``HMSM_S3_ENDPOINT_URL`` when set). Every flight log is decoded and checked by
:mod:`server.flightlog`, exactly as an upload is, then its features are computed by the
service's own :func:`server.phm.recording.log_features`.

A streamed campaign (:class:`FeatureSink`) does that in the worker that simulated the flight
and keeps the features instead of the file; only every ``keep_raw_every``-th flight of a
pattern is written as a file, so ingest stays exercised, and its features are computed from
its Parquet bytes. The other flights skip the Parquet round trip: their features are computed
from the in-memory log after the same checks, on the very channel values a file would hold
(:func:`server.flightlog.read_back`).
"""

from __future__ import annotations

import json
import os
import time
from collections.abc import Callable, Mapping
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path
from typing import Any

from server.campaign_store import CampaignStore
from server.feature_canary import canary_digest
from server.flightlog import (
    FlightLog,
    FlightLogError,
    check_coherence,
    read_back,
    read_parquet,
    read_parquet_metadata,
    write_parquet,
)
from server.phm.chain import PhmModel
from server.phm.dataset import Campaign, FlightRecord, Pattern
from server.phm.features import (
    FeatureConfig,
    FeatureSummary,
    FlightFeatures,
)
from server.phm.recording import log_features
from server.phm.signal_quality import QualityConfig
from server.phm.training import train_phm_model

__all__ = ["CAMPAIGN_FORMAT", "FEATURE_CACHE", "CampaignError", "FeatureSink", "campaign_store",
           "read_manifest", "single_fault", "decode_log", "checked_log", "read_started_at",
           "load_campaign", "train_from_directory"]

CAMPAIGN_FORMAT = "ema-campaign/1"
FEATURE_CACHE = "phm_features.json"
_CACHE_FORMAT = "phm-features/3"  # keyed by flight id, valid for a canary digest
_LEGACY_FORMAT = "phm-features/2"  # keyed by a feature version string
#: the canary digest of each feature version whose campaigns were cached under its name; a
#: campaign of that version is read while today's features still give that digest
LEGACY_DIGESTS = {"features/10": "258d58cc3e1f7992a02c561563cfa63d"}


class CampaignError(ValueError):
    """A campaign directory that breaks its contract (manifest or a flight log)."""


Location = str | os.PathLike[str] | CampaignStore


def campaign_store(location: Location) -> CampaignStore:
    """The store of a campaign at a directory or ``s3://bucket/prefix`` (a ValueError if
    malformed); an S3 one at the service's ``HMSM_S3_ENDPOINT_URL`` when that is set."""
    if isinstance(location, CampaignStore) or not os.fspath(location).startswith("s3:"):
        return CampaignStore.at(location)
    from server.config import load_settings

    return CampaignStore.at(location, load_settings().s3_endpoint_url)


def read_manifest(directory: Location) -> dict[str, Any]:
    root = campaign_store(directory)
    try:
        manifest = json.loads(root.read("manifest.json"))
    except (OSError, ValueError) as exc:
        raise CampaignError(f"{root}: no readable manifest.json ({exc})") from None
    if not isinstance(manifest, dict) or manifest.get("format") != CAMPAIGN_FORMAT:
        raise CampaignError(f"{root}: not an {CAMPAIGN_FORMAT} manifest")
    return manifest


def single_fault(manifest: Mapping[str, Any], where: str, use: str) -> None:
    """Refuse (:class:`CampaignError`) a concurrent-fault campaign (``manifest``, at ``where``)
    for ``use``: training and the single-fault scoring read one fault per pattern, a single
    mode, position and true RUL; a concurrent campaign is scored by
    :func:`server.evaluation.concurrent.evaluate_concurrent` (``hmsm evaluate`` chooses it)."""
    if manifest.get("kind") == "concurrent":
        raise CampaignError(
            f"{where} is a concurrent-fault campaign (two faults per pattern); {use} reads "
            "single-fault campaigns (design or verification) only; hmsm evaluate scores a "
            "concurrent one per fault (server.evaluation.concurrent)")


def decode_log(data: bytes, name: str) -> FlightLog:
    """A flight log's Parquet bytes, decoded and checked as an upload is."""
    return _checked(lambda: read_parquet(data), name)


def checked_log(log: FlightLog, name: str) -> FlightLog:
    """An in-memory flight log as it would read back from its Parquet bytes, to the bit
    (:func:`~server.flightlog.read_back`), checked as an upload is: :func:`decode_log` without
    the encoding."""
    return _checked(lambda: read_back(log), name)


def _checked(decode: Callable[[], FlightLog], name: str) -> FlightLog:
    try:
        log = decode()
        issues = check_coherence(log, fleet_serials=dict(log.metadata.actuator_serials))
    except FlightLogError as exc:
        issues = exc.issues
    if issues:
        raise CampaignError(f"{name}: " + "; ".join(i.message for i in issues))
    return log


def feature_config_key(cfg: FeatureConfig) -> str:
    """What stored features are valid for: the feature code's outputs on the canary flights
    (:func:`server.feature_canary.canary_digest`), so a refactor that moves no feature keeps
    every stored campaign and a change that moves one invalidates them; and the configurations
    themselves, since a threshold may move features on a campaign's flights and on no canary."""
    return f"canary:{canary_digest(cfg)} {cfg!r} {QualityConfig()!r}"


def _legacy_key(cfg: FeatureConfig) -> str | None:
    """The version-string key a campaign cached before the canaries carries, when features
    under ``cfg`` are still the ones that version computed (its canary digest pinned)."""
    digest = canary_digest(cfg)
    for version, pinned in LEGACY_DIGESTS.items():
        if digest == pinned:
            return f"{version} {cfg!r} {QualityConfig()!r}"
    return None


def _write_cache(root: CampaignStore, key: str, flights: Mapping[str, Any]) -> None:
    doc = {"format": _CACHE_FORMAT, "config": key, "flights": flights}
    root.write(FEATURE_CACHE, json.dumps(doc).encode())


def _read_cache(root: CampaignStore, cfg: FeatureConfig) -> dict[str, Any]:
    text = root.read_text(FEATURE_CACHE)
    if text is None:
        return {}
    doc = json.loads(text)
    valid = {(_CACHE_FORMAT, feature_config_key(cfg)), (_LEGACY_FORMAT, _legacy_key(cfg))}
    if (doc.get("format"), doc.get("config")) not in valid:
        return {}
    return dict(doc["flights"])


@dataclass(frozen=True)
class FeatureSink:
    """Streams a campaign: each rendered flight checked as an upload, its features computed by
    the service's own code; the log is then dropped, except every ``keep_raw_every``-th flight
    of a pattern (index 0 included), written as its file and analysed from its bytes. A
    dropped flight is analysed on its stored channels without encoding them
    (:func:`checked_log`). Features go to ``phm_features.json`` at the end."""

    keep_raw_every: int = 200
    config: FeatureConfig = field(default_factory=FeatureConfig)

    def __post_init__(self) -> None:
        if isinstance(self.keep_raw_every, bool) or not isinstance(self.keep_raw_every, int) \
                or self.keep_raw_every < 1:
            raise ValueError("keep_raw_every must be a positive int")

    def __call__(self, out: CampaignStore | Path, rel: str, index: int, log: FlightLog,
                 ground_temp_c: float) -> tuple[str | None, dict[str, Any] | None]:
        if index % self.keep_raw_every:  # dropped: no Parquet round trip, the same channels
            return None, self._features(checked_log(log, rel), ground_temp_c)
        data = write_parquet(log)
        features = self._features(decode_log(data, rel), ground_temp_c)
        CampaignStore.at(out).write(rel, data)
        return rel, features

    def _features(self, log: FlightLog, ground_temp_c: float) -> dict[str, Any]:
        return log_features(log, config=self.config, ground_temp_c=ground_temp_c).to_dict()

    def describe(self) -> dict[str, Any]:
        return {"sink": "features", "keep_raw_every": self.keep_raw_every,
                "features": feature_config_key(self.config)}

    def finish(self, out: CampaignStore | Path, stored: dict[str, dict[str, Any]]) -> None:
        _write_cache(CampaignStore.at(out), feature_config_key(self.config), stored)


def read_started_at(source: str | os.PathLike[str] | Any) -> datetime | None:
    """Take-off time (UTC) of a flight-log file (its path, or the file opened), from its
    metadata only."""
    meta = read_parquet_metadata(source)
    return None if meta is None else meta.started_at


def _features_of(args: tuple[CampaignStore, str, float | None, FeatureConfig]
                 ) -> dict[str, Any]:
    root, rel, ground, cfg = args
    return log_features(decode_log(root.read(rel), f"{root}/{rel}"), config=cfg,
                        ground_temp_c=ground).to_dict()


def _features_from_dict(d: Mapping[str, Any]) -> FlightFeatures:
    summ = {k: FeatureSummary(float(v["value"]), float(v["dispersion"]), int(v["n_valid"]))
            for k, v in d["summaries"].items()}
    cond = {p: {k: float(v) for k, v in c.items()} for p, c in d["conditions"].items()}
    quality = {ch: {k: float(v) for k, v in q.items()} for ch, q in d.get("quality", {}).items()}
    return FlightFeatures(summ, cond, quality=quality)


def _cached_features(root: CampaignStore, manifest: Mapping[str, Any], cfg: FeatureConfig,
                     jobs: int, cache: bool) -> dict[str, Any]:
    """Features of every flight by flight id: the stored ones, the missing ones computed from
    their files (a flight streamed without its file must have stored features)."""
    key = feature_config_key(cfg)
    cached = _read_cache(root, cfg) if cache else {}
    flights = [fl for pat in manifest["patterns"] for fl in pat["flights"]]
    todo = [fl for fl in flights if fl["flight"] not in cached]
    if not todo:
        return cached
    lost = [fl["flight"] for fl in todo if not fl.get("file")]
    if lost:
        raise CampaignError(
            f"{root}: {len(lost)} flights (first {lost[0]}) were streamed without their logs "
            f"and have no features valid for today's feature code ({key}); "
            "generate the campaign again")
    args = [(root, fl["file"], fl.get("ground_temp_c"), cfg) for fl in todo]
    if jobs > 1:
        with ProcessPoolExecutor(max_workers=jobs) as ex:
            results = list(ex.map(_features_of, args, chunksize=4))
    else:
        results = [_features_of(a) for a in args]
    for fl, r in zip(todo, results, strict=True):
        cached[fl["flight"]] = r
    if cache:
        _write_cache(root, key, cached)
    return cached


def _started_at(root: CampaignStore, fl: Mapping[str, Any]) -> datetime | None:
    if fl.get("started_at"):
        return datetime.fromisoformat(str(fl["started_at"]))
    with root.open(fl["file"]) as f:  # the footer alone, a ranged read on S3
        return read_started_at(f)


def _record(root: CampaignStore, fl: Mapping[str, Any], features: Mapping[str, Any]
            ) -> FlightRecord:
    return FlightRecord(str(fl["flight"]), int(fl["index"]), float(fl.get("severity", 0.0)),
                        float(fl.get("severity_norm", 0.0)),
                        None if fl.get("true_rul_flights") is None
                        else float(fl["true_rul_flights"]),
                        fl.get("ground_temp_c"), _features_from_dict(features),
                        _started_at(root, fl))


def load_campaign(directory: Location, *, config: FeatureConfig | None = None,
                  jobs: int = 1, cache: bool = True) -> Campaign:
    """Read a campaign manifest and the features of every flight (cached with ``cache``;
    ``cache=False`` recomputes them all from the files, so a streamed campaign, whose dropped
    logs live on only as stored features, needs the default). ``directory``: a local one or
    ``s3://bucket/prefix``."""
    root = campaign_store(directory)
    manifest = read_manifest(root)
    cached = _cached_features(root, manifest, config or FeatureConfig(), jobs, cache)
    bases = {str(a.get("tail")): a.get("base") for a in manifest.get("aircraft", [])}
    patterns: list[Pattern] = []
    study: list[Pattern] = []
    for pat in manifest["patterns"]:
        recs = [_record(root, fl, cached[fl["flight"]])
                for fl in sorted(pat["flights"], key=lambda f: int(f["index"]))]
        (study if pat.get("sensor_study") else patterns).append(Pattern(
            str(pat["id"]), str(pat["aircraft"]), str(pat["mode"]), pat.get("position"),
            pat.get("onset_flight"), pat.get("failure_flight"), recs,
            bases.get(str(pat["aircraft"])), pat.get("sensor_study")))
    return Campaign(str(manifest.get("kind")), int(manifest.get("seed", 0)), patterns,
                    list(manifest.get("aircraft", [])), study)


def train_from_directory(design_dir: Location, *, seed: int = 0,
                         jobs: int | None = None,
                         progress: Callable[[str, float], None] | None = None
                         ) -> tuple[PhmModel, dict[str, Any]]:
    """Read a design campaign (features computed or taken from the cache) and train the
    chain on it (:func:`server.phm.training.train_phm_model`); the report gains the
    campaign's directory and the time spent on features."""
    single_fault(read_manifest(design_dir), str(design_dir), "training")
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
