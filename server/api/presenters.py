"""ORM row -> response schema conversions shared by the routers (and later the dashboard)."""

from __future__ import annotations

from server.models import Actuator, Aircraft, ApiKey, Flight
from server.schemas import ActuatorRead, AircraftRead, FlightRead, KeyRead

API = "/api/v1"


def actuator_read(row: Actuator) -> ActuatorRead:
    return ActuatorRead(id=row.id, aircraft_tail=row.aircraft.tail, position=row.position,
                        serial=row.serial, installed_at=row.installed_at,
                        removed_at=row.removed_at, removal_note=row.removal_note,
                        failed_at_flight=row.failed_at_flight, failed_at=row.failed_at)


def aircraft_read(row: Aircraft) -> AircraftRead:
    installed = {a.position: actuator_read(a) for a in row.actuators if a.removed_at is None}
    return AircraftRead(tail=row.tail, base=row.base, created_at=row.created_at,
                        actuators=installed)


def flight_read(row: Flight, uploader: ApiKey | None = None) -> FlightRead:
    return FlightRead(id=row.id, aircraft=row.tail, flight=row.flight_code, status=row.status,
                      reasons=row.reasons, sha256=row.sha256, size_bytes=row.size_bytes,
                      content_kind=row.content_kind, started_at=row.started_at,
                      block_hours=row.block_hours, received_at=row.received_at,
                      uploader=uploader.name if uploader else None,
                      status_url=f"{API}/flights/{row.id}")


def key_read(row: ApiKey) -> KeyRead:
    return KeyRead.model_validate(row)
