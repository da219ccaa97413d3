import json, sys, math
import numpy as np
rows=[json.loads(l) for l in open(sys.argv[1])]
scales=list(rows[0]["model"].keys())
def wrap(a): return (a+math.pi)%(2*math.pi)-math.pi
for shape in ("box","cylinder","all"):
    sel=[r for r in rows if (shape=="all" or r["shape"]==shape) and not r["toppled"] and not any(v[3] for v in r["model"].values())]
    # only pushes that moved the object in mujoco
    print(shape, len(sel))
    for s in scales:
        ey=[abs(wrap(r["model"][s][2]-r["mujoco"][2])) for r in sel]
        ep=[math.hypot(r["model"][s][0]-r["mujoco"][0], r["model"][s][1]-r["mujoco"][1]) for r in sel]
        # signed: model turn / mujoco turn
        tm=[wrap(r["model"][s][2]-r["yaw0"]) for r in sel]; tj=[wrap(r["mujoco"][2]-r["yaw0"]) for r in sel]
        big=[(a,b) for a,b in zip(tm,tj) if abs(b)>0.2]
        ratio=np.median([a/b for a,b in big]) if big else float('nan')
        print(f"  c x{s}: yaw err median {np.median(ey):.3f} mean {np.mean(ey):.3f} | pos err median {100*np.median(ep):.2f} cm mean {100*np.mean(ep):.2f} | turn ratio model/mujoco (|turn|>0.2, n={len(big)}) {ratio:.2f}")
inv=sum(any(v[3] for v in r["model"].values()) for r in rows); top=sum(r["toppled"] for r in rows)
print("model invalid", inv, "mujoco toppled", top)
