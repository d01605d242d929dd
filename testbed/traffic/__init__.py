"""Other road users: same-direction cars that follow their lane's centre line at an IDM speed, their
configuration (`[traffic]`), their bodies in the physics world and their records."""
