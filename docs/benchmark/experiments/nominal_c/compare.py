"""The shipped default before (`9da04b9`, and `0a50c89` with the same searches) and after
the nominal support's c was fitted to MuJoCo (`fcce53e`), on held-out varied seeds 9-14, and
the variant with max_turn 4.1 rad/m (docs/experiments.md, 2026-11-30). Seeds 9-12 before are
the rows of docs/benchmark/time/kinematics_once/ (run one after the other on an idle machine
on 2026-11-30); after, run the same way. Seeds 13 + 14 before and after ran at the same time,
one beside the other, so their times are longer, as did the fixed set's seed 0 before and
after. The fixed set's seeds 0-2 after ran alone, from a clone of `fcce53e`. Run from this
folder: python3 compare.py > compare.txt"""
import csv
from math import comb

BEFORE = {'9-10': '../../time/kinematics_once/varied_s9_s10_0a50c89',
          '11-12': '../../time/kinematics_once/varied_s11_s12_0a50c89',
          '13-14': 'varied_s13_s14_9da04b9'}
AFTER = {'9-10': 'varied_s9_s10_fcce53e', '11-12': 'varied_s11_s12_fcce53e',
         '13-14': 'varied_s13_s14_fcce53e'}
MAX_TURN = {'9-10': 'varied_s9_s10_fcce53e_max_turn_4.1',
            '13-14': 'varied_s13_s14_fcce53e_max_turn_4.1'}


def load(folder):
    with open(f'{folder}/trials.csv') as f:
        return {(r['scene'], r['seed']): r for r in csv.DictReader(f)}


def reached(r):
    return r['executed_servo'] == '1'


def toppled(r):
    return r['executed_toppled'] not in ('0', '')


def line(label, rows):
    times = sorted(float(r['plan_time_s']) for r in rows)
    p90 = times[int(0.9 * len(times)) - 1]
    print(f"| {label} | {len(rows)} | {sum(r['solved'] == '1' for r in rows)} | "
          f"{sum(map(reached, rows))} | {sum(map(toppled, rows))} | "
          f"{sum(r['executed_toppled_goal'] == '1' for r in rows)} | "
          f"{times[len(times) // 2]:.2f} / {p90:.1f} s | {sum(t > 20 for t in times)} |")


print('| seeds, commit | requests | solved | reached | plans toppling | the goal object |'
      ' median / p90 | over 20 s |')
print('|---|---|---|---|---|---|---|---|')
everything = {'before': {}, 'after': {}}
for seeds in BEFORE:
    before, after = load(BEFORE[seeds]), load(AFTER[seeds])
    everything['before'].update(before)
    everything['after'].update(after)
    line(f'{seeds}, before', list(before.values()))
    line(f'{seeds}, after', list(after.values()))
    if seeds in MAX_TURN:
        line(f'{seeds}, after, max_turn 4.1', list(load(MAX_TURN[seeds]).values()))
line('9-14, before', list(everything['before'].values()))
line('9-14, after', list(everything['after'].values()))

before, after = everything['before'], everything['after']
for name, test in (('reached', reached), ('toppling', toppled)):
    only_before = sum(test(before[k]) and not test(after[k]) for k in before)
    only_after = sum(test(after[k]) and not test(before[k]) for k in before)
    n, low = only_before + only_after, min(only_before, only_after)
    p = min(1.0, 2 * sum(comb(n, i) for i in range(low + 1)) / 2 ** n)
    print(f'\n{name}: before only {only_before}, after only {only_after} (two-sided sign '
          f'test p = {p:.2f})')



def before_after(title, before_folder, after_folder):
    print(f'\n| {title} | requests | solved | reached | plans toppling | the goal object |'
          ' median / p90 | over 20 s |')
    print('|---|---|---|---|---|---|---|---|')
    line('before', list(load(before_folder).values()))
    line('after', list(load(after_folder).values()))


before_after('fixed set, seed 0', 'fixed_s0_9da04b9', 'fixed_s0_fcce53e')

rows = list(load('fixed_s0_s2_fcce53e').values())
print('\n| fixed set, seeds 0-2, after, alone | requests | solved | reached | plans toppling |'
      ' the goal object | median / p90 | over 20 s |')
print('|---|---|---|---|---|---|---|---|')
line('after', rows)
slow = [r for r in rows if float(r['plan_time_s']) > 20]
print(f"\nover 20 s: {len(slow)}, of which {sum(r['solved'] != '1' for r in slow)} unsolved, "
      f"{sum(int(r['candidates'] or 0) >= 3 for r in slow)} searched 3-5 candidates "
      f"(a fragile best), {sum(r['executed_servo'] == '1' for r in slow)} reached")

before_after('first plan of one tree, varied seed 0, 20 s (side by side, one core each)',
             'first_plan_varied_s0_9da04b9', 'first_plan_varied_s0_fcce53e')
