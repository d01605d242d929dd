"""OpenDRIVE (ASAM, revisions 1.4-1.8) import into a `tracks.road.Track` and export of any track as OpenDRIVE.

`load.load_track_spec("PATH#ROUTE")` reads a route of roads; `write.track_to_xodr(track)` writes one.
What the reader uses and ignores: docs/opendrive.md.
"""
