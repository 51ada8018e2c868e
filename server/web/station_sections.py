"""The test-station page's sections, one per kind of the registry (``server.services.station.
KINDS``): its form, made from the kind's create schema, and its table.

A form's fields are the schema's, in its order: a field with a vocabulary (a ``Literal``'s enum,
or a vocabulary named here where the schema holds a pattern) is a select of it, a number an
input with the schema's bounds (the browser's first check; the server's is the schema itself),
its hint the field's description; ``aircraft`` offers the fleet's tails. What a kind's section
says beyond its schema (headings, ids the tests and users rely on, its table's columns, its
truth in a line) is its :class:`KindPage`; a kind without one gets a section made from its
noun, its schema and its truth's fields.

The service layer knows nothing of HTML; this module knows no HTML either beyond the intro's
``<code>``: the template (``test_station.html``) draws what it describes.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from functools import cache
from typing import Any

from markupsafe import Markup
from pydantic import BaseModel

from server.schemas import CONDITION_UNITS
from server.services import station
from server.services.station import Kind
from server.vocabulary import BASES, FAULT_MODES, MODE_NAMES, PROGRESSIVE

__all__ = ["FormField", "Cell", "Note", "Column", "KindPage", "Section", "section", "sections",
           "form_fields", "page_of", "default_page", "PAGES"]

#: one item as :func:`server.services.dashboard.station_view` gives it: ``item`` (the row),
#: ``tail``, ``truth_count``, ``truth_latest``, ``live``, ``warnings``
Item = Mapping[str, Any]


@dataclass(frozen=True)
class FormField:
    """One field of a kind's form: a select or an input named as the schema's field."""

    name: str
    id: str
    label: str
    control: str  # "select", "number" or "text"
    required: bool
    options: tuple[tuple[str, str], ...] = ()  # (value, label) of a select
    minimum: float | None = None
    maximum: float | None = None
    step: str | None = None  # "any" for a number that is no integer
    default: str = ""  # shown in a fresh form
    hint: str | None = None
    hint_id: str | None = None
    wide: bool = False  # spans the form's width (a long hint)


@dataclass(frozen=True)
class Note:
    """A small line under a cell's value (a warning, a plan)."""

    text: str
    id: str
    css: str | None = None


@dataclass(frozen=True)
class Cell:
    """One cell of an item's row: its value shown as ``show`` says, then ``after``."""

    value: Any
    show: str = "text"  # "text", "mode" (a fault mode's code and name), "badge", "when"
    after: str = ""
    note: Note | None = None


@dataclass(frozen=True)
class Column:
    label: str
    cell: Callable[[Item], Cell]
    css: str | None = None  # "num", "wide"


@dataclass(frozen=True)
class KindPage:
    """What a kind's section of the page says beyond its schema."""

    #: the section's heading above the form, and its id (None: the form's heading leads)
    heading: str | None
    heading_id: str | None
    #: the section's line under its heading; ``{api}`` becomes the API's create path
    intro: str | None
    form_id: str
    form_heading: str
    form_heading_id: str
    form_heading_level: int
    #: whether the form's action ends in ``#<form_id>`` (the page then scrolls back to the
    #: form that failed; the fault form's tests expect the bare URL after a success)
    anchor: bool
    error_id: str
    button: str
    #: a hint under the form's fields: (id, text)
    footnote: tuple[str, str] | None
    #: a heading between the form and the table (None: the section's heading names the table)
    table_heading: str | None
    #: the cancel button's id before the item's id
    cancel_id: str
    #: the item in the cancel button's label: (row, tail) -> "MTEL on T001 WL1"
    cancel_what: Callable[[Any, str], str]
    #: the last truth in a few words: (row, truth row) -> "severity 0.20, true RUL 40"
    truth: Callable[[Any, Any], str]
    columns: tuple[Column, ...]
    labels: Mapping[str, str] = field(default_factory=dict)
    ids: Mapping[str, str] = field(default_factory=dict)
    hints: Mapping[str, str] = field(default_factory=dict)
    hint_ids: Mapping[str, str] = field(default_factory=dict)
    #: select choices of fields whose schema holds a pattern or free text, not an enum
    choices: Mapping[str, Sequence[str]] = field(default_factory=dict)
    #: an option's label from its value, per field (default: the value)
    option_labels: Mapping[str, Callable[[str], str]] = field(default_factory=dict)
    wide: tuple[str, ...] = ()
    #: schema fields the page leaves to the API
    omit: tuple[str, ...] = ()

    def intro_html(self, kind: Kind) -> Markup | None:
        if self.intro is None:
            return None
        api = Markup("<code>POST /api/v1/test-station/{}</code>").format(kind.path)
        return Markup(self.intro).format(api=api)


# ---- cells shared by the kinds --------------------------------------------------------------

def _value(name: str) -> Callable[[Item], Cell]:
    """The row's column ``name`` ("–" when empty)."""
    def cell(it: Item) -> Cell:
        value = getattr(it["item"], name)
        return Cell("–" if value is None else value)
    return cell


def _tail(it: Item) -> Cell:
    return Cell(it["tail"])


def _status_from(it: Item) -> Cell:
    """The status, and the flight an item started on (the simulator's first truth)."""
    row = it["item"]
    started = getattr(row, "started_flight", None)
    return Cell(row.status, show="badge", after="" if started is None else f" from {started}")


def _created(it: Item) -> Cell:
    return Cell(it["item"].created_at, show="when")


def _truth(it: Item) -> Cell:
    """The item's truth: how many flights, and the last in its kind's words (``summary``)."""
    last = it["truth_latest"]
    if last is None:
        return Cell("none yet")
    return Cell(f"{it['truth_count']} flights; last {last.flight_code}: {it['summary']}")


def _g(value: float) -> str:
    return format(value, "g")


def _rul(value: float | None) -> str:
    return "–" if value is None else f"{value:.0f}"


# ---- fault injections -----------------------------------------------------------------------

def _fault_mode_label(mode: str) -> str:
    return f"{mode}: {MODE_NAMES[mode]}" + (" (progressive)" if mode in PROGRESSIVE else "")


def _ttf(it: Item) -> Cell:
    """The time to failure, with the warning of a live one outside the model's training."""
    row = it["item"]
    warnings = it["warnings"]
    note = (Note(f"⚠ {warnings[0]}", id=f"span-warning-{row.id}", css="warning-text")
            if warnings else None)
    ttf = row.time_to_failure_flights
    return Cell("–" if ttf is None else ttf, note=note)


def _fault_status(it: Item) -> Cell:
    """The status; the flight it failed at, or while live the flight it is steered to fail at."""
    row = it["item"]
    if row.failure_flight is not None:
        return Cell(row.status, show="badge", after=f" at {row.failure_flight}")
    planned = row.planned_failure_flight
    note = (Note(f"planned failure at flight {planned}", id=f"plan-{row.id}")
            if planned is not None and it["live"] else None)
    return Cell(row.status, show="badge", note=note)


def _fault_truth(row: Any, last: Any) -> str:
    if last.true_rul_flights is not None:
        rul = f"true RUL {_rul(last.true_rul_flights)}"
    elif row.planned_failure_flight is not None:
        rul = f"planned RUL {_rul(row.planned_failure_flight - last.flight_number)}"
    else:
        rul = "true RUL –"
    return f"severity {last.severity_norm:.2f}, {rul}"


FAULT_PAGE = KindPage(
    heading=None, heading_id=None, intro=None, form_id="inject-form",
    form_heading="Inject a fault", form_heading_id="h-inject", form_heading_level=2,
    anchor=False, error_id="inject-error", button="Inject fault",
    footnote=("concurrent-hint", "Faults fly concurrently: on another actuator of the "
              "aircraft, or another mode on the same one. An actuator takes one live injection "
              "per mode; when one fault fails its actuator, replacing the unit ends every fault "
              "on it."),
    table_heading="Injections", cancel_id="cancel-",
    cancel_what=lambda row, tail: f"{row.fault_mode} on {tail} {row.position}",
    truth=_fault_truth,
    columns=(Column("#", _value("id")), Column("Aircraft", _tail),
             Column("Position", _value("position")),
             Column("Mode", lambda it: Cell(it["item"].fault_mode, show="mode"), "wide"),
             Column("Onset", _value("onset_flight"), "num"), Column("TTF", _ttf, "num"),
             Column("Status", _fault_status), Column("Ground truth", _truth, "wide"),
             Column("By", _value("created_by")), Column("Created", _created)),
    labels={"time_to_failure_flights": "Time to failure [flights]"},
    ids={"aircraft": "aircraft", "position": "position", "fault_mode": "fault_mode",
         "onset_flight": "onset_flight", "time_to_failure_flights": "ttf"},
    hints={"onset_flight": "Aircraft flight number; 0 = the next flight.",
           "time_to_failure_flights": "Progressive modes only; empty = drawn by the simulator."},
    hint_ids={"onset_flight": "onset-hint"},
    # the schema holds the modes as a pattern (its 422 names them): the vocabulary's
    choices={"fault_mode": FAULT_MODES}, option_labels={"fault_mode": _fault_mode_label},
    omit=("severity",))  # not on the page before the registry drew it: the API takes it


# ---- sensor injections ----------------------------------------------------------------------

#: what the sensor form's value means for each kind (the bounds are the schema's, in its hint)
SENSOR_KIND_LABELS = {"noise": "noise × factor", "drift": "drift per flight [m]",
                      "quantisation": "quantisation step", "stuck": "stuck at",
                      "clipped": "clipped at"}

_UNTIL_CANCELLED = {"onset_flight": "Start flight"}

SENSOR_PAGE = KindPage(
    heading="Sensor injections", heading_id="h-sensor",
    intro="Created with this form or over the API ({api}), with the same checks; the "
    "simulator flies them in the loop until cancelled.",
    form_id="sensor-form", form_heading="Degrade a sensor", form_heading_id="h-sensor-form",
    form_heading_level=3, anchor=True, error_id="sensor-error", button="Degrade sensor",
    footnote=None, table_heading=None, cancel_id="cancel-sensor-",
    cancel_what=lambda row, tail: f"{row.kind} on {tail} {row.position} {row.sensor}",
    truth=lambda row, last: _g(last.applied),
    columns=(Column("#", _value("id")), Column("Aircraft", _tail),
             Column("Position", _value("position")), Column("Sensor", _value("sensor")),
             Column("Kind", lambda it: Cell(f"{it['item'].kind} {_g(it['item'].value)}")),
             Column("Onset", _value("onset_flight"), "num"), Column("Status", _status_from),
             Column("Ground truth", _truth, "wide"),
             Column("By", _value("created_by"))),
    labels=_UNTIL_CANCELLED, ids={"onset_flight": "sensor-onset"},
    option_labels={"kind": lambda k: SENSOR_KIND_LABELS.get(k, k)}, wide=("value",))


# ---- conditions -----------------------------------------------------------------------------

def _condition_label(kind: str) -> str:
    unit = CONDITION_UNITS.get(kind)
    return kind.replace("_", " ") + (f" [{unit}]" if unit else "")


def _condition_truth(row: Any, last: Any) -> str:
    # a base's truth is the ground temperature its climate gave the flight
    return _g(last.applied) + (" °C on the ground" if row.kind == "base" else "")


CONDITION_PAGE = KindPage(
    heading="Conditions", heading_id="h-conditions",
    intro="Simulation conditions on a whole aircraft (ambient temperature offset, load scale "
    "or offset, command scale, base), created with this form or over the API ({api}), with the "
    "same checks; the simulator flies them until cancelled.",
    form_id="condition-form", form_heading="Set a condition",
    form_heading_id="h-condition-form", form_heading_level=3, anchor=True,
    error_id="condition-error", button="Set condition", footnote=None, table_heading=None,
    cancel_id="cancel-condition-",
    cancel_what=lambda row, tail: f"{station.describe_condition(row)} on {tail}",
    truth=_condition_truth,
    columns=(Column("#", _value("id")), Column("Aircraft", _tail),
             Column("Condition", lambda it: Cell(station.describe_condition(it["item"])),
                    "wide"),
             Column("Onset", _value("onset_flight"), "num"), Column("Status", _status_from),
             Column("Ground truth", _truth, "wide"),
             Column("By", _value("created_by"))),
    labels=_UNTIL_CANCELLED, ids={"onset_flight": "condition-onset"},
    choices={"base": BASES}, option_labels={"kind": _condition_label}, wide=("kind", "value"))

#: the sections the page words itself, by the kind's form
PAGES: dict[str, KindPage] = {station.FAULTS.form: FAULT_PAGE,
                              station.SENSORS.form: SENSOR_PAGE,
                              station.CONDITIONS.form: CONDITION_PAGE}


# ---- a kind without a page of its own -------------------------------------------------------

def _label(name: str) -> str:
    return name.replace("_", " ").capitalize()


def _truth_fields(kind: Kind) -> Callable[[Any, Any], str]:
    """The truth's values by name, e.g. ``applied 1.5``."""
    def truth(row: Any, last: Any) -> str:
        values = ((name, getattr(last, name)) for name in kind.truth_fields)
        return ", ".join(f"{name} {'–' if v is None else _g(v) if isinstance(v, float) else v}"
                         for name, v in values)
    return truth


def default_page(kind: Kind) -> KindPage:
    """A section made from the kind's noun, schema and truth: a form of every field and a
    table of every field, its status, truth and author."""
    noun, slug = kind.noun.lower(), kind.noun.lower().replace(" ", "-")
    fields = [name for name in kind.spec.model_fields if name != "aircraft"]
    return KindPage(
        heading=f"{kind.noun}s", heading_id=f"h-{kind.form}",
        intro="Created with this form or over the API ({api}), with the same checks.",
        form_id=f"{kind.form}-form", form_heading=f"New {noun}",
        form_heading_id=f"h-{kind.form}-form", form_heading_level=3, anchor=True,
        error_id=f"{kind.form}-error", button=f"Create {noun}", footnote=None,
        table_heading=None, cancel_id=f"cancel-{slug}-",
        cancel_what=lambda row, tail: " ".join(str(getattr(row, c)) for c in kind.slot)
        + f" on {tail}",
        truth=_truth_fields(kind),
        columns=(Column("#", _value("id")), Column("Aircraft", _tail),
                 *(Column(_label(name), _value(name)) for name in fields),
                 Column("Status", _status_from), Column("Ground truth", _truth, "wide"),
                 Column("By", _value("created_by"))))


def page_of(kind: Kind) -> KindPage:
    return PAGES.get(kind.form) or default_page(kind)


# ---- the form's fields from the schema ------------------------------------------------------

def _property(schema: type[BaseModel], name: str) -> dict[str, Any]:
    """A field's JSON schema, an optional one's non-null member (with the field's own keys)."""
    prop = dict(schema.model_json_schema()["properties"][name])
    for member in prop.pop("anyOf", ()):
        if member.get("type") != "null":
            prop.update(member)
    return prop


def _form_field(kind: Kind, page: KindPage, name: str) -> FormField:
    info = kind.spec.model_fields[name]
    prop = _property(kind.spec, name)
    field_id = page.ids.get(name, f"{kind.form}-{name}")
    values = tuple(prop.get("enum") or page.choices.get(name) or ())
    hint = page.hints.get(name, info.description)
    base = FormField(
        name=name, id=field_id, label=page.labels.get(name, _label(name)), control="text",
        required=info.is_required(), hint=hint,
        hint_id=page.hint_ids.get(name, f"{field_id}-hint") if hint else None,
        wide=name in page.wide,
        default="" if info.default is None or info.is_required() else str(info.default))
    if values:
        label = page.option_labels.get(name, str)
        return replace(base, control="select", options=tuple((v, label(v)) for v in values))
    if prop.get("type") in ("integer", "number"):
        return replace(base, control="number", minimum=prop.get("minimum"),
                       maximum=prop.get("maximum"),
                       step="any" if prop["type"] == "number" else None)
    return base


@cache  # the schemas' and the pages': fixed while the process runs
def form_fields(kind: Kind) -> tuple[FormField, ...]:
    """The kind's form, in its schema's order (``aircraft``'s options are the request's)."""
    page = page_of(kind)
    return tuple(_form_field(kind, page, name) for name in kind.spec.model_fields
                 if name not in page.omit)


# ---- the page -------------------------------------------------------------------------------

@dataclass(frozen=True)
class Row:
    id: int
    cells: tuple[Cell, ...]
    live: bool
    cancel_label: str


@dataclass(frozen=True)
class Section:
    """One kind on the page: its wording, its form's fields and its items' rows."""

    kind: Kind
    page: KindPage
    intro: Markup | None
    fields: tuple[FormField, ...]
    columns: tuple[Column, ...]
    rows: tuple[Row, ...]
    row_id: str  # a row's id before the item's id
    empty: str


def _row(kind: Kind, page: KindPage, it: Item) -> Row:
    """An item's row: its cells (its last truth in the kind's words: ``summary``) and what its
    Cancel button says."""
    row, last = it["item"], it["truth_latest"]
    shown = {**it, "summary": None if last is None else page.truth(row, last)}
    return Row(id=row.id, cells=tuple(c.cell(shown) for c in page.columns), live=it["live"],
               cancel_label=f"Cancel {kind.noun.lower()} {row.id} "
               f"({page.cancel_what(row, it['tail'])})")


def _aircraft_offered(fields: tuple[FormField, ...], tails: Sequence[str]
                      ) -> tuple[FormField, ...]:
    """The form's ``aircraft`` a select of the fleet's tails."""
    return tuple(replace(f, control="select", options=tuple((t, t) for t in tails))
                 if f.name == "aircraft" else f for f in fields)


def section(kind: Kind, items: Sequence[Item], tails: Sequence[str]) -> Section:
    """One kind's section: its form (``aircraft`` offering ``tails``) and its items' rows."""
    page = page_of(kind)
    slug = kind.noun.lower().replace(" ", "-")
    return Section(kind=kind, page=page, intro=page.intro_html(kind),
                   fields=_aircraft_offered(form_fields(kind), tails), columns=page.columns,
                   rows=tuple(_row(kind, page, it) for it in items), row_id=f"{slug}-",
                   empty=f"No {kind.noun.lower()}s yet.")


def sections(items: Mapping[str, Sequence[Item]], tails: Sequence[str]) -> list[Section]:
    """The page's sections, one per kind in the registry's order, from
    :func:`server.services.dashboard.station_view`'s items (by kind key) and tails."""
    return [section(kind, items.get(kind.key, ()), tails) for kind in station.KINDS]
