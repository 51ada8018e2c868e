"""Sensor faults of a campaign (sensor-health studies): their specs (:class:`SensorFault`,
``WT.lvdt:noise=2``, ``WL1.lvdt:drift=1e-06``) in a canonical order, and the aircraft they
give: noisier sensors as rigged, a drifting LVDT as flown at each flight.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, replace
from typing import Any

from server.vocabulary import POSITIONS, SENSORS

from ..fleet import Aircraft

__all__ = ["SensorFault", "canonical_sensor_faults", "with_noise", "with_sensor_noise", "at_flight"]

#: the noise field of each sensor in :class:`~sim_worker.params.SensorParams`
_NOISE_FIELD = {"current": "current_noise_a", "voltage": "voltage_noise_v",
                "resolver": "resolver_noise_rad", "lvdt": "lvdt_noise_m"}
_FAULT_KINDS = ("noise", "drift")


@dataclass(frozen=True)
class SensorFault:
    """One degraded sensor of one actuator (sensor-health studies), on every aircraft.

    ``noise``: that actuator's noise of that sensor multiplied by ``value`` (> 0, on top of
    ``noise_scale``). ``drift`` (LVDT only): its offset grows by ``value`` metres per flight,
    rigging offset + value x flight index of the pattern. Spec: ``WT.lvdt:noise=2``,
    ``WL1.lvdt:drift=1e-06``.
    """

    position: str
    sensor: str
    kind: str
    value: float

    def __post_init__(self) -> None:
        if self.position not in POSITIONS:
            raise ValueError(f"unknown position {self.position!r}; expected one of "
                             f"{', '.join(POSITIONS)}")
        if self.sensor not in SENSORS:
            raise ValueError(f"unknown sensor {self.sensor!r}; expected one of "
                             f"{', '.join(SENSORS)}")
        if self.kind not in _FAULT_KINDS:
            raise ValueError(f"unknown sensor fault {self.kind!r}; expected noise or drift")
        if self.kind == "drift" and self.sensor != "lvdt":
            raise ValueError(f"drift is an LVDT fault, not a {self.sensor} one")
        value = float(self.value)
        if not math.isfinite(value):
            raise ValueError(f"{self.kind} must be finite, got {value}")
        if self.kind == "noise" and not value > 0:
            raise ValueError(f"noise factor must be positive, got {value:g}")
        object.__setattr__(self, "value", value)  # a plain float: the spec is canonical

    @classmethod
    def parse(cls, spec: str) -> SensorFault:
        """``<POSITION>.<SENSOR>:noise=<factor>`` or ``<POSITION>.lvdt:drift=<m per flight>``."""
        target, sep, setting = spec.strip().partition(":")
        position, dot, sensor = target.partition(".")
        kind, eq, text = setting.partition("=")
        if not (sep and dot and eq):
            raise ValueError(f"sensor fault {spec!r} is not POSITION.SENSOR:noise=FACTOR or "
                             "POSITION.lvdt:drift=METRES")
        try:
            value = float(text)
        except ValueError:
            raise ValueError(f"sensor fault {spec!r}: {text!r} is not a number") from None
        return cls(position.strip(), sensor.strip(), kind.strip(), value)

    @property
    def spec(self) -> str:
        # repr round-trips the float exactly; "2.0" is written "2"
        text = repr(self.value)
        return f"{self.position}.{self.sensor}:{self.kind}=" + text.removesuffix(".0")


def canonical_sensor_faults(faults: Iterable[SensorFault | str] | None) -> tuple[SensorFault, ...]:
    """Faults (specs parsed) in a canonical order, so that the settings of a campaign do not
    depend on the order they were given in; one fault per position, sensor and kind."""
    parsed = [f if isinstance(f, SensorFault) else SensorFault.parse(f) for f in faults or ()]
    seen: set[tuple[str, str, str]] = set()
    for f in parsed:
        key = (f.position, f.sensor, f.kind)
        if key in seen:
            raise ValueError(f"sensor fault {f.position}.{f.sensor}:{f.kind} given twice")
        seen.add(key)
    return tuple(sorted(parsed, key=lambda f: (POSITIONS.index(f.position),
                                               SENSORS.index(f.sensor), f.kind)))


def with_noise(aircraft: Aircraft, factor: float) -> Aircraft:
    def scaled(p: Any) -> Any:
        sen = p.sensors
        return p.with_(sensors=replace(
            sen, current_noise_a=sen.current_noise_a * factor,
            voltage_noise_v=sen.voltage_noise_v * factor,
            resolver_noise_rad=sen.resolver_noise_rad * factor,
            lvdt_noise_m=sen.lvdt_noise_m * factor))

    return replace(aircraft, ema={pos: scaled(p) for pos, p in aircraft.ema.items()})


def with_sensor_noise(aircraft: Aircraft, faults: Iterable[SensorFault]) -> Aircraft:
    ema = dict(aircraft.ema)
    for f in faults:
        sen, field = ema[f.position].sensors, _NOISE_FIELD[f.sensor]
        ema[f.position] = ema[f.position].with_(
            sensors=replace(sen, **{field: getattr(sen, field) * f.value}))
    return replace(aircraft, ema=ema)


def at_flight(aircraft: Aircraft, faults: Iterable[SensorFault], index: int) -> Aircraft:
    """The aircraft as flown at flight ``index`` of a pattern: each drifting LVDT's offset
    grown linearly from its rigging offset (the kernel reads the offset from the parameter
    row, so the drift acts in the loop that closes on the LVDT, as a real one would)."""
    flown = aircraft
    for f in faults:
        if f.kind == "drift":
            rigging = aircraft.offsets[f.position][3]
            flown = flown.with_lvdt_offset(f.position, rigging + f.value * index)
    return flown
