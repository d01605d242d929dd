"""CAN bridge: DBC, codec, chassis port over python-can, ECU emulator, and scenario runs over CAN.

The loop drives a `CanChassisBridge` (a ChassisPort) instead of the PyBullet car; commands go out as the
ACU_*Ctrl frames of dbc/chassis.dbc at 50 Hz, the VCU answers with VCU_*Status reports (and, in simulation,
SIM_Truth* frames with the true pose). In lockstep the bridge clocks the ECU with SIM_StepRequest/StepDone.

Usage:
  ld3 hil parking-lot                          # in-process ECU (PyBullet plant) on a fresh virtual bus
  ld3 hil parking-lot --interface slcan        # ECU emulator as its own process, SLCAN over a pty
  ld3 hil SCENARIO --interface socketcan --channel can0   # a real chassis, realtime clock
  ld3 hil SCENARIO --attack trace:default,start=1 --defense ld3 --out runs/x --log runs/x/can.blf
  ld3 hil replay runs/x/can.asc --interface socketcan --channel vcan0
  ld3 ecu --interface slcan-pty --scenario parking-lot   # prints SLCAN_PTY <path>; then
  ld3 hil parking-lot --interface slcan --channel <path>
`ld3 hil` accepts the overrides of `ld3 run` and writes the same outputs (summary.json gains interface,
channel, clock and CAN frame counts) plus the CAN log (default OUT/can.asc). In Python:
`hil.scenario_run.run_hil_scenario(scenario, out_dir, LinkConfig(interface, channel))`.
"""
