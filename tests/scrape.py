"""Reading a /metrics scrape in tests: every sample by name and labels."""

from __future__ import annotations

from prometheus_client.parser import text_string_to_metric_families

__all__ = ["STAGES", "samples", "value"]

#: the stages of an analysis, as /metrics labels them
STAGES = ("decode", "features", "detection", "classification", "prognosis")


def samples(text: str) -> dict[tuple[str, frozenset], float]:  # type: ignore[type-arg]
    """Every sample of a scrape: (name, labels) -> value."""
    return {(s.name, frozenset(s.labels.items())): s.value
            for family in text_string_to_metric_families(text) for s in family.samples}


def value(scrape: dict, name: str, **labels: str) -> float | None:  # type: ignore[type-arg]
    """One sample's value; None when the scrape has no such sample."""
    return scrape.get((name, frozenset(labels.items())))
