"""Lane detection beyond the core's contract, in rooms: the run-time detectors and their shipped weights
(`detectors`), their training (`training`) and lab drives (`lab`); `commands` is `ld3 ld`."""
