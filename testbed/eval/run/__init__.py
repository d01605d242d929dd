"""One run: the scenario model and its TOML, building and stepping a run, its consequence, and everything it writes
(summary.json, trajectory.csv, run.mcap, camera.mp4, its figures)."""
