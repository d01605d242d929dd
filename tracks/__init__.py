"""Road geometry, lanes, markings, procedural textures, the semantic map and named presets."""
