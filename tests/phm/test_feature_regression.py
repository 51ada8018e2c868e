"""Bit-for-bit regression of the feature extraction: short simulated flights (healthy and every
fault mode, both winglet modes, either winglet drive standing by) through the extraction
:func:`server.phm.recording.log_features` runs, hashed against recorded values.

Each case's hash covers every output of the extraction: the 20 summaries, the conditions and
signal-quality figures of each actuator, and every 80 Hz track (series and validity). They
must change only with a deliberate change of a feature's formula or validity (which bumps
``FEATURE_VERSION``, recorded beside them) or of the simulated flights; a refactor must leave
them alone. The flights' own hashes are recorded too, so a failure says which of the two moved.
After a deliberate change, re-record them with ``python tests/phm/test_feature_regression.py``
and say why in the commit. (Like ``tests/sim/test_kernel_regression.py``, the values depend on
the platform's libm and the simulator's FMA contraction: a failure of the flight hashes on a
new kind of machine with no simulator change is that. The extraction itself calls no LAPACK:
its small least-squares systems are solved by one compiled elimination, because LAPACK's
kernels, and so the last bits of its answers, change with the processor.)
"""

from __future__ import annotations

import hashlib
import math
from functools import cache
from typing import Any

import numpy as np
import pytest

from server.phm.features import FEATURE_VERSION, FlightFeatures, flight_features
from server.phm.recording import Float64Channels
from sim_worker.faults import fault_at
from sim_worker.fleet import WingletMode, build_aircraft
from sim_worker.flight import simulate_flight

AA, AS = WingletMode.ACTIVE_ACTIVE, WingletMode.ACTIVE_STANDBY

#: (mode, position, severity / threshold, winglet mode, flight): active-standby flight 0 has
#: WL2 standing by, flight 1 WL1
CASES: dict[str, tuple[str, str | None, float, WingletMode, int]] = {
    "healthy": ("healthy", None, 0.0, AA, 0),
    "TTS": ("TTS", "WL1", 0.6, AA, 0),
    "DMD": ("DMD", "WT", 0.6, AA, 0),
    "SE": ("SE", "WL2", 0.6, AA, 0),
    "BDO": ("BDO", "WT", 1.0, AA, 0),
    "MTEL": ("MTEL", "WL1", 0.7, AA, 0),
    "MTWEAR": ("MTWEAR", "WL2", 0.7, AA, 0),
    "REWEAR": ("REWEAR", "WL1", 0.7, AA, 0),
    "standby healthy": ("healthy", None, 0.0, AS, 0),
    "standby TTS": ("TTS", "WL2", 0.6, AS, 0),
    "standby DMD": ("DMD", "WL1", 0.6, AS, 0),
    "standby SE": ("SE", "WT", 0.6, AS, 0),
    "standby BDO": ("BDO", "WL1", 1.0, AS, 0),
    "standby MTEL": ("MTEL", "WT", 0.7, AS, 0),
    "standby MTWEAR": ("MTWEAR", "WL1", 0.7, AS, 0),
    "standby REWEAR": ("REWEAR", "WL2", 0.7, AS, 0),
    "other standby healthy": ("healthy", None, 0.0, AS, 1),
    "other standby REWEAR": ("REWEAR", "WL1", 0.7, AS, 1),
    "other standby MTEL": ("MTEL", "WL2", 0.7, AS, 1),
    "other standby MTWEAR": ("MTWEAR", "WT", 0.7, AS, 1),
}

RECORDED_VERSION = "features/10"

#: case -> (hash of the flight's channels, hash of its features)
EXPECTED: dict[str, tuple[str, str]] = {
    "healthy": ("409d3f406dfcbe70e0952aa25917f3198dc38081114c82712189de3a07392a38",
               "63cdc3e0af3e4bc45b777be390dd2c99baa71bc74c6e2438bd9318c6a1d68fd1"),
    "TTS": ("2a835ee09bf9ae337aefd9090dc54ec4250effe934e7bad3531be7387f23daf3",
           "8e0ded44b46ee8ed19c8032d3c86d38775f1a4ba9d9f5dbbecdffcd048f2199b"),
    "DMD": ("675584a90d9f51753b546b095de768ee63a8777391a68eec309ee36ac2cb882e",
           "6f5779edeb835e8ee2ecbea0927a1b9399c5a8b9497fc2c32a848fec950b332b"),
    "SE": ("8804e1f2a8b697c6979b35986fe8af74eaa91e09fe5557ceb9eb097a8b1e22b6",
          "00927e09b6712ecd1deca91d62a7d891295d83978cd893f9797416a62535dcdc"),
    "BDO": ("af98c09a9b37aba944d598afc3c5dd7374745097e8b7d901618ab9005c9bea74",
           "9e9910e081718d406036d443ef8272a5d89b5147275a3fe8c0a1ca5323995af7"),
    "MTEL": ("563015d8711c048546cf7902fa7d2f71252ee05fe6f1824dd85b4b10dfe819f9",
            "4a2ce5bf93a2754ed8f292f4d44dd9b44b53c74a4ca2f66d76cac1227cfd6b5a"),
    "MTWEAR": ("a8bbcaaaee87eac54f7385e93885bf2660862c14d782363b692a032e1aadc7c8",
              "3951ba4b6cb0ad3f9dddd8ac031966b0d282fb2e1772d58da0c5b312c00ee344"),
    "REWEAR": ("4010adbfbf42bfa349369022b0d4a836f6c917b7be42693927ab9082d9a33448",
              "813b70d12fb3af75f63c2a63afd815ffff7d675115aed749745aec60efe1ed71"),
    "standby healthy": ("e53bbac22a34a410b93f7f676de9ced9b20e646615bec7775fb2de87d2cc187b",
                       "fee18ab951cb143d4f60f102180989756c406a3356e45e0d8a26af4ab5270245"),
    "standby TTS": ("03e0e758148290f2c7e1ecd3b730449f7a860f1ee7abe83c91c65c4119f0fa90",
                   "380fd429584fc47bf90145f7efa0ae4f9b21ca9b8d8f0881bd9b3e46b729d3a2"),
    "standby DMD": ("ab4fcbf15629c5cda3444ce044d7f6790bb0fb16896ea0ff174d3139fa73f78e",
                   "03b6bec41ac5c4d2583ac7276b8653231851bb23ca1f490cc446c9eb22e92836"),
    "standby SE": ("1bfd6de8556702065f0c2338cc3a8597f3f3a2ee19f78d4f394a302b6d82f334",
                  "3e7a16d944fe566549899c855d39e6c1e0d0980698628d258e5250da00f078fc"),
    "standby BDO": ("e70a210dd3e75d17238d888c3077679e9a73e7f9bf67afb5f96f658de0fdb0a1",
                   "1acfbd2b950d023ea2daff8b370b2e5cf70603a2edcb50fb62248eb6e6ccf0c0"),
    "standby MTEL": ("e6056bd347bf331b88923aa9b5d990e7a7137cfe0ceb400053f3297298f8b4b7",
                    "0b7840f3d5ea1d67427f4128e8e49ad20f4b3120a403580fc515204cc165c9bd"),
    "standby MTWEAR": ("7a05ddbec612bb8b7047c75cbec8a2c93a857f69cae906a19451d5bc7c7306bf",
                      "26ef2a4cc7e32116051dc437463bb9c1f664413d9a983361967de873a4fba982"),
    "standby REWEAR": ("b69c7ae1276b63a8600793848a5c01dd439a2e4c8b338136d09ef9940b7e556d",
                      "ccb2f757b685a5b02c4dbeb0debac259bb2b39b03ba4e822cb3c0591e7b789ae"),
    "other standby healthy": ("abf5269385456e1bda3a3c15ce541d8cdc5121023c6297e10e916e38be93e555",
                             "e797b10979063caf3b7842256c77af809b7fdccf2cf8f900390ed08214b174a5"),
    "other standby REWEAR": ("360a1aa2d8a765660c7e5b65fedfbb9ebc7963a6ca9afa66059a64e73cc1ab90",
                            "d2013a4d83c2ccb04bd0a31fb2ef63c08126acf52898aaac79c112fab10ce34f"),
    "other standby MTEL": ("82ca493474faba88b517bf98658758c75eecf45c6fa54849607e18c46ee0466b",
                          "203a2e1fdcdc21c583a2ccdbf491e6b9b9fc0ae9bf575cb8b7afbdd4a853d196"),
    "other standby MTWEAR": ("c284e21296e9c77064ba1d6568e25ccdb04e63f832bd25e61ac4393b563aec62",
                            "38e08fe4348f46750419c5bcd14bc04a6503beda225a473bf1fb81816be09b5d"),
}

_DURATION_S = 30.0  # the reference cycle compressed: climb, cruise and descent in 30 s


@cache
def _flight(case: str) -> Any:
    mode, position, severity_norm, winglet_mode, flight = CASES[case]
    fault = fault_at(mode, position, severity_norm, phase_rad=1.0 if mode == "SE" else 0.0)
    aircraft = build_aircraft("I-FEAT01", "Turin", seed=2025)
    log, _ = simulate_flight(aircraft, fault, flight, np.random.default_rng([11, flight]),
                             duration_s=_DURATION_S, winglet_mode=winglet_mode)
    return log


def _float_bytes(x: float) -> bytes:
    return np.float64(x).tobytes() if not math.isnan(x) else b"nan"


def features_hash(features: FlightFeatures) -> str:
    """sha256 of every output of one flight's extraction, in a fixed order."""
    h = hashlib.sha256()
    for name, s in features.summaries.items():
        h.update(name.encode())
        h.update(_float_bytes(s.value) + _float_bytes(s.dispersion) + str(s.n_valid).encode())
    for group in (features.conditions, features.quality):
        for key, figures in group.items():
            h.update(key.encode())
            for name, value in figures.items():
                h.update(name.encode() + _float_bytes(float(value)))
    for name, track in (features.tracks or {}).items():
        h.update(name.encode())
        h.update(np.ascontiguousarray(track.series, dtype="<f8").tobytes())
        h.update(np.ascontiguousarray(track.valid, dtype=bool).tobytes())
        h.update(_float_bytes(track.value) + _float_bytes(track.dispersion)
                 + str(track.n_valid).encode())
    return h.hexdigest()


def flight_hash(case: str) -> str:
    h = hashlib.sha256()
    for name, values in _flight(case).channels.items():
        h.update(name.encode() + np.ascontiguousarray(values).tobytes())
    return h.hexdigest()


def case_features(case: str) -> FlightFeatures:
    """What :func:`server.phm.recording.log_features` computes on the case's flight, with the
    80 Hz tracks kept."""
    log = _flight(case)
    return flight_features(Float64Channels(log.channels), keep_tracks=True,
                           active_channels=log.metadata.active_channels)


def case_hashes(case: str) -> tuple[str, str]:
    return flight_hash(case), features_hash(case_features(case))


def test_the_recorded_hashes_are_of_todays_feature_version() -> None:
    assert FEATURE_VERSION == RECORDED_VERSION, (
        "a new feature version: re-record the hashes (python tests/phm/test_feature_regression.py)")
    assert set(EXPECTED) == set(CASES)


@pytest.mark.parametrize("case", list(CASES))
def test_features_bit_for_bit(case: str) -> None:
    flight, features = case_hashes(case)
    assert flight == EXPECTED[case][0], "the simulated flight changed (see the module's note)"
    assert features == EXPECTED[case][1], "the features of an unchanged flight changed"


if __name__ == "__main__":  # print the values to record
    print(f'RECORDED_VERSION = "{FEATURE_VERSION}"')
    print("EXPECTED: dict[str, tuple[str, str]] = {")
    for name in CASES:
        flight_h, features_h = case_hashes(name)
        print(f'    "{name}": ("{flight_h}",\n{" " * (8 + len(name))}"{features_h}"),')
    print("}")
