"""Objects a plan pushes, by the planner's tipping margin d - mu_s h (tipmargin.py's output), against
MuJoCo's verdict (one line per object per solved plan; the seed-6 run holds two arms' plans): would refusing pushes within a margin of the limit avoid the plans that topple?
Usage: python3 margin_bands.py tip_margins_held_out_s4_s6.txt"""
import re
import sys

LINE = re.compile(r"^(\S+) (\S+) (\S+) toppled=(\d) margin=(-?[\d.]+)mm h=([\d.]+) H=([\d.]+) "
                  r"link=(\S+) reached=(\d)")
rows = [m.groups() for m in map(LINE.match, open(sys.argv[1])) if m]
print(f"{len(rows)} objects pushed, {sum(r[3] == '1' for r in rows)} toppled")
for lo, hi in [(-99, 0), (0, 1), (1, 2), (2, 3), (3, 5), (5, 8), (8, 15), (15, 99)]:
    band = [r for r in rows if lo <= float(r[4]) < hi]
    goal = [r for r in band if r[2] == "target"]
    print(f"margin [{lo}, {hi}) mm: {len(band)} objects, {sum(r[3] == '1' for r in band)} toppled;"
          f" goal objects {len(goal)}, {sum(r[3] == '1' for r in goal)} toppled")
near = [r for r in rows if r[2] == "target" and 0 <= float(r[4]) < 5
        and float(r[5]) < float(r[6]) - 0.005]
print(f"goal objects pushed within 5 mm of the limit below their top: {len(near)} plans, "
      f"{sum(r[8] == '1' for r in near)} reached, {sum(r[3] == '1' for r in near)} toppled")
top = [r for r in rows if float(r[5]) >= float(r[6]) - 0.005]
print(f"objects touched at their top rim: {len(top)}, {sum(r[3] == '1' for r in top)} toppled")
