"""The closed loop and everything it runs: world, camera, perception, localization, attacks, defense."""
