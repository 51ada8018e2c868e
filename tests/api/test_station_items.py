"""One create for every test-station kind: ``POST /test-station/items``, its body tagged with
``station_kind`` (a kind's key; not ``kind``, which sensor injections and conditions already
have). It makes the same item as the kind's own route, under the same role and slot rules,
refuses a tag it does not know, and the OpenAPI shows it as a ``oneOf`` with the
discriminator's mapping."""

from __future__ import annotations

from fastapi.testclient import TestClient

from server.auth import ALLOWED
from server.models import ROLES
from server.services.station import KINDS
from tests.api.conftest import auth

URL = "/api/v1/test-station/items"


def _bodies(tail: str) -> dict[str, dict]:  # type: ignore[type-arg]
    """A body of each kind, by its key (the tag added by the tests)."""
    return {"injections": {"aircraft": tail, "position": "WL1", "fault_mode": "MTEL",
                           "onset_flight": 3, "time_to_failure_flights": 80},
            "sensor_injections": {"aircraft": tail, "position": "WT", "sensor": "current",
                                  "kind": "noise", "value": 3},
            "conditions": {"aircraft": tail, "kind": "load_scale", "value": 1.5}}


def test_every_kind_is_created_as_by_its_own_route(client: TestClient, keys, aircraft) -> None:  # type: ignore[no-untyped-def]
    operator = auth(keys["operator"])
    bodies = _bodies(aircraft)
    assert set(bodies) == {kind.key for kind in KINDS}
    for kind in KINDS:
        r = client.post(URL, headers=operator, json=bodies[kind.key] | {"station_kind": kind.key})
        assert r.status_code == 201, r.text
        made = r.json()
        assert made["station_kind"] == kind.key and made["status"] == "pending"
        assert made["created_by"] == "test-operator" and made["aircraft"] == aircraft
        # the kind's own route reads the same item, field for field
        own = client.get(f"/api/v1/test-station/{kind.path}/{made['id']}", headers=operator)
        assert own.status_code == 200
        assert own.json() == {k: v for k, v in made.items() if k != "station_kind"}
        listed = client.get(f"/api/v1/test-station/{kind.path}", headers=operator).json()
        assert [i["id"] for i in listed["items"]] == [made["id"]]
    sensor = client.get("/api/v1/test-station/sensor-injections", headers=operator).json()
    assert sensor["items"][0]["channels"] == ["WT.ia", "WT.ib", "WT.ic"]


def test_an_unknown_or_missing_or_wrong_tag_is_a_422(client: TestClient, keys, aircraft) -> None:  # type: ignore[no-untyped-def]
    operator = auth(keys["operator"])
    bodies = _bodies(aircraft)
    for body in (bodies["conditions"] | {"station_kind": "valves"},
                 bodies["conditions"],  # no tag
                 bodies["conditions"] | {"station_kind": "condition"},  # the form's name
                 # a sensor injection tagged as a condition: the condition's schema refuses it
                 bodies["sensor_injections"] | {"station_kind": "conditions"},
                 # the kind's own checks hold (noise factor above 50)
                 bodies["sensor_injections"] | {"station_kind": "sensor_injections",
                                                "value": 80},
                 # and its strict integers
                 bodies["injections"] | {"station_kind": "injections", "onset_flight": "3"}):
        r = client.post(URL, headers=operator, json=body)
        assert r.status_code == 422, (body, r.text)
    for kind in KINDS:
        listed = client.get(f"/api/v1/test-station/{kind.path}", headers=operator).json()
        assert listed["total"] == 0


def test_a_live_item_holds_its_slot_across_both_routes(client: TestClient, keys, aircraft) -> None:  # type: ignore[no-untyped-def]
    operator = auth(keys["operator"])
    body = _bodies(aircraft)["sensor_injections"]
    tagged = body | {"station_kind": "sensor_injections"}
    assert client.post(URL, headers=operator, json=tagged).status_code == 201
    for url, json in ((URL, tagged | {"value": 4}),
                      ("/api/v1/test-station/sensor-injections", body | {"value": 4})):
        r = client.post(url, headers=operator, json=json)
        assert r.status_code == 409 and r.json()["error"]["code"] == "sensor_injection_exists"
    fault = _bodies(aircraft)["injections"]
    assert client.post("/api/v1/test-station/injections", headers=operator,
                       json=fault).status_code == 201
    r = client.post(URL, headers=operator, json=fault | {"station_kind": "injections"})
    assert r.status_code == 409 and r.json()["error"]["code"] == "injection_exists"
    # an unknown aircraft is the kind's 404
    r = client.post(URL, headers=operator, json=tagged | {"aircraft": "NOPE"})
    assert r.status_code == 404


def test_only_the_roles_that_operate_create(client: TestClient, keys, aircraft) -> None:  # type: ignore[no-untyped-def]
    body = _bodies(aircraft)["conditions"] | {"station_kind": "conditions"}
    for role in ROLES:
        r = client.post(URL, headers=auth(keys[role]), json=body | {"value": 1.5})
        if role in ALLOWED["operate"]:
            assert r.status_code in (201, 409), (role, r.text)
        else:
            assert r.status_code == 403, (role, r.text)
    assert client.post(URL, json=body).status_code == 401
    listed = client.get("/api/v1/test-station/conditions", headers=auth(keys["viewer"])).json()
    assert listed["total"] == 1  # the first operating role's; the second met its slot


def test_the_openapi_shows_a_one_of_with_the_discriminators_mapping(client: TestClient, keys  # type: ignore[no-untyped-def]
                                                                   ) -> None:
    doc = client.get("/openapi.json", headers=auth(keys["viewer"])).json()
    post = doc["paths"][URL]["post"]
    for schema in (post["requestBody"]["content"]["application/json"]["schema"],
                   post["responses"]["201"]["content"]["application/json"]["schema"]):
        assert schema["discriminator"]["propertyName"] == "station_kind"
        mapping = schema["discriminator"]["mapping"]
        assert set(mapping) == {kind.key for kind in KINDS}
        assert sorted(ref["$ref"] for ref in schema["oneOf"]) == sorted(mapping.values())
        for key, ref in mapping.items():
            tagged = doc["components"]["schemas"][ref.rsplit("/", 1)[1]]
            assert tagged["properties"]["station_kind"]["const"] == key
            assert "station_kind" in tagged["required"]
    # the kinds' own paths stay public
    for kind in KINDS:
        assert "post" in doc["paths"][f"/api/v1/test-station/{kind.path}"]
