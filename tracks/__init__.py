"""Road geometry, lanes, markings, procedural textures, the semantic map, named presets and OpenDRIVE import/export."""
