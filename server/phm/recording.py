"""The features of a decoded flight log: what the chain reads of a recording.

The chain does not import the format's package (``server.flightlog`` stands apart, see the
layer contracts in pyproject.toml): a log is anything with ``channels`` and a ``metadata``
naming its active drives, :class:`server.flightlog.FlightLog` among them.
"""

from __future__ import annotations

from collections.abc import Collection, Iterator, Mapping
from typing import Protocol

import numpy as np

from .features import FeatureConfig, FlightFeatures, flight_features

__all__ = ["DecodedLog", "Float64Channels", "log_features"]


class _Roles(Protocol):
    @property
    def active_channels(self) -> Collection[str] | None: ...


class DecodedLog(Protocol):
    """A decoded flight log as the features read it."""

    @property
    def channels(self) -> Mapping[str, np.ndarray]: ...

    @property
    def metadata(self) -> _Roles: ...


class Float64Channels(Mapping[str, np.ndarray]):
    """A log's channels as float64, each converted when first read and kept.

    The features are computed in float64 whatever the log stores (format v1 signals are
    float32); channels they never read (rod commands, surface deflections) are never copied,
    and one already float64 (``t``) is not copied either.
    """

    def __init__(self, stored: Mapping[str, np.ndarray]) -> None:
        self._stored = stored
        self._read: dict[str, np.ndarray] = {}

    def __getitem__(self, name: str) -> np.ndarray:
        if name not in self._read:
            self._read[name] = np.asarray(self._stored[name], dtype=np.float64)
        return self._read[name]

    def __contains__(self, name: object) -> bool:  # without converting the channel
        return name in self._stored

    def __iter__(self) -> Iterator[str]:
        return iter(self._stored)

    def __len__(self) -> int:
        return len(self._stored)


def log_features(log: DecodedLog, *, config: FeatureConfig | None = None,
                 ground_temp_c: float | None = None) -> FlightFeatures:
    """A decoded flight log's features (:func:`server.phm.features.flight_features` on its
    channels as float64), its drives' roles taken from its metadata: what the service computes
    on an upload and a campaign on each flight."""
    return flight_features(Float64Channels(log.channels), config=config,
                           ground_temp_c=ground_temp_c,
                           active_channels=log.metadata.active_channels)
