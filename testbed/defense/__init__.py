"""LD3 detection and response, the NaiveAR and SAVIOR baselines. No PyBullet, no torch."""
