"""The loop over CAN, in rooms: the CAN link (`link`: chassis profiles, codec, SecOC, the bridge over python-can),
the simulated chassis behind it (`emulator`: the ECU emulator, scenario runs over CAN, drills) and a real vehicle
(`vehicle`: NMEA GNSS, camera, `ld3 vehicle`, replay); the commands at the top (`cli`, `vehicle_cli`, ...).

The loop drives a `CanChassisBridge` (a ChassisPort) instead of the PyBullet car. A chassis profile
(hil/link/profiles/<name>/: chassis.dbc + profile.toml; shipped: ld3-dev, ld3-dev-secoc, pix-hooke) says which
messages carry the commands and reports, their units, enums, counters and checksums or SecOC freshness and MAC
(`hil.link.secoc`), cycle and time-outs. The bridge sends a command cycle only for a fresh loop command, places the
simulated world at its odometry pose (from reported speed and steering), and ends the run as chassis_fault
after an in-lane stop when a fault latches. In lockstep the bridge clocks the emulator with
SIM_StepRequest/StepDone. See docs/hil.md and docs/can-security.md.

Usage:
  ld3 hil parking-lot --profile pix-hooke      # in-process ECU (PyBullet plant) on a fresh virtual bus
  ld3 hil parking-lot --interface slcan        # ECU emulator as its own process, SLCAN over a pty
  ld3 hil SCENARIO --profile pix-hooke --interface socketcan --channel can0   # a real chassis, realtime clock
  ld3 hil SCENARIO --attack trace:default,start=1 --defense ld3 --out runs/x --log runs/x/can.blf
  ld3 hil parking-lot --drill chassis_estop@2  # a fault drill against the emulator
  ld3 hil replay runs/x/can.asc --channel test # command IDs only; a hardware bus needs --yes
  ld3 ecu --interface slcan-pty --scenario parking-lot --profile pix-hooke   # prints SLCAN_PTY <path>; then
  ld3 hil parking-lot --profile pix-hooke --interface slcan --channel <path>
  ld3 hil parking-lot --profile ld3-dev-secoc  # authenticated frames; the test key only on an emulator's bus
`ld3 hil` accepts the overrides of `ld3 run` and writes the same outputs (summary.json gains interface,
channel, clock, profile, faults and CAN frame counts) plus the CAN log (default OUT/can.asc). In Python:
`hil.emulator.scenario_run.run_hil_scenario(scenario, out_dir, LinkConfig(interface, channel, profile="pix-hooke"))`.
"""
