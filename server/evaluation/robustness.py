"""Robustness campaigns derived from existing ones (issue 9 part 3), until the simulator has
``--noise-scale`` / ``--bases`` options of its own.

- ``noise``: the same campaign with the sensor noise multiplied by ``--scale`` (default 2):
  Gaussian noise of standard deviation sqrt(scale^2 - 1) x the simulator's sensor noise
  (current 0.04 A, phase voltage 0.8 V, resolver 2e-4 rad, LVDT 2e-6 m; docs/SIMULATOR.md) is
  added to the recorded 800 Hz channels, re-quantised to the sensor LSB, and the features are
  recomputed into the derived campaign's feature cache. The flight files are not copied (the
  derived manifest points at the source's ``flights/`` through a symlink). An emulation: the
  simulator adds its noise before quantisation, inside the kernel.
- ``climate``: a design campaign without the aircraft of one climate and a verification
  campaign with only that climate's aircraft, so the model is verified on a climate it has
  not seen in training (the design and verification fleets both have 4 Turin / temperate,
  3 Vancouver / cold, 3 Abu Dhabi / hot aircraft).

Usage::

    python -m server.evaluation.robustness noise --campaign /tmp/cv2 --out /tmp/cv2_noise2
    python -m server.evaluation.robustness climate --design /tmp/cq2 --verification /tmp/cv2 \\
        --hold-out hot --out /tmp/climate_hot
    hmsm evaluate --campaign /tmp/cv2_noise2 --design /tmp/cq2
    hmsm evaluate --campaign /tmp/climate_hot/verification --design /tmp/climate_hot/design
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import zlib
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["SENSOR_NOISE", "add_sensor_noise", "noisy_campaign", "subset_campaign", "main"]

#: channel suffix -> (noise rms, LSB) of the simulator's sensors (sim_worker/params.py)
SENSOR_NOISE: dict[str, tuple[float, float]] = {
    "ia": (0.04, 2.0**-5), "ib": (0.04, 2.0**-5), "ic": (0.04, 2.0**-5),
    "va": (0.8, 2.0**-3), "vb": (0.8, 2.0**-3), "vc": (0.8, 2.0**-3),
    "theta": (2.0e-4, 2.0 * math.pi / 65536), "x": (2.0e-6, 2.0**-19),
}


def add_sensor_noise(channels: Mapping[str, np.ndarray], scale: float,
                     rng: np.random.Generator) -> dict[str, np.ndarray]:
    """Channels with the sensor noise standard deviation multiplied by ``scale`` (>= 1)."""
    if scale < 1:
        raise ValueError("scale must be >= 1 (noise can only be added)")
    extra = math.sqrt(scale**2 - 1.0)
    out = dict(channels)
    for name, v in channels.items():
        suffix = name.rsplit(".", 1)[-1] if "." in name else None
        if suffix not in SENSOR_NOISE:
            continue
        sigma, lsb = SENSOR_NOISE[suffix]
        noisy = v + extra * sigma * rng.standard_normal(v.shape)
        out[name] = np.round(noisy / lsb) * lsb
    return out


def _noisy_features(args: tuple[str, str, float | None, float, int]) -> tuple[str, dict[str, Any]]:
    from server.phm.evaluate_detection import read_flight_channels
    from server.phm.features import FeatureConfig, flight_features

    path, key, ground, scale, seed = args
    rng = np.random.default_rng(np.random.SeedSequence([seed, zlib.crc32(key.encode())]))
    ch = add_sensor_noise(read_flight_channels(path), scale, rng)
    return key, flight_features(ch, config=FeatureConfig(), ground_temp_c=ground).to_dict()


def _link_flights(src: Path, dst: Path) -> None:
    dst.mkdir(parents=True, exist_ok=True)
    link = dst / "flights"
    if not link.exists():
        link.symlink_to((src / "flights").resolve(), target_is_directory=True)


def noisy_campaign(src: str | os.PathLike[str], dst: str | os.PathLike[str], *,
                   scale: float = 2.0, seed: int = 0, jobs: int = 1) -> Path:
    """Derived campaign with ``scale`` x sensor noise (features precomputed into its cache)."""
    from server.phm.features import FEATURE_VERSION, FeatureConfig

    s, d = Path(src), Path(dst)
    manifest = json.loads((s / "manifest.json").read_text())
    _link_flights(s, d)
    manifest["derived"] = {"from": str(s.resolve()), "sensor_noise_scale": scale, "seed": seed}
    args = [(str(s / fl["file"]), fl["file"], fl.get("ground_temp_c"), scale, seed)
            for p in manifest["patterns"] for fl in p["flights"]]
    if jobs > 1:
        with ProcessPoolExecutor(max_workers=jobs) as ex:
            res = dict(ex.map(_noisy_features, args, chunksize=4))
    else:
        res = dict(map(_noisy_features, args))
    (d / "phm_features.json").write_text(json.dumps(
        {"config": f"{FEATURE_VERSION} {FeatureConfig()!r}", "flights": res}))
    (d / "manifest.json").write_text(json.dumps(manifest, indent=1))
    return d


def subset_campaign(src: str | os.PathLike[str], dst: str | os.PathLike[str],
                    keep: Callable[[Mapping[str, Any]], bool]) -> Path:
    """Derived campaign with the aircraft ``keep(aircraft)`` accepts and their patterns."""
    s, d = Path(src), Path(dst)
    manifest = json.loads((s / "manifest.json").read_text())
    tails = {a["tail"] for a in manifest["aircraft"] if keep(a)}
    manifest["aircraft"] = [a for a in manifest["aircraft"] if a["tail"] in tails]
    manifest["patterns"] = [p for p in manifest["patterns"] if p["aircraft"] in tails]
    manifest["derived"] = {"from": str(s.resolve()), "aircraft": sorted(tails)}
    _link_flights(s, d)
    cache = s / "phm_features.json"
    if cache.exists():
        doc = json.loads(cache.read_text())
        files = {fl["file"] for p in manifest["patterns"] for fl in p["flights"]}
        doc["flights"] = {k: v for k, v in doc["flights"].items() if k in files}
        (d / "phm_features.json").write_text(json.dumps(doc))
    (d / "manifest.json").write_text(json.dumps(manifest, indent=1))
    return d


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=(__doc__ or "").split("\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    n = sub.add_parser("noise", help="same campaign, sensor noise x scale")
    n.add_argument("--campaign", required=True)
    n.add_argument("--out", required=True)
    n.add_argument("--scale", type=float, default=2.0)
    n.add_argument("--seed", type=int, default=0)
    n.add_argument("--jobs", type=int, default=min(2, os.cpu_count() or 1))
    c = sub.add_parser("climate", help="hold one climate out of design, verify on it only")
    c.add_argument("--design", required=True)
    c.add_argument("--verification", required=True)
    c.add_argument("--hold-out", required=True, help="climate: temperate, cold or hot")
    c.add_argument("--out", required=True, help="writes OUT/design and OUT/verification")
    args = ap.parse_args(argv)
    if args.cmd == "noise":
        d = noisy_campaign(args.campaign, args.out, scale=args.scale, seed=args.seed,
                           jobs=args.jobs)
        print(f"wrote {d}")
    else:
        out = Path(args.out)
        held = str(args.hold_out)
        d = subset_campaign(args.design, out / "design", lambda a: a.get("climate") != held)
        v = subset_campaign(args.verification, out / "verification",
                            lambda a: a.get("climate") == held)
        for p in (d, v):
            m = json.loads((p / "manifest.json").read_text())
            print(f"wrote {p}: {len(m['aircraft'])} aircraft, {len(m['patterns'])} patterns")
    return 0


if __name__ == "__main__":
    sys.exit(main())
