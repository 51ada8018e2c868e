"""Test-station sensor injections, flown in the loop (``sim-worker run``).

Each kind changes the sensor model the kernel samples, never the recorded log after the fact,
so the controller closes its loops on the degraded reading as it would on a real aircraft:

* ``noise``: that sensor's rms noise (one actuator's) multiplied by the factor;
* ``drift`` (LVDT): its offset grows by ``value`` metres a flight from the flight the injection
  started on (flight ``started``: one step, the next: two, ...); the position loop closes on
  the LVDT, so the rod settles off its command by the offset, as a drifting LVDT's would;
* ``quantisation``: the sensor's converter step replaced by the coarser ``value``;
* ``stuck``: every reading is ``value`` (a frozen converter); ``clipped``: readings held within
  +-``value`` (a saturated one). Both clamp the kernel's reading after noise and quantisation
  (``SensorParams.*_clamp``), so the loop that closes on it reads the frozen value: a stuck
  resolver freezes the commutation angle (flown), a stuck or clipped LVDT would drive the rod
  past its stroke (no end stops are modelled: the API refuses it, server/schemas.py).

Nothing of this reaches the flight's metadata; the runner reports what it applied as ground
truth (``PUT /test-station/sensor-injections/{id}/ground-truth``).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

from .fleet import Aircraft

__all__ = ["SensorInjection", "degrade"]

#: the SensorParams fields of each sensor: (noise rms, quantisation step, output clamp)
_FIELDS = {"current": ("current_noise_a", "current_lsb_a", "current_clamp_a"),
           "voltage": ("voltage_noise_v", "voltage_lsb_v", "voltage_clamp_v"),
           "resolver": ("resolver_noise_rad", "resolver_lsb_rad", "resolver_clamp_rad"),
           "lvdt": ("lvdt_noise_m", "lvdt_lsb_m", "lvdt_clamp_m")}


@dataclass(frozen=True)
class SensorInjection:
    id: int
    position: str
    sensor: str
    kind: str
    value: float
    started: int

    @classmethod
    def from_api(cls, doc: dict[str, Any], flight: int) -> SensorInjection:
        """From the API's document; a pending one starts on ``flight``."""
        started = doc.get("started_flight")
        return cls(int(doc["id"]), doc["position"], doc["sensor"], doc["kind"],
                   float(doc["value"]), int(started) if started is not None else flight)

    def applied(self, flight: int) -> float:
        """What it does on ``flight``: the noise factor, the LVDT offset added [m] or the
        step."""
        if self.kind == "drift":
            return self.value * (flight - self.started + 1)
        return self.value


def degrade(aircraft: Aircraft, injections: list[SensorInjection], flight: int) -> Aircraft:
    """The aircraft as flown on ``flight`` with its sensor injections in its sensor models."""
    flown = aircraft
    for inj in injections:
        if inj.kind == "drift":
            rigging = aircraft.offsets[inj.position][3]
            flown = flown.with_lvdt_offset(inj.position, rigging + inj.applied(flight))
            continue
        field, new = _sensor_change(inj, flown.ema[inj.position].sensors)
        p = flown.ema[inj.position]
        flown = replace(flown, ema={**flown.ema, inj.position: p.with_(
            sensors=replace(p.sensors, **{field: new}))})
    return flown


def _sensor_change(inj: SensorInjection, sensors: Any) -> tuple[str, Any]:
    """The SensorParams field the injection sets, and its new value."""
    noise, step, clamp = _FIELDS[inj.sensor]
    if inj.kind == "noise":
        return noise, getattr(sensors, noise) * inj.value
    if inj.kind == "quantisation":
        return step, inj.value
    if inj.kind == "stuck":
        return clamp, (inj.value, inj.value)
    return clamp, (-abs(inj.value), abs(inj.value))  # clipped
