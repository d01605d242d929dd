"""The simulated chassis behind the link: the ECU emulator and its plants, scenarios over CAN (`ld3 hil`), fault
drills, sensor-level HIL, the chassis campaign, the injection study, log replay and benchmarks."""
