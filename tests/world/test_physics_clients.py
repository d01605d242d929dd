"""Physics clients kept for reuse: a released client comes back with an empty world, and a run on it gives the
records of a run on a new connection."""

from __future__ import annotations

import pybullet as pb
import pytest

from testbed import api, physics_clients


@pytest.fixture
def no_kept_clients(monkeypatch):
    """Every client released is disconnected, so each world gets a new connection."""
    monkeypatch.setattr(physics_clients, "KEPT_CLIENTS", 0)
    monkeypatch.setattr(physics_clients, "_kept", [])


def test_a_released_client_is_reused_with_an_empty_world(monkeypatch):
    monkeypatch.setattr(physics_clients, "_kept", [])
    client = physics_clients.connect()
    pb.createMultiBody(0, pb.createCollisionShape(pb.GEOM_PLANE, physicsClientId=client), physicsClientId=client)
    assert pb.getNumBodies(physicsClientId=client) == 1
    physics_clients.release(client)
    assert physics_clients.connect() == client
    assert pb.getNumBodies(physicsClientId=client) == 0
    physics_clients.release(client)
    physics_clients.release(client)  # released twice: kept once
    assert physics_clients._kept == [client]


def test_a_client_released_beyond_those_kept_is_disconnected(monkeypatch):
    monkeypatch.setattr(physics_clients, "_kept", [])
    clients = [physics_clients.connect() for _ in range(physics_clients.KEPT_CLIENTS + 1)]
    for client in clients:
        physics_clients.release(client)
    assert physics_clients._kept == clients[:-1]
    assert not pb.isConnected(clients[-1])


def _records(sc) -> str:
    """The run's ticks as trajectory.csv would hold them, and its consequence."""
    result = api.run(sc)
    return result.frame.to_csv() + result.summary["consequence"]


def test_a_run_on_a_reused_client_gives_the_records_of_a_new_connection(request):
    """A drive through the roadside into a curb, then a highway drive at speed, each run after another world was built
    and released in this process, against the same runs each on a new connection."""
    scenarios = [api.scenario("local", duration=12.0, localization="msf", defense="none",
                              attack={"kind": "trace", "trace": "default", "start": 2.0}),
                 api.scenario("highway", duration=8.0, localization="msf", speed=27.0)]
    reused = [_records(sc) for sc in scenarios for _ in range(2)]
    request.getfixturevalue("no_kept_clients")
    fresh = [_records(sc) for sc in scenarios for _ in range(2)]
    assert reused == fresh
    assert reused[0] == reused[1] and reused[2] == reused[3]
