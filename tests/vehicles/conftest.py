"""Fixture: a fresh flat PyBullet world per test, disconnected afterwards."""

from __future__ import annotations

from collections.abc import Iterator

import pybullet as p
import pytest

from tests.vehicles.flat_world import make_world


@pytest.fixture
def world() -> Iterator[int]:
    cid = make_world()
    yield cid
    p.disconnect(cid)
