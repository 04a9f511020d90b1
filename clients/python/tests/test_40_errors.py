"""Bad input through the client, against the real binary: every refusal is a MentalsimError
carrying the HTTP status, the API's stable error code and its message."""

from __future__ import annotations

from pathlib import Path

import pytest
from conftest import Service, free_port

from mentalsim_client import Client, MentalsimError


def refused(call: object) -> MentalsimError:
    assert callable(call)
    with pytest.raises(MentalsimError) as e:
        call()
    return e.value


def test_an_unknown_place_is_404_not_found(robot: Client) -> None:
    e = refused(lambda: robot.place("no-such-place"))
    assert (e.status, e.code) == (404, "not_found")
    assert "no-such-place" in e.message and e.request_id
    assert e.operation == "get_place"
    assert str(e).startswith("404 not_found (get_place): ")


def test_unknown_jobs_and_policies_are_404(robot: Client) -> None:
    missing = "01900000-0000-7000-8000-000000000000"
    assert refused(lambda: robot.job(missing)).code == "not_found"
    assert refused(lambda: list(robot.job_events(missing))).status == 404
    assert refused(lambda: robot.policy("nope")).status == 404


def test_a_goal_outside_the_map_is_422_unprocessable(robot: Client, kitchen: str) -> None:
    e = refused(lambda: robot.plan("R-001", kitchen, (1.0, 0.0, 0.0), (40.0, 40.0)))
    assert (e.status, e.code) == (422, "unprocessable")
    assert "goal" in e.message
    assert e.details is not None


def test_a_training_of_negative_length_is_422_naming_the_field(engineer: Client) -> None:
    e = refused(lambda: engineer.submit_training("R-001", "F0", -1))
    assert (e.status, e.code) == (422, "unprocessable") and "minutes" in e.message


def test_a_map_with_a_bad_name_is_refused(engineer: Client, shared_map: Path) -> None:
    e = refused(lambda: engineer.import_map("Not A Name!", shared_map))
    assert e.status == 422 and e.code == "unprocessable" and "name" in e.message


def test_a_robot_may_not_submit_jobs(robot: Client) -> None:
    e = refused(lambda: robot.submit_training("R-001", "F0", 1))
    assert (e.status, e.code) == (403, "forbidden")


def test_a_wrong_token_is_401(service: Service) -> None:
    with Client(service.url, "not-a-token") as client:
        e = refused(client.me)
    assert (e.status, e.code) == (401, "unauthorized")


def test_no_service_is_an_error_without_a_status() -> None:
    with Client(f"http://127.0.0.1:{free_port()}", "t", timeout=5) as client:
        e = refused(client.me)
    assert e.status is None and e.code == "unreachable"
