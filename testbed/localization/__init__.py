"""Sensor models (GNSS, LiDAR locator, IMU) and multi-sensor fusion. No PyBullet, no torch."""
