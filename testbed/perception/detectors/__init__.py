"""The lane detectors a run uses (neural, ONNX, classical, oracle), their registry, the map's ground-truth lines and
the shipped weights."""
