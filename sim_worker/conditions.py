"""Test-station simulation conditions on an aircraft, flown by ``sim-worker run``.

Each condition moves an input of the flight's physics, never the recorded log after the fact:

* ``ambient_offset`` [K]: the air, ground to cruise, hotter or colder by the offset (an ISA
  deviation): the thermal model's ambient, hence the winding temperature and its resistance.
  The recorder's ``T_amb`` channel reads that air, as a real air-temperature probe would;
* ``load_scale``: eq. (1)'s drawn sigma_F multiplied by the value: the aerodynamic hinge load
  the drives hold is that much larger (the gust is not scaled: it is turbulence, not the
  set-point), so the phase currents and the copper losses grow with it;
* ``load_offset`` [N]: added to eq. (1)'s drawn sigma_F0 on both surfaces (a trim load);
* ``command_scale``: eq. (1)'s drawn sigma_x multiplied by the value: larger or smaller
  commanded surface motion, clipped at the command limit as every command is;
* ``base``: the flight's ground temperature drawn from that base's climate instead of the
  aircraft's own.

Nothing of this reaches the flight's metadata (its aircraft keeps its base); the runner reports
what it flew as ground truth (``PUT /test-station/conditions/{id}/ground-truth``). With no
condition the flight is bit-identical to one flown without this module: the random draws are
the same and nothing is added.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

from .scenario import Warp

__all__ = ["Conditions", "NO_CONDITIONS", "from_api"]


@dataclass(frozen=True)
class Conditions:
    """The conditions one flight is flown under; the defaults change nothing."""

    ambient_offset_k: float = 0.0
    load_scale: float = 1.0
    load_offset_n: float = 0.0
    command_scale: float = 1.0
    base: str | None = None

    def warp(self, warp: Warp) -> Warp:
        """Eq. (1)'s drawn warp with the load and command conditions applied."""
        if (self.load_scale, self.load_offset_n, self.command_scale) == (1.0, 0.0, 1.0):
            return warp
        # per surface (winglet, wingtip), as eq. (1) draws them
        x, f, f0 = warp.sigma_x, warp.sigma_f, warp.sigma_f0_n
        return replace(
            warp, sigma_x=(x[0] * self.command_scale, x[1] * self.command_scale),
            sigma_f=(f[0] * self.load_scale, f[1] * self.load_scale),
            sigma_f0_n=(f0[0] + self.load_offset_n, f0[1] + self.load_offset_n))


NO_CONDITIONS = Conditions()

#: the Conditions field each kind sets (a base is a name, every other kind a number)
_FIELD = {"ambient_offset": "ambient_offset_k", "load_scale": "load_scale",
          "load_offset": "load_offset_n", "command_scale": "command_scale", "base": "base"}


def from_api(docs: list[dict[str, Any]]) -> Conditions:
    """The conditions of the API's documents (one live per kind: the service refuses two)."""
    out = NO_CONDITIONS
    for doc in docs:
        kind = doc["kind"]
        value: str | float = doc["base"] if kind == "base" else float(doc["value"])
        # the kind picks the field: a str for the base, a float for every other
        out = replace(out, **{_FIELD[kind]: value})  # type: ignore[arg-type]
    return out
