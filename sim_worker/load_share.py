"""Load share of a worn drive: how much of the quasi-static sliding work it really does.

:func:`~sim_worker.flight.estimate_summary` computes a flight's sliding work from the surface's
aerodynamic load alone. The 12 kHz model knows better: added backlash in one drive of the
winglet pair lets its partner hold the tab, so the worn drive carries less and less of the load
as it wears (rod-end free play at failure leaves it about 7 % of its healthy work). Archard wear
is driven by that work, so the wear slows itself down.

``g(mode, position, s_n)`` is the ratio *simulated work / estimated work* of the faulty drive at
normalised severity ``s_n``, measured by :func:`sim_worker.calibration.measure_load_share` on
flights simulated at 12 kHz (ratio of summed works over paired flights, same conditions) and
stored in ``data/load_share.json``. It is used twice, so that a fault grows the same way whether
its flights are rendered or not:

* :func:`~sim_worker.flight.estimate_summary` multiplies the faulty drive's estimated work by it
  (flights of a campaign that are not rendered);
* :func:`~sim_worker.faults.new_fault` sets the wear rate so that the *expected* life at the
  reference conditions, integrated with it, is the drawn (or the operator's) span of flights.

Modes whose driver is not a sliding work (thermal modes) have no entry: ``g = 1``. Neither has a
pair flying active-standby: its active drive carries the hinge moment and its standby its own
drag whatever their wear, and :func:`~sim_worker.flight.estimate_summary` knows the roles
(rendered over estimated work 0.95 at onset, 0.93 at failure for REWEAR, 1.02 throughout for
MTWEAR, tests/sim/test_active_standby.py).
"""

from __future__ import annotations

import json
from functools import cache
from importlib import resources

import numpy as np

from .fleet import WingletMode

__all__ = ["WORK_FIELD", "load_share", "life_integral", "table"]

#: the ActuatorSummary field that drives each wear mode (faults.driver)
WORK_FIELD: dict[str, str] = {"MTWEAR": "work_screw_n_m", "REWEAR": "work_rod_end_n_m"}
_FORMAT = "ema-load-share/1"


@cache
def table() -> dict:
    """The measured table (``data/load_share.json``): ``{"severity_norm": [...],
    "ratio": {mode: {position: [...]}}, ...}``."""
    doc = json.loads(resources.files("sim_worker").joinpath("data/load_share.json").read_text())
    if doc.get("format") != _FORMAT:
        raise ValueError(f"data/load_share.json: expected format {_FORMAT!r}")
    return doc


def _shares(mode: str, position: str, severity_norm: np.ndarray,
            winglet_mode: WingletMode) -> np.ndarray:
    """:func:`load_share` at every severity of an array."""
    if WingletMode(winglet_mode) is WingletMode.ACTIVE_STANDBY:
        return np.ones_like(severity_norm, dtype=float)
    doc = table()
    curve = doc["ratio"].get(mode, {}).get(position)
    if curve is None:
        return np.ones_like(severity_norm, dtype=float)
    return np.interp(severity_norm, doc["severity_norm"], curve)


def load_share(mode: str, position: str, severity_norm: float, *,
               winglet_mode: WingletMode) -> float:
    """Simulated over estimated work of the faulty drive (1.0 for modes without an entry and
    under active-standby; the mode is required: a default would silently give 1.0 to an
    active-active caller)."""
    return float(_shares(mode, position, np.asarray(severity_norm, dtype=float), winglet_mode))


def life_integral(mode: str, position: str, onset_norm: float, growth_c: float, *,
                  winglet_mode: WingletMode) -> float:
    """``int_onset^1 ds / (g(s) (s + c))``: flights to failure times rate times driver.

    The progression ``ds/dn = rate d g(s) (s + c)`` (faults.advance_fault, with the driver ``d``
    of the estimated reference flight) reaches ``s = 1`` after this integral / (rate d) flights.
    """
    s = np.linspace(onset_norm, 1.0, 401)
    shares = _shares(mode, position, s, winglet_mode)
    return float(np.trapezoid(1.0 / (shares * (s + growth_c)), s))
