"""CAN bridge: DBC, codec, chassis port over python-can, ECU emulator."""
