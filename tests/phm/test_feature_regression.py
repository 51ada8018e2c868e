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
new kind of machine with no simulator change is that.)
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
               "ee8766bd24db1a0f020966de5173d3dd8c362279a98b7f4288b50be0ae27821e"),
    "TTS": ("2a835ee09bf9ae337aefd9090dc54ec4250effe934e7bad3531be7387f23daf3",
           "442d400a37ede0ca0423c33b8a4c69573e2cc89345f393d09ce89fa6a1b340eb"),
    "DMD": ("675584a90d9f51753b546b095de768ee63a8777391a68eec309ee36ac2cb882e",
           "c1384b80a77315d67742b6c9151ed1359aa1023e7b2a4faa36f3737bc86bad47"),
    "SE": ("8804e1f2a8b697c6979b35986fe8af74eaa91e09fe5557ceb9eb097a8b1e22b6",
          "edffd6a791d51c9dc077821e46374b42b00e3421548425609b68d61ffee2d7a4"),
    "BDO": ("af98c09a9b37aba944d598afc3c5dd7374745097e8b7d901618ab9005c9bea74",
           "b2ecc832175098cd86dc9ce6137785346ad9f8a45ec23381b57b3f6e910c3c52"),
    "MTEL": ("563015d8711c048546cf7902fa7d2f71252ee05fe6f1824dd85b4b10dfe819f9",
            "e35414acb1cac26d4d4e1e84efc758323a33b0b5b169510112faa7e103858115"),
    "MTWEAR": ("a8bbcaaaee87eac54f7385e93885bf2660862c14d782363b692a032e1aadc7c8",
              "859858d13fda5fddcac02e7461d60dca39f8a737acbf0359e5b9a63f86202d12"),
    "REWEAR": ("4010adbfbf42bfa349369022b0d4a836f6c917b7be42693927ab9082d9a33448",
              "2f000d25c13aaf74d951ef7419bd30d84296fc4e41522ab7ca233514f0ebdf2b"),
    "standby healthy": ("e53bbac22a34a410b93f7f676de9ced9b20e646615bec7775fb2de87d2cc187b",
                       "a7842f68170f19e89e8e76ba91ad306c8ff5d2a8aad341ec2d25e9fc0689e89e"),
    "standby TTS": ("03e0e758148290f2c7e1ecd3b730449f7a860f1ee7abe83c91c65c4119f0fa90",
                   "a5977e0f201f7737663064d06275c2cba27aed94814f5bfcc887afa6ba8a6fbb"),
    "standby DMD": ("ab4fcbf15629c5cda3444ce044d7f6790bb0fb16896ea0ff174d3139fa73f78e",
                   "db009670bfee0e4fc7757014f9ccaece22eeb07970874ac10457b177059d13d9"),
    "standby SE": ("1bfd6de8556702065f0c2338cc3a8597f3f3a2ee19f78d4f394a302b6d82f334",
                  "fe0a7e9400c14539b14846baa604ab376bdfd438bb4827e562bedd99288eed2d"),
    "standby BDO": ("e70a210dd3e75d17238d888c3077679e9a73e7f9bf67afb5f96f658de0fdb0a1",
                   "3b8b20c5c786f98032a4fd7f93b5032034a74530e2b2bf517cef3663cf440f6f"),
    "standby MTEL": ("e6056bd347bf331b88923aa9b5d990e7a7137cfe0ceb400053f3297298f8b4b7",
                    "7f282e6ded441737631018349737ad28030d74c55152f1e2a4989cddc44a6475"),
    "standby MTWEAR": ("7a05ddbec612bb8b7047c75cbec8a2c93a857f69cae906a19451d5bc7c7306bf",
                      "6bd5994d9cdb2f444c54c1cb2665e2fe96071e69e22cf05b9be40ceb11d083ea"),
    "standby REWEAR": ("b69c7ae1276b63a8600793848a5c01dd439a2e4c8b338136d09ef9940b7e556d",
                      "db1375ff5c954b9a5110666324dfd2dc44391d69867870a45f2ce566ba37c2b4"),
    "other standby healthy": ("abf5269385456e1bda3a3c15ce541d8cdc5121023c6297e10e916e38be93e555",
                             "ebfaa24d5735fe1bcf8149898065c883473fc8769dad9af0cc83494e7e6f8279"),
    "other standby REWEAR": ("360a1aa2d8a765660c7e5b65fedfbb9ebc7963a6ca9afa66059a64e73cc1ab90",
                            "7c356607466a0823932fbaee1d4c2e42b6ec823b09f56a73aa036db20595d035"),
    "other standby MTEL": ("82ca493474faba88b517bf98658758c75eecf45c6fa54849607e18c46ee0466b",
                          "552ab29adadcb098d3cadad091cdf09b4f8d74cde2b2adb09ac3cd01817f9bac"),
    "other standby MTWEAR": ("c284e21296e9c77064ba1d6568e25ccdb04e63f832bd25e61ac4393b563aec62",
                            "c8f685233a26cf59c08c00d560163cb5d4fd6cbeb80ed89b2ca75d40c6aaa4fa"),
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
