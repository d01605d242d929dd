"""A real vehicle: NMEA GNSS, camera readers and calibration, localization, `ld3 vehicle`, and the replay of a
recorded drive."""
