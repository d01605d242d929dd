"""PyBullet DIRECT clients kept for reuse within a process: a released client's world is emptied
(`resetSimulation`) and handed to the next physics world, which sets every engine parameter it uses itself, so a
campaign's worker, which builds a world per run, connects once (docs/decisions.md, "Campaign speed, eighteenth
round").
"""

from __future__ import annotations

import pybullet as pb

KEPT_CLIENTS = 2
"""At most this many released clients wait for reuse; one released beyond them is disconnected."""

_kept: list[int] = []


def connect() -> int:
    """A DIRECT client with an empty world: a kept one, else a new connection."""
    while _kept:
        client = _kept.pop()
        if pb.isConnected(client):
            return client
    return pb.connect(pb.DIRECT)


def release(client: int) -> None:
    """Empty `client`'s world and keep it for the next `connect`, or disconnect it when enough are kept; a client
    already kept, or no longer connected, is left as it is."""
    if client in _kept or not pb.isConnected(client):
        return
    if len(_kept) >= KEPT_CLIENTS:
        pb.disconnect(client)
        return
    pb.resetSimulation(physicsClientId=client)
    _kept.append(client)
