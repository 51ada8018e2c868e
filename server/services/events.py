"""What changed in the database, as the dashboard's live updates need it: a snapshot of a
few aggregates (a fixed number of indexed queries, whatever the fleet size), and the stream's
own short sessions: whether its key is active, and the snapshot while it is."""

from __future__ import annotations

import json
from typing import Any

from sqlalchemy import func, select
from sqlalchemy.orm import Session

from server.auth import authenticate
from server.db import SessionFactory
from server.models import Alarm, AlarmEvent, HealthRecord, Injection, ModelVersion, Prognosis

__all__ = ["snapshot", "key_is_active", "snapshot_while_active"]


def key_is_active(factory: SessionFactory, token: str) -> bool:
    """Whether ``token`` is an active API key, in a short session of its own."""
    with factory() as session:
        return authenticate(session=session, plaintext=token) is not None


def snapshot_while_active(factory: SessionFactory, token: str) -> dict[str, Any] | None:
    """The snapshot, or None once the key ``token`` is revoked: one short session, the key's
    check and the snapshot in the same transaction."""
    with factory() as session:
        if authenticate(session=session, plaintext=token) is None:
            return None
        return snapshot(session)


def snapshot(session: Session) -> dict[str, Any]:
    """Aggregates whose change means a page should refresh (a fixed number of queries)."""
    alarm = session.execute(select(func.max(Alarm.id), func.max(Alarm.acknowledged_at),
                                   func.max(Alarm.closed_at))).one()
    alarm_status = sorted(session.execute(select(Alarm.status, func.count())
                                          .group_by(Alarm.status)).all())
    # a change of an open alarm's leading class is an event of its own (the inbox shows it)
    alarm_events = session.scalar(select(func.max(AlarmEvent.id))) or 0
    injection = session.execute(select(func.max(Injection.id),
                                       func.max(Injection.cancelled_at))).one()
    injection_status = sorted(session.execute(select(Injection.status, func.count())
                                              .group_by(Injection.status)).all())
    model = session.execute(select(func.max(ModelVersion.id), func.max(ModelVersion.finished_at),
                                   func.count())).one()
    active = session.scalar(select(func.max(ModelVersion.id)).where(
        ModelVersion.active.is_(True)))
    return {
        "alarm": alarm[0] or 0,
        "alarm-status": json.dumps([str(alarm[1]), str(alarm[2]), alarm_status, alarm_events],
                                   default=str),
        "flight": session.scalar(select(func.max(HealthRecord.id))) or 0,
        "prognosis": session.scalar(select(func.max(Prognosis.id))) or 0,
        "injection": json.dumps([injection[0], str(injection[1]), injection_status],
                                default=str),
        "model": json.dumps([model[0], str(model[1]), model[2], active], default=str),
    }
