"""Training and evaluating lane detectors: datasets, labels' occlusion, training, existence refits, weight averages,
ONNX export, held-out seeds."""
