"""One unit through the online judge on its own, for tests about a single unit's statistics."""

from __future__ import annotations

from collections.abc import Mapping

from server.phm.detection import DetectionResult, DetectionState, FaultDetector, update_units


def judge_alone(detector: FaultDetector, state: DetectionState, z: Mapping[str, float],
                extra_variance: Mapping[str, float] | None = None,
                evidence: Mapping[str, float] | None = None) -> DetectionResult:
    """One flight of one unit, judged without its partner (so nothing is held)."""
    return update_units(detector, {state.unit: state}, z, extra_variance, evidence)[state.unit]
