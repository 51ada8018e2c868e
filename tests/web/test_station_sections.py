"""The station page's forms and tables come from the registry: each kind's form is its create
schema's fields (a vocabulary a select of it, a number an input with the schema's bounds, the
description its hint unless the page words it), and a kind the page has no wording for still
gets a form and a table made from its schema. The page's own tests: test_station_forms.py and
tests/browser."""

from __future__ import annotations

import html
import re
from dataclasses import replace

from server.services import station
from server.web import station_sections
from server.web.routes import templates
from server.web.station_sections import default_page, form_fields, page_of, section


def _schema(kind: station.Kind) -> dict:  # type: ignore[type-arg]
    return kind.spec.model_json_schema()["properties"]


def test_every_form_is_its_kinds_schema() -> None:
    for kind in station.KINDS:
        page, props = page_of(kind), _schema(kind)
        fields = form_fields(kind)
        assert [f.name for f in fields] == [n for n in kind.spec.model_fields
                                            if n not in page.omit], kind.key
        for f in fields:
            prop = props[f.name]
            member = next((m for m in prop.get("anyOf", ()) if m.get("type") != "null"), prop)
            assert f.required == kind.spec.model_fields[f.name].is_required()
            if "enum" in member:
                assert [v for v, _ in f.options] == member["enum"]
            if member.get("type") in ("integer", "number") and "enum" not in member:
                assert f.control == "number"
                assert (f.minimum, f.maximum) == (member.get("minimum"), member.get("maximum"))
                assert (f.step == "any") == (member["type"] == "number")
            if f.name not in page.hints:
                assert f.hint == prop.get("description")


def test_the_vocabularies_the_schemas_hold_as_patterns_are_the_vocabularys() -> None:
    from server.vocabulary import BASES, FAULT_MODES

    faults = {f.name: f for f in form_fields(station.FAULTS)}
    assert [v for v, _ in faults["fault_mode"].options] == list(FAULT_MODES)
    for mode in FAULT_MODES:  # every option is a mode the schema takes
        station.FAULTS.spec.model_validate({"aircraft": "T1", "position": "WT",
                                            "fault_mode": mode})
    base = {f.name: f for f in form_fields(station.CONDITIONS)}["base"]
    assert [v for v, _ in base.options] == list(BASES) and not base.required


def _probe() -> station.Kind:
    """A kind the page has no wording for (the sensor injection's schema under a new name)."""
    return replace(station.SENSORS, path="probes", key="probes", form="probe", noun="Probe")


def test_a_kind_without_wording_gets_a_form_and_a_table_from_its_schema() -> None:
    probe = _probe()
    assert probe.form not in station_sections.PAGES
    page = default_page(probe)
    assert [c.label for c in page.columns] == ["#", "Aircraft", "Position", "Sensor", "Kind",
                                               "Value", "Onset flight", "Status",
                                               "Ground truth", "By"]
    rendered = templates().env.from_string(
        '{% from "_station.html" import station_form, station_table %}'
        '{{ station_form(s, {}, "refused", "tok") }}{{ station_table(s, true, "tok") }}'
    ).render(s=section(probe, [], ["T001"]))
    text = html.unescape(rendered)
    assert 'action="/test-station/probes#probe-form"' in text and 'id="probe-error"' in text
    for name in probe.spec.model_fields:
        assert f'name="{name}"' in text
    assert re.search(r'<select id="probe-sensor" name="sensor" required', text)
    assert 'id="probe-table"' in text and "No probes yet." in text
