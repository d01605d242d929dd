"""Where LaneNet reads each lane line: the distances ahead of the camera's car (m) of its anchor rows, and the
emphasis its cubic fit gives each. Kept apart from the network so labels can be made without torch."""

X_ANCHORS = (5.0, 6.0, 7.0, 8.0, 10.0, 12.0, 14.0, 17.0, 20.0, 25.0, 30.0)
ANCHOR_WEIGHTS = (3.0, 3.0, 2.5, 2.0, 1.5, 1.2, 1.0, 0.8, 0.6, 0.4, 0.3)  # fit emphasis near the car
