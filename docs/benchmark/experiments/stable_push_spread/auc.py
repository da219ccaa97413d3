import json, sys
rows=[json.loads(l) for l in open(sys.argv[1]) if l.startswith("{")]
def auc(key, sign=1):
    pos=[sign*float(r[key]) for r in rows if r["reached"]=="1"]; neg=[sign*float(r[key]) for r in rows if r["reached"]!="1"]
    s=sum((p>n)+0.5*(p==n) for p in pos for n in neg); return s/(len(pos)*len(neg))
print(len(rows), "reached", sum(r["reached"]=="1" for r in rows))
for k in ["yaw_spread","worst","pos_spread","turn","segments"]:
    print(k, "AUC(low value -> reached) %.3f"%auc(k,-1))
print("robustness AUC %.3f"%auc("robustness",1))
