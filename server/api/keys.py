"""API key administration (admin only). Keys can also be made with `hmsm keys create`."""

from __future__ import annotations

from fastapi import APIRouter

from server.api.deps import Admin, SessionDep
from server.api.openapi import errors
from server.api.presenters import key_read
from server.auth import create_key, list_keys, revoke_key
from server.schemas import IdPath, KeyCreate, KeyCreated, KeyRead

router = APIRouter(prefix="/keys", tags=["keys"])


@router.get("", response_model=list[KeyRead], responses=errors(403),
            summary="List keys (admin)")
def list_(session: SessionDep, _: Admin) -> list[KeyRead]:
    return [key_read(r) for r in list_keys(session=session)]


@router.post("", status_code=201, response_model=KeyCreated, summary="Create a key (admin)")
def create(body: KeyCreate, session: SessionDep, _: Admin) -> KeyCreated:
    row, plaintext = create_key(session=session, name=body.name, role=body.role)
    session.commit()
    return KeyCreated(**key_read(row).model_dump(), key=plaintext)


@router.post("/{key_id}/revoke", response_model=KeyRead, responses=errors(409),
             summary="Revoke a key (admin; never the last active admin key)")
def revoke(key_id: IdPath, session: SessionDep, _: Admin) -> KeyRead:
    row = revoke_key(session=session, key_id=key_id, keep_an_admin=True)
    session.commit()
    return key_read(row)
