#!/usr/bin/env python3
"""Usage: cvgap_twin.py BIN OUTDIR TB seedN/caseK_X ...
Validation of each down_poweron_T0 run by models fitted on the up_* runs without (and with) its up twin."""
import csv, glob, json, os, subprocess, sys
B, OUT, TB = sys.argv[1:4]; cases = sys.argv[4:]
os.makedirs(OUT, exist_ok=True)
T0S = ['-35C', '-20C', '-05C', '+10C', '+25C', '+40C', '+55C']
def runs_file(path, case, role):
    with open(f'{TB}/{case}/runs.csv') as f, open(path, 'w', newline='') as g:
        w = csv.writer(g); w.writerow(['run', 'position', 'input_rate_dph', 'role'])
        for r in csv.DictReader(f):
            w.writerow([r['run'], r['position'], r['input_rate_dph'], role(r['run'])])
res = {}
for case in cases:
    logs = sorted(glob.glob(f'{TB}/{case}/recorded/*.csv'))
    for t0 in T0S:
        for twin in (False, True):
            fr = f'{OUT}/fit.csv'; vr = f'{OUT}/val.csv'
            runs_file(fr, case, lambda n: 'cal' if n.startswith('up_') and (twin or n != f'up_poweron_{t0}') else 'val')
            runs_file(vr, case, lambda n: 'val' if n == f'down_poweron_{t0}' else 'cal')
            for m in ('poly', 'mesh'):
                model = f'{OUT}/m.fogm'
                f = subprocess.run([B, 'fit', '--method', m, '--out', model, '--json', *logs, '--runs', fr], capture_output=True, text=True)
                if f.returncode: print(case, t0, m, f.stderr[-200:], file=sys.stderr); continue
                v = json.loads(subprocess.run([B, 'validate', '--model', model, '--json', *logs, '--runs', vr], capture_output=True, text=True).stdout)
                r = v['runs'][0]
                res[f'{case}|{t0}|{twin}|{m}'] = (r['compensated_bias_stability_dph'], r['flag_samples']['outside_hull'])
        print(case, t0, {k.split('|', 2)[2]: v for k, v in res.items() if k.startswith(f'{case}|{t0}|')}, flush=True)
json.dump(res, open(f'{OUT}/twin.json', 'w'))
