"""Lane detectors (torch net, classical OpenCV, map oracle), their training and shipped weights."""
