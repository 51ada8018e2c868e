"""Dashboard pages (server-rendered Jinja2) and their form posts.

Handlers are thin: authenticate from the ``hmsm_session`` cookie, read the page's model from
:mod:`server.services.dashboard` (built on the same services as the JSON API) and call those
services for the form posts, word it with :mod:`server.web.data`, build figures with
:mod:`server.web.figures`, render. No SQLAlchemy here: the session is
``server.dependencies.SessionDep``'s, passed on to the services.

Security:

* the session cookie holds the API key the user pasted: ``HttpOnly``, ``SameSite=Strict``,
  ``Secure`` on https, ``Path=/``;
* every form post carries a CSRF token bound to the cookie and, when the browser sends an
  ``Origin``, it must be our own (the rule and the token: ``server.auth.session_write_refusal``,
  the same one the API applies to cookie-authenticated writes);
* roles are enforced here as in the API (``server.auth.may``); the templates only hide controls.
"""

from __future__ import annotations

import secrets
from collections.abc import Callable
from functools import cache
from pathlib import Path
from typing import Annotated, Any, TypeVar
from urllib.parse import quote, urlsplit

import plotly
from fastapi import APIRouter, Depends, Form, Request
from fastapi.responses import FileResponse, HTMLResponse, RedirectResponse, Response
from fastapi.templating import Jinja2Templates
from pydantic import BaseModel, ValidationError

import web
from server.auth import (
    SESSION_COOKIE,
    SIGNIN_COOKIE,
    authenticate,
    csrf_token,
    may,
    session_write_refusal,
)
from server.dependencies import SessionDep, SettingsDep, own_origin
from server.errors import DomainError
from server.models import ApiKey
from server.phm.prognosis.document import rul_quantile
from server.schemas import (
    WORK_ORDER_FORM_PATTERN,
    ActuatorDefer,
    ActuatorInspect,
    ActuatorReplace,
    IdPath,
    IdQuery,
)
from server.services import dashboard, station
from server.services import health as health_service
from server.services import maintenance as maintenance_service
from server.services import models as model_service
from server.vocabulary import FEATURE_LABELS, MODE_NAMES, AlarmStatus
from server.web import data, figures, station_sections

__all__ = ["router", "COOKIE", "STATIC_DIR", "TEMPLATE_DIR", "csrf_token"]

COOKIE = SESSION_COOKIE
WEB_DIR = Path(web.__file__).resolve().parent
TEMPLATE_DIR = WEB_DIR / "templates"
STATIC_DIR = WEB_DIR / "static"
PLOTLY_JS = Path(plotly.__file__).resolve().parent / "package_data" / "plotly.min.js"
_NO_STORE = {"Cache-Control": "no-store"}

#: a form post's schema (the API's), the type its handler's service call takes
Body = TypeVar("Body", bound=BaseModel)

router = APIRouter(include_in_schema=False)


@cache
def templates() -> Jinja2Templates:
    t = Jinja2Templates(directory=str(TEMPLATE_DIR))
    t.env.autoescape = True
    t.env.globals["figure_json"] = figures.figure_json
    t.env.globals["rul_quantile"] = rul_quantile
    t.env.globals["work_order_pattern"] = WORK_ORDER_FORM_PATTERN
    t.env.globals["mode_names"] = MODE_NAMES
    t.env.globals["feature_labels"] = FEATURE_LABELS
    t.env.filters["condition_name"] = data.condition_name
    return t


def _key(request: Request, session: SessionDep) -> ApiKey | None:
    token = request.cookies.get(COOKIE)
    return authenticate(session=session, plaintext=token) if token else None


def _signin_redirect(request: Request) -> RedirectResponse:
    target = request.url.path + (f"?{request.url.query}" if request.url.query else "")
    return RedirectResponse(f"/signin?next={quote(target, safe='')}", status_code=303)


class SignInRequired(Exception):
    """A page asked for without a signed-in key; the app answers it with
    :func:`signin_redirect` (to the sign-in page, and back to the page after)."""


def signin_redirect(request: Request, exc: Exception) -> Response:
    """The app's handler of :class:`SignInRequired`."""
    return _signin_redirect(request)


def _signed_in(request: Request, session: SessionDep) -> ApiKey:
    key = _key(request, session)
    if key is None:
        raise SignInRequired
    return key


#: the signed-in key of a dashboard page (a redirect to the sign-in page without one)
SignedInKey = Annotated[ApiKey, Depends(_signed_in)]


def _safe_next(value: str | None) -> str:
    """Only local absolute paths (no scheme, no host, no ``//``) are followed after sign-in."""
    if not value or not value.startswith("/") or value.startswith("//") or "\\" in value:
        return "/fleet"
    parts = urlsplit(value)
    return "/fleet" if parts.scheme or parts.netloc else value


def _render(request: Request, name: str, key: ApiKey | None, status_code: int = 200,
            **context: Any) -> HTMLResponse:
    cookie = request.cookies.get(COOKIE, "")
    ctx = {"key": key, "role": key.role if key else None,
           "can": {"admin": bool(key and may(key.role, "admin")),
                   "operate": bool(key and may(key.role, "operate")),
                   "maintain": bool(key and may(key.role, "maintain"))},
           "csrf": csrf_token(cookie) if cookie and key else "",
           "nav": name.removesuffix(".html"), **context}
    return templates().TemplateResponse(request, name, ctx, status_code=status_code,
                                        headers=_NO_STORE)


def _problem(request: Request, key: ApiKey | None, status: int, message: str) -> HTMLResponse:
    return _render(request, "error.html", key, status_code=status, status=status,
                   message=message)


def _check_post(request: Request, session: SessionDep, csrf: str, action: str
                ) -> ApiKey | Response:
    """The key behind a form post, or the response refusing it (sign-in, 403)."""
    key = _key(request, session)
    if key is None:
        return _signin_redirect(request)
    refusal = session_write_refusal(session_cookie=request.cookies.get(COOKIE, ""),
                                    presented_token=csrf, origin=request.headers.get("origin"),
                                    own_origin=own_origin(request))
    if refusal == "cross_origin":
        return _problem(request, key, 403, "Cross-origin form post refused.")
    if refusal is not None:
        return _problem(request, key, 403, "The form is stale or was not sent by this "
                        "dashboard (CSRF token mismatch); reload the page and try again.")
    if not may(key.role, action):
        return _problem(request, key, 403, f"Role '{key.role}' may not do this.")
    return key


# ------------------------------------------------------------------------------------------
# sign in / out, static
# ------------------------------------------------------------------------------------------


@router.get("/")
def root() -> RedirectResponse:
    return RedirectResponse("/fleet", status_code=307)


@router.get("/static/vendor/plotly.min.js")
def plotly_js() -> FileResponse:
    """plotly.js from the installed ``plotly`` package (never a CDN)."""
    return FileResponse(PLOTLY_JS, media_type="text/javascript",
                        headers={"Cache-Control": "public, max-age=86400"})


def _signin_page(request: Request, key: ApiKey | None, next: str | None, *,
                 status_code: int = 200, error: str | None = None) -> Response:
    """The sign-in form with the CSRF token of the pre-session cookie (set when absent)."""
    pre = request.cookies.get(SIGNIN_COOKIE, "")
    fresh = len(pre) < 32
    pre = secrets.token_urlsafe(32) if fresh else pre
    response = _render(request, "signin.html", key, status_code=status_code,
                       next=_safe_next(next), error=error, signin_csrf=csrf_token(pre))
    if fresh:
        response.set_cookie(SIGNIN_COOKIE, pre, httponly=True, samesite="strict",
                            path="/signin", secure=request.url.scheme == "https")
    return response


def _form_refusal(request: Request, cookie: str, csrf: str) -> str | None:
    return session_write_refusal(session_cookie=cookie, presented_token=csrf,
                                 origin=request.headers.get("origin"),
                                 own_origin=own_origin(request),
                                 fetch_site=request.headers.get("sec-fetch-site"))


@router.get("/signin", response_class=HTMLResponse)
def signin_form(request: Request, session: SessionDep, next: str | None = None) -> Response:
    return _signin_page(request, _key(request, session), next)


@router.post("/signin", response_class=HTMLResponse)
def signin(request: Request, session: SessionDep, key: str = Form(""),
           next: str = Form("/fleet"), csrf: str = Form("")) -> Response:
    """Login CSRF: only this site's own sign-in form may sign a browser in (the pre-session
    cookie's token, a same-origin ``Origin`` / ``Sec-Fetch-Site``), so that no other page can
    sign a victim in under a key of its choosing."""
    refusal = _form_refusal(request, request.cookies.get(SIGNIN_COOKIE, ""), csrf)
    if refusal is not None:
        return _signin_page(request, None, next, status_code=403, error=(
            "Sign-in refused: it did not come from this site's sign-in form "
            f"({refusal.replace('_', ' ')}). Paste your key here."))
    row = authenticate(session=session, plaintext=key.strip())
    if row is None:
        return _signin_page(request, None, next, status_code=401,
                            error="That key is unknown or revoked.")
    response = RedirectResponse(_safe_next(next), status_code=303)
    response.set_cookie(COOKIE, key.strip(), httponly=True, samesite="strict", path="/",
                        secure=request.url.scheme == "https", max_age=12 * 3600)
    return response


@router.post("/signout")
def signout(request: Request, csrf: str = Form("")) -> Response:
    """Needs the session's CSRF token, like every form post (no other page may sign us out)."""
    cookie = request.cookies.get(COOKIE, "")
    if cookie and _form_refusal(request, cookie, csrf) is not None:
        return _problem(request, None, 403, "Sign-out refused: it did not come from this "
                        "dashboard (CSRF token mismatch); reload the page and try again.")
    response = RedirectResponse("/signin", status_code=303)
    response.delete_cookie(COOKIE, path="/", httponly=True, samesite="strict",
                           secure=request.url.scheme == "https")
    return response


# ------------------------------------------------------------------------------------------
# pages
# ------------------------------------------------------------------------------------------


@router.get("/fleet", response_class=HTMLResponse)
def fleet_page(request: Request, key: SignedInKey, session: SessionDep, sort: str = "rul",
               base: str | None = None, status: str | None = None) -> Response:
    return _render(request, "fleet.html", key,
                   **dashboard.fleet_view(session=session, sort=sort, base=base or None,
                                          status=status or None))


@router.get("/alarms", response_class=HTMLResponse)
def alarms_page(request: Request, key: SignedInKey, session: SessionDep,
                status: str | None = None) -> Response:
    status = status if status in set(AlarmStatus) else None
    return _render(request, "alarms.html", key, **dashboard.alarms_view(session=session,
                                                                        status=status))


def _alarm_action(request: Request, session: SessionDep, alarm_id: int, note: str, csrf: str,
                  back: str, action: str, partner: str = "") -> Response:
    """Acknowledge or close an alarm; with ``partner``, the winglet-pair alarm shown with it
    too (when it is still that alarm's pair partner)."""
    key = _check_post(request, session, csrf, "admin")
    if not isinstance(key, ApiKey):
        return key
    fn = (health_service.acknowledge_alarm if action == "acknowledge"
          else health_service.close_alarm)
    try:
        ids = [alarm_id]
        if partner.strip():
            pair = health_service.winglet_partner_alarm(session=session, alarm_id=alarm_id)
            if pair is not None and str(pair[0].id) == partner.strip() and (
                    action == "close" or pair[0].status == AlarmStatus.OPEN):
                ids.append(pair[0].id)
        for i in ids:
            fn(session=session, alarm_id=i, by=key.name, note=note.strip()[:2000] or None)
    except DomainError as exc:
        session.rollback()
        return _problem(request, key, exc.status_code, exc.message)
    session.commit()
    return RedirectResponse(_safe_next(back or "/alarms"), status_code=303)


@router.post("/alarms/{alarm_id}/acknowledge")
def acknowledge(request: Request, session: SessionDep, alarm_id: IdPath, note: str = Form(""),
                csrf: str = Form(""), back: str = Form("/alarms"), partner: str = Form("")
                ) -> Response:
    return _alarm_action(request, session, alarm_id, note, csrf, back, "acknowledge", partner)


@router.post("/alarms/{alarm_id}/close")
def close(request: Request, session: SessionDep, alarm_id: IdPath, note: str = Form(""),
          csrf: str = Form(""), back: str = Form("/alarms"), partner: str = Form("")
          ) -> Response:
    return _alarm_action(request, session, alarm_id, note, csrf, back, "close", partner)


@router.get("/actuators/{actuator_id}", response_class=HTMLResponse)
def actuator_page(request: Request, key: SignedInKey, session: SessionDep,
                  actuator_id: IdPath) -> Response:
    try:
        view = data.actuator_view(dashboard.actuator_view(session=session,
                                                          actuator_id=actuator_id))
    except DomainError as exc:
        return _problem(request, key, exc.status_code, exc.message)
    figs = {
        "trends": figures.feature_trends(view["records"], band=view["band"],
                                         threshold=view["threshold"],
                                         marks=view["station_marks"]),
        "confidence": figures.mark_station(figures.detection_confidence(
            view["records"], alarm_level=view["alarm_confidence"]), view["station_marks"]),
        "classes": figures.class_probabilities(view["records"]),
        "severity": figures.severity_band(view["prognoses"]),
        "cone": figures.rul_cone(view["prognoses"], view["truth"],
                                 planned=view["truth_planned"]),
        "histogram": figures.rul_histogram(
            view["latest_prognosis"], failed_at_flight=view["actuator"].failed_at_flight),
    }
    return _render(request, "actuator.html", key, figs=figs, **view)


def _form_error(exc: ValidationError) -> str:
    return "; ".join(f"{'.'.join(str(p) for p in e['loc']) or 'form'}: {e['msg']}"
                     for e in exc.errors())


def _maintenance(request: Request, session: SessionDep, actuator_id: int, csrf: str,
                 schema: type[Body], raw: dict[str, str], act: Callable[[ApiKey, Body], int]
                 ) -> Response:
    """A maintenance form post: CSRF and role (``maintain``), the API's schema, the service."""
    key = _check_post(request, session, csrf, "maintain")
    if not isinstance(key, ApiKey):
        return key
    try:
        body = schema.model_validate_strings({k: v.strip() for k, v in raw.items()
                                              if v.strip()})
        target = act(key, body)
    except ValidationError as exc:
        session.rollback()
        return _problem(request, key, 422, _form_error(exc))
    except DomainError as exc:
        session.rollback()
        return _problem(request, key, exc.status_code, exc.message)
    session.commit()
    return RedirectResponse(f"/actuators/{target}", status_code=303)


@router.post("/actuators/{actuator_id}/replace")
def replace(request: Request, session: SessionDep, actuator_id: IdPath,
            new_serial: str = Form(""), work_order: str = Form(""), note: str = Form(""),
            csrf: str = Form("")) -> Response:
    def act(key: ApiKey, body: ActuatorReplace) -> int:
        new, _ = maintenance_service.replace_actuator(
            session=session, actuator_id=actuator_id, new_serial=body.new_serial, by=key,
            work_order=body.work_order, note=body.note)
        return new.id

    return _maintenance(request, session, actuator_id, csrf, ActuatorReplace,
                        {"new_serial": new_serial, "work_order": work_order, "note": note}, act)


@router.post("/actuators/{actuator_id}/inspect")
def inspect(request: Request, session: SessionDep, actuator_id: IdPath,
            work_order: str = Form(""), note: str = Form(""), csrf: str = Form("")) -> Response:
    def act(key: ApiKey, body: ActuatorInspect) -> int:
        maintenance_service.inspect_actuator(session=session, actuator_id=actuator_id, by=key,
                                             work_order=body.work_order, note=body.note)
        return actuator_id

    return _maintenance(request, session, actuator_id, csrf, ActuatorInspect,
                        {"work_order": work_order, "note": note}, act)


@router.post("/actuators/{actuator_id}/defer")
def defer(request: Request, session: SessionDep, actuator_id: IdPath,
          work_order: str = Form(""), reason: str = Form(""), flights: str = Form(""),
          until: str = Form(""), csrf: str = Form("")) -> Response:
    def act(key: ApiKey, body: ActuatorDefer) -> int:
        maintenance_service.defer_alarm(session=session, actuator_id=actuator_id, by=key,
                                        work_order=body.work_order, reason=body.reason,
                                        flights=body.flights, until=body.until)
        return actuator_id

    # a date field gives a day: the deferral runs to the end of it, UTC
    day = f"{until.strip()}T23:59:59Z" if until.strip() else ""
    return _maintenance(request, session, actuator_id, csrf, ActuatorDefer,
                        {"work_order": work_order, "reason": reason, "flights": flights,
                         "until": day}, act)


@router.get("/models", response_class=HTMLResponse)
def models_page(request: Request, key: SignedInKey, session: SessionDep,
                id: IdQuery = None) -> Response:
    view = dashboard.models_view(session=session, model_id=id)
    fig = figures.confusion_matrix(view["confusion"]) if view["confusion"] else None
    return _render(request, "models.html", key, fig=fig, **view)


@router.post("/models/{model_id}/activate")
def activate(request: Request, session: SessionDep, model_id: IdPath, csrf: str = Form("")
             ) -> Response:
    key = _check_post(request, session, csrf, "admin")
    if not isinstance(key, ApiKey):
        return key
    try:
        model_service.activate(session=session, version_id=model_id)
    except DomainError as exc:
        return _problem(request, key, exc.status_code, exc.message)
    session.commit()
    return RedirectResponse(f"/models?id={model_id}", status_code=303)


@router.get("/test-station", response_class=HTMLResponse)
def station_page(request: Request, key: SignedInKey, session: SessionDep) -> Response:
    return _station(request, session, key)


def _station(request: Request, session: SessionDep, key: ApiKey, status_code: int = 200,
             error: str | None = None, failed: str | None = None,
             form: dict[str, str] | None = None) -> HTMLResponse:
    """The station page; after a refused post, its error beside the form that ``failed``
    (``fault``, ``sensor``, ``condition``; None: a cancel) with what was typed in it."""
    view = dashboard.station_view(session=session)
    return _render(request, "test_station.html", key, status_code=status_code, error=error,
                   failed=failed, forms={failed: form or {}} if failed else {},
                   sections=station_sections.sections(view["station_items"], view["tails"]))


async def _form_fields(request: Request) -> dict[str, str]:
    """A form post's text fields (a station form's fields are its kind's schema's)."""
    form = await request.form()
    return {name: value for name, value in form.items() if isinstance(value, str)}


FormFields = Annotated[dict[str, str], Depends(_form_fields)]


def _create_on_station(request: Request, session: SessionDep, kind: station.Kind,
                       fields: dict[str, str]) -> Response:
    """An operator's create from the station form of ``kind``: the API's schema, then the
    service; the page again with the form and the schema's or the service's message, or back
    to it once committed."""
    key = _check_post(request, session, fields.get("csrf", ""), "operate")
    if not isinstance(key, ApiKey):
        return key
    form = {name: fields.get(name, "") for name in kind.spec.model_fields if name in fields}
    try:
        # form fields are strings: parsed as such, while JSON bodies keep strict integers;
        # an empty field is an absent one (the schema's default)
        spec = kind.spec.model_validate_strings({k: v.strip() for k, v in form.items()
                                                 if v.strip()})
        station.create(session=session, kind=kind, spec=spec, created_by=key.name)
    except ValidationError as exc:
        session.rollback()
        return _station(request, session, key, 422, _form_error(exc), kind.form, form)
    except DomainError as exc:
        session.rollback()
        return _station(request, session, key, exc.status_code, exc.message, kind.form, form)
    session.commit()
    return RedirectResponse("/test-station", status_code=303)


def _cancel_on_station(request: Request, session: SessionDep, kind: station.Kind,
                       item_id: int, csrf: str) -> Response:
    """An operator's cancel from the station page: the page again with the error, or back to
    it once the cancel is committed."""
    key = _check_post(request, session, csrf, "operate")
    if not isinstance(key, ApiKey):
        return key
    try:
        station.cancel(session=session, kind=kind, item_id=item_id)
    except DomainError as exc:
        session.rollback()
        return _station(request, session, key, exc.status_code, exc.message)
    session.commit()
    return RedirectResponse("/test-station", status_code=303)


def _add_station_forms(kind: station.Kind) -> None:
    """The station page's create and cancel posts of one kind (``/test-station/<kind>``)."""

    def create(request: Request, session: SessionDep, fields: FormFields) -> Response:
        return _create_on_station(request, session, kind, fields)

    def cancel(request: Request, session: SessionDep, item_id: IdPath,
               csrf: str = Form("")) -> Response:
        return _cancel_on_station(request, session, kind, item_id, csrf)

    router.post(f"/test-station/{kind.path}", name=f"create_{kind.key}")(create)
    router.post(f"/test-station/{kind.path}/{{item_id}}/cancel",
                name=f"cancel_{kind.key}")(cancel)


for _kind in station.KINDS:
    _add_station_forms(_kind)


@router.get("/evaluation", response_class=HTMLResponse)
def evaluation_page(request: Request, key: SignedInKey, settings: SettingsDep) -> Response:
    return _render(request, "evaluation.html", key,
                   **data.evaluation_view(data_dir=settings.data_dir))
