"""Vehicle parameters, URDF generation, the PyBullet vehicle and its camera rig."""
