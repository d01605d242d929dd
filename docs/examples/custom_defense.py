"""A defense of your own, run through the Python API: LD3's detection with a gentler stop.

Run: python docs/examples/custom_defense.py
"""

from testbed import api
from testbed.defense.config import DefenseConfig
from testbed.defense.ld3 import Ld3Defense


class GentleLd3(Ld3Defense):
    """LD3 whose attack response brakes at 2.5 m/s² instead of 4."""

    name = "gentle-ld3"

    @property
    def response_decel(self) -> float:
        return 2.5


sc = api.scenario("urban-straight", duration=25.0, localization="msf", defense="ld3",
                  attack={"kind": "trace", "trace": "default", "start": 6.0})
result = api.run(sc, defense=GentleLd3(DefenseConfig()))
s = result.summary
print(f"{s['defense']}: {s['consequence']}, detected at {s['detection_time_s']:.2f} s, "
      f"stop deviation {s['ar_stop_dev_m']:+.3f} m")
ar = result.frame[result.frame["mode"] == "ar"]
print(f"attack response: {len(ar)} ticks, deceleration {-ar['accel'].median():.2f} m/s² (median command)")
