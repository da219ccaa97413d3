"""Diagnostic (docs/experiments.md, "Candidates from one tree"): the requests of shipped runs
that searched more than two candidates, binned by the best robustness of their first two;
how often the answer came from the extra candidates, how often it reached in MuJoCo (servo arm,
nothing toppled), and the seconds the extras searched. Requests whose first two scored 0 are
listed. python extras_by_first_two.py ROWS/trials.csv ..."""
import csv, sys, collections
files = sys.argv[1:]
tab = collections.defaultdict(lambda: [0, 0, 0, 0.0, 0])  # requests, answer from extras, reached, extra seconds, reached when answer from extras
for f in files:
    for r in csv.DictReader(open(f)):
        c = (r['candidate_searches'] or '').split()
        if len(c) <= 2:
            continue
        parsed = []
        for s in c:
            it, rob, tr, sec = s.split(':')
            parsed.append((int(it), None if rob == '-' else float(rob), None if tr == '-' else float(tr), float(sec)))
        first2 = [p[1] for p in parsed[:2] if p[1] is not None]
        b2 = max(first2) if first2 else None
        ranks = [(p[1] - 0.5 * p[2], i) for i, p in enumerate(parsed) if p[1] is not None]
        ans = max(ranks)[1] if ranks else None
        extra_s = sum(p[3] for p in parsed[2:])
        reached = r['executed_servo'] == '1' and r['executed_toppled'] == '0'
        key = 'none' if b2 is None else ('0' if b2 == 0 else ('0.05-0.1' if b2 <= 0.1 else '0.15-0.25'))
        t = tab[key]
        t[0] += 1; t[1] += ans is not None and ans >= 2; t[2] += reached; t[3] += extra_s
        t[4] += reached and ans is not None and ans >= 2
        if key in ('0',) : print(f.split('/')[-2], r['scene'], r['seed'], c, reached, r['plan_time_s'])
for k, v in sorted(tab.items()):
    print(k, "requests", v[0], "answer from extras", v[1], "reached", v[2], "reached w/ extra answer", v[4], "extra s %.0f" % v[3])
