"""The CAN link: chassis profiles (DBC + signal map), the codec with counters, checksums and SecOC, the bridge (a
ChassisPort over any python-can bus), its faults, timing and recorder."""
