"""A campaign's run: its patterns on a process pool or any executor, resumable from the
finished patterns kept in ``DIR/progress/``, its settings and manifest written once all are
done (:func:`run_campaign`), and a snapshot of an unfinished run (:func:`snapshot_campaign`).
Results are identical for any number of workers or any executor.
"""

from __future__ import annotations

import json
import os
from collections.abc import Iterable, Iterator
from concurrent.futures import Executor, ProcessPoolExecutor, as_completed
from dataclasses import asdict
from pathlib import Path
from typing import Any

from server.campaign_store import CampaignStore

from ..fleet import BASES, DEFAULT_WINGLET_MODE, Aircraft, WingletMode
from ..flight import LANES
from .pattern import FlightSink, ParquetSink, PatternTask, iter_patterns, run_patterns
from .planning import KINDS, PatternSpec, execution_order, fleet_for, plan_campaign
from .scales import SCALES, SENSOR_STUDY_NOISE, SENSOR_STUDY_PATTERNS, ScaleConfig, scale_config
from .sensor_faults import SensorFault, canonical_sensor_faults

__all__ = ["FORMAT", "SETTINGS_FILE", "run_campaign", "snapshot_campaign"]

FORMAT = "ema-campaign/1"
#: at most this many patterns a pool task runs in lockstep: twice the kernel's lanes, so a
#: finished pattern's lane is taken by the next while the group's longest runs (a group is
#: saved when it ends)
GROUP = 2 * LANES
#: the settings a finished campaign was made with, beside its manifest
SETTINGS_FILE = "campaign_settings.json"


def _completed(tasks: dict[int, PatternTask], workers: int, executor: Executor | None
               ) -> Iterator[tuple[int, dict[str, Any]]]:
    """(task number, result) as each group of patterns finishes (patterns in lockstep, their
    flights in the kernel's lanes), on ``executor`` if given, else on a local process pool of
    ``workers`` (1: in this process). A group holds at most :data:`GROUP` patterns, and one
    group per worker when there are fewer; the patterns are dealt out to the groups in turn,
    so each group holds long and short ones alike and the workers finish together. In this
    process each pattern is saved as it finishes; on a pool, a group's when it ends."""
    size = max(1, min(GROUP, -(-len(tasks) // max(workers, 1))))
    numbers = list(tasks)
    n_groups = -(-len(numbers) // size)
    groups = [numbers[g::n_groups] for g in range(n_groups)]
    if executor is None and workers <= 1:
        for group in groups:  # saved as each pattern finishes
            for i, result in iter_patterns([tasks[n] for n in group]):
                yield group[i], result
        return
    pool = executor if executor is not None else ProcessPoolExecutor(max_workers=workers)
    try:
        futures = {pool.submit(run_patterns, [tasks[n] for n in group]): group
                   for group in groups}
        for fut in as_completed(futures):
            yield from zip(futures[fut], fut.result(), strict=True)
    finally:
        if executor is None:
            pool.shutdown(wait=True, cancel_futures=True)


def _settings(kind: str, seed: int, scale: str, cfg: ScaleConfig, options: dict[str, Any],
              sink: FlightSink) -> dict[str, Any]:
    """What determines the campaign's content: a resumed campaign must match it exactly."""
    settings = {"format": FORMAT, "kind": kind, "seed": int(seed), "scale": scale,
                "config": _config_settings(cfg),
                "bases": list(options["bases"]) if options["bases"] else None,
                "noise_scale": options["noise_scale"], "sink": sink.describe(),
                "winglet_mode": DEFAULT_WINGLET_MODE.value}
    if kind == "design":
        settings["sensor_study"] = {"patterns": SENSOR_STUDY_PATTERNS,
                                    "noise": SENSOR_STUDY_NOISE}
    if options["sensor_faults"]:
        # only when given: campaigns without sensor faults keep the settings they had
        # before the option existed, so finished ones are still recognised
        settings["sensor_faults"] = [f.spec for f in options["sensor_faults"]]
    return settings


def _config_settings(cfg: ScaleConfig) -> dict[str, Any]:
    """The scale config as settings; a uniform span draw is left out, so campaigns finished
    before the draw could be chosen are still recognised."""
    out = asdict(cfg)
    if out["span_draw"] == "uniform":
        del out["span_draw"]
    # likewise the envelope, when the scale does not vary it
    for key in ("recordings_s", "condition_blocks"):
        if not out[key]:
            del out[key]
    return out


_PROGRESS = "progress"


class _Progress:
    """Finished patterns of an interrupted run, one file each in ``DIR/progress/``; a finished
    pattern is never simulated again. Removed once the manifest is written."""

    def __init__(self, out: CampaignStore | Path, settings: dict[str, Any]) -> None:
        self.out = CampaignStore.at(out)
        rel = f"{_PROGRESS}/settings.json"
        text = json.dumps(settings, sort_keys=True)
        held = self.out.read_text(rel)
        if held is not None and held != text:
            raise ValueError(f"{self.out} holds an unfinished campaign with other settings "
                             f"(see {self.out}/{rel}); resume it with the same options or use "
                             "another directory")
        if held is None:
            self.out.write(rel, text.encode())

    def done(self, spec: PatternSpec) -> dict[str, Any] | None:
        text = self.out.read_text(_progress_file(spec))
        return None if text is None else json.loads(text)

    def save(self, spec: PatternSpec, result: dict[str, Any]) -> None:
        self.out.write(_progress_file(spec), json.dumps(result).encode())

    def remove(self) -> None:
        self.out.remove_dir(_PROGRESS)


def _progress_file(spec: PatternSpec) -> str:
    return f"{_PROGRESS}/{spec.number:04d}.json"


def run_campaign(kind: str, out_dir: str | Path | CampaignStore, *, seed: int,
                 scale: str = "quick",
                 workers: int | None = None, progress: bool = True,
                 bases: tuple[str, ...] | None = None, noise_scale: float = 1.0,
                 sensor_faults: Iterable[SensorFault | str] = (),
                 render_every: int | None = None,
                 span_flights: tuple[float, float] | None = None,
                 span_draw: str | None = None,
                 sink: FlightSink | None = None,
                 executor: Executor | None = None,
                 per_mode: int | None = None,
                 recordings_s: Iterable[float] | None = None,
                 patterns_per_mode: int | None = None,
                 step_flights: int | None = None) -> dict[str, Any]:
    """Write a campaign and its manifest; returns the manifest.

    Manifest (``DIR/manifest.json``)::

        {"format": "ema-campaign/1", "kind", "seed", "scale", "duration_s", "render_every",
         "lead_flights", "span_flights", "noise_scale", "bases", "sensor_faults", "sink",
         "aircraft": [{"tail", "base", "climate", "serials": {pos: serial}, "params": {...}}],
         "patterns": [{"id", "aircraft", "mode", "position", "threshold", "onset_flight",
                       "failure_flight", "flights": [{"flight", "index", "file", "started_at",
                       "severity", "severity_norm", "true_rul_flights", "block_hours",
                       "ground_temp_c", "measured_summary"}]}]}

    A design campaign ends with its sensor study: patterns with ``"sensor_study": {"sensor",
    "noise", "twin"}``, healthy, each the twin pattern again with one sensor noisier.

    A concurrent campaign (``kind="concurrent"``, the ``ci`` and ``quick`` scales) flies two
    faults per pattern (:data:`~.planning.COMBINATIONS`, ``per_mode`` patterns per
    combination kind). Its pattern entries are ``{"id", "aircraft", "mode"`` (the combination
    kind, e.g. ``"MTWEAR+MTEL"``), ``"faults": [{"mode", "position", "threshold",
    "onset_flight", "span_flights", "expected_failure_flight", "started", "outcome"``
    (failed, censored or unfinished), ``"end_flight", "failure_flight",
    "severity_norm_at_end"}], "flights"}``, and each flight's entry, in place of the
    single-fault ``severity``, ``severity_norm`` and ``true_rul_flights``, has ``"faults":
    [{"mode", "position", "severity", "severity_norm", "true_rul_flights",
    "failure_flight"}]`` (the faults on that flight; a censored fault's RUL and failure flight
    are None). Its aircraft are its own (tails ``I-CON..``, seeds of their own).

    A flight's ``file`` is None when the sink kept no log of it (a streamed campaign keeps
    its features instead). ``sensor_faults`` (:class:`SensorFault` or their specs) degrade
    one sensor of one actuator on every aircraft, written as their specs
    (``["WT.lvdt:noise=2"]``, empty when none). ``render_every`` overrides the scale's
    rendering step of fault-to-failure runs (1 renders every flight, as a fleet in service
    downloads every one); ``span_flights`` the range of expected fault-to-failure spans,
    ``span_draw`` how a pattern draws from it ("uniform" or "log", log-uniform; default the
    scale's: the quick and protocol designs span the envelope log-uniformly). The
    winglet tab flies active-standby (``fleet.DEFAULT_WINGLET_MODE``, recorded in the manifest
    as ``"winglet_mode"``).
    ``per_mode`` flies every healthy pattern and only the first ``per_mode`` patterns of each
    fault mode (0: the healthy ones alone, for false alarms over long healthy lives), the
    same flights as in the whole campaign.
    ``patterns_per_mode`` plans that many fault patterns per mode instead of the scale's
    (numbered and seeded as a campaign of its own; ``per_mode`` then takes the first of them).
    ``step_flights`` overrides the length of the step faults' (SE, BDO) patterns: the same
    flights, more of them after onset (how long a step fault takes to be found).
    ``recordings_s`` overrides the scale's recording lengths: every rendered flight draws its
    own from them (one value: every flight that long); a scale that varies them, and its
    test-station condition blocks, records each flight's under ``"recording_s"`` and
    ``"conditions"``.
    ``out_dir`` is a directory, ``s3://bucket/prefix`` (AWS S3) or a
    :class:`~server.campaign_store.CampaignStore` (another S3 server's); every file of the
    campaign goes there, the kept logs straight from the workers.
    ``sink`` decides what is kept of a rendered flight (default: its Parquet file). Patterns
    run on ``executor`` (any ``concurrent.futures.Executor``, e.g. a Dask client's) if given,
    else on a local pool of ``workers`` processes; the output does not depend on either. An
    interrupted run resumes where it stopped when called again with the same arguments.
    """
    if kind not in KINDS:
        raise ValueError(f"kind must be one of {KINDS}")
    if scale not in SCALES:
        raise ValueError(f"scale must be one of {sorted(SCALES)}")
    if bases and not set(bases) <= set(BASES):
        raise ValueError(f"bases must be among {sorted(BASES)}")
    if not noise_scale > 0:
        raise ValueError("noise_scale must be positive")
    if per_mode is not None and (isinstance(per_mode, bool) or int(per_mode) != per_mode
                                 or per_mode < 0):
        raise ValueError(f"per_mode must be a count of patterns (>= 0), got {per_mode!r}")
    faults = canonical_sensor_faults(sensor_faults)
    cfg = scale_config(scale, kind, render_every, span_flights, span_draw, recordings_s,
                       patterns_per_mode, step_flights)
    sink = sink if sink is not None else ParquetSink()
    from tqdm import tqdm

    from ..kernel import warm_up

    out = CampaignStore.at(out_dir)
    # a plain tuple of frozen dataclasses: pickled as is to pool and Dask workers
    options: dict[str, Any] = {"bases": tuple(bases) if bases else None,
                               "noise_scale": float(noise_scale),
                               "sensor_faults": faults}
    settings = _settings(kind, seed, scale, cfg, options, sink)
    if per_mode is not None:
        settings["per_mode"] = int(per_mode)  # only when given, as sensor_faults
    finished = _finished_manifest(out, settings)
    if finished is not None:
        return finished
    warm_up()  # compile (or load the cache) once before forking workers
    specs = plan_campaign(kind, seed, scale, per_mode=per_mode,
                          patterns_per_mode=cfg.patterns_per_mode,
                          step_flights=cfg.apriori_flights)
    fleet = fleet_for(kind, seed, **options)
    store = _Progress(out, settings)
    results = {s.number: r for s in specs if (r := store.done(s)) is not None}
    todo = {s.number: PatternTask(out, kind, seed, cfg, s, options, sink)
            for s in execution_order(specs) if s.number not in results}
    bar = tqdm(total=len(specs), initial=len(results), desc=f"{kind} campaign",
               unit="pattern", disable=not progress)
    by_number = {s.number: s for s in specs}  # a part's numbers are the whole campaign's
    for number, res in _completed(todo, workers or os.cpu_count() or 1, executor):
        store.save(by_number[number], res)
        results[number] = res
        bar.update(1)
    bar.close()
    ordered = [results[s.number] for s in specs]
    sink.finish(out, {fid: data for r in ordered for fid, data in r["stored"].items()})
    manifest = _manifest(settings, cfg, fleet, [r["entry"] for r in ordered])
    out.write("manifest.json", json.dumps(manifest, indent=1).encode())
    out.write(SETTINGS_FILE, json.dumps(settings, sort_keys=True).encode())
    store.remove()
    return manifest


def snapshot_campaign(out_dir: str | Path | CampaignStore, snap_dir: str | Path | CampaignStore,
                      *, sink: FlightSink | None = None) -> dict[str, Any]:
    """The patterns an unfinished campaign in ``out_dir`` has finished so far, written to
    ``snap_dir`` as a campaign of their own, so that a run of hours can be scored before it
    ends; returns its manifest. The run itself is not touched and resumes as before.

    The manifest is the full campaign's for the finished patterns, in pattern order, plus
    ``"partial": {"patterns": finished, "of": planned}``; ``sink`` (the run's, default
    :class:`ParquetSink`) writes what it keeps of them, and ``snap_dir/flights`` links to the
    run's kept logs (between two local directories; else the finished patterns' kept logs are
    copied). A finished campaign, or a sink other than the run's, is refused.
    """
    out, snap = CampaignStore.at(out_dir), CampaignStore.at(snap_dir)
    sink = sink if sink is not None else ParquetSink()
    if out.exists(SETTINGS_FILE):
        raise ValueError(f"{out} is a finished campaign: score it directly")
    text = out.read_text(f"{_PROGRESS}/settings.json")
    if text is None:
        raise ValueError(f"{out}: no campaign in progress (no {_PROGRESS}/settings.json)")
    settings = json.loads(text)
    if settings["sink"] != sink.describe():
        raise ValueError(f"{out} was run with the sink {settings['sink']}, not "
                         f"{sink.describe()}")
    fields: dict[str, Any] = {k: tuple(v) if isinstance(v, list) else v
                              for k, v in settings["config"].items()}
    cfg = ScaleConfig(**fields)
    specs = plan_campaign(settings["kind"], settings["seed"], settings["scale"],
                          per_mode=settings.get("per_mode"),
                          patterns_per_mode=cfg.patterns_per_mode,
                          step_flights=cfg.apriori_flights)
    store = _Progress(out, settings)
    done = [r for s in specs if (r := store.done(s)) is not None]
    fleet = fleet_for(settings["kind"], settings["seed"],
                      bases=tuple(settings["bases"]) if settings["bases"] else None,
                      noise_scale=settings["noise_scale"],
                      sensor_faults=canonical_sensor_faults(settings.get("sensor_faults")))
    entries = [r["entry"] for r in done]
    _share_logs(out, snap, [fl["file"] for e in entries for fl in e["flights"] if fl["file"]])
    sink.finish(snap, {fid: data for r in done for fid, data in r["stored"].items()})
    manifest = _manifest(settings, cfg, fleet, entries)
    manifest["partial"] = {"patterns": len(done), "of": len(specs)}
    snap.write("manifest.json", json.dumps(manifest, indent=1).encode())
    return manifest


def _share_logs(out: CampaignStore, snap: CampaignStore, files: list[str]) -> None:
    """The run's kept logs seen from the snapshot: ``flights`` a link to the run's between
    local directories (the run goes on writing there), else the given files copied."""
    here, there = out.local_dir(), snap.local_dir()
    if here is None or there is None:
        for rel in files:
            if not snap.exists(rel):
                snap.write(rel, out.read(rel))
        return
    there.mkdir(parents=True, exist_ok=True)
    if not (there / "flights").exists():
        (there / "flights").symlink_to((here / "flights").resolve(), target_is_directory=True)


def _manifest(settings: dict[str, Any], cfg: ScaleConfig, fleet: list[Aircraft],
              patterns: list[dict[str, Any]]) -> dict[str, Any]:
    return {
        "format": FORMAT,
        "kind": settings["kind"],
        "seed": settings["seed"],
        "scale": settings["scale"],
        "duration_s": cfg.duration_s,
        "render_every": cfg.render_every,
        "lead_flights": cfg.lead_flights,
        "span_flights": list(cfg.span_flights),
        "noise_scale": settings["noise_scale"],
        "bases": settings["bases"],
        "sensor_faults": settings.get("sensor_faults", []),
        "winglet_mode": settings.get("winglet_mode", WingletMode.ACTIVE_ACTIVE.value),
        "sink": settings["sink"],
        "aircraft": [{"tail": a.tail, "base": a.base, "climate": BASES[a.base],
                      "serials": dict(a.serials), "params": a.params_summary()} for a in fleet],
        "patterns": patterns,
    }


def _finished_manifest(out: CampaignStore, settings: dict[str, Any]) -> dict[str, Any] | None:
    """The manifest of a campaign already finished in ``out`` with these settings; a finished
    campaign with other settings is refused (it is never overwritten)."""
    held = out.read_text(SETTINGS_FILE)
    if held is None:
        return None  # nothing finished here, or a campaign of an older simulator: regenerate
    if held != json.dumps(settings, sort_keys=True):
        raise ValueError(f"{out} already holds a campaign with other settings (see "
                         f"{out}/{SETTINGS_FILE}); use another directory")
    return json.loads(out.read("manifest.json"))
