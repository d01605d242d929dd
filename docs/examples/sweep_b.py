"""A parameter sweep: LD3's CUSUM weight b against the detection deviation under trace injection.

Run: python docs/examples/sweep_b.py   (writes runs/sweep-b/runs.csv, one row per value of b)
"""

from pathlib import Path

import pandas as pd

from testbed import api

rows = []
for b in (0.4, 0.6, 0.8):
    sc = api.scenario("urban-straight", duration=20.0, localization="msf", defense_params={"b": b},
                      defense="ld3", attack={"kind": "trace", "trace": "default", "start": 6.0})
    s = api.run(sc).summary
    rows.append({"b": s["defense_params"]["b"], "detected": s["detected"], "detection_time_s": s["detection_time_s"],
                 "detection_dev_m": s["detection_dev_m"], "consequence": s["consequence"]})
table = pd.DataFrame(rows)
out = Path("runs/sweep-b")
out.mkdir(parents=True, exist_ok=True)
table.to_csv(out / "runs.csv", index=False)
print(table.to_string(index=False))
