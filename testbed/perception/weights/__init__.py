"""Shipped LaneNet weights (lanenet.pt), loaded by `testbed.perception.neural.load_model`."""
