#!/usr/bin/env python3
"""Usage: cvgap_per_validation_run.py BIN OUTDIR TB seedN/caseK_X ...
Per validation run: compensated bias stability of cubic-t, poly, mesh and outside-hull samples."""
import csv, glob, json, os, subprocess, sys
B, OUT, TB = sys.argv[1:4]; cases = sys.argv[4:]
os.makedirs(OUT, exist_ok=True)
for case in cases:
    name = case.replace('/', '_')
    d = f'{TB}/{case}'
    runs = f'{OUT}/runs_{name}.csv'
    with open(f'{d}/runs.csv') as f, open(runs, 'w', newline='') as g:
        w = csv.writer(g); w.writerow(['run', 'position', 'input_rate_dph', 'role'])
        for r in csv.DictReader(f):
            w.writerow([r['run'], r['position'], r['input_rate_dph'], 'cal' if r['run'].startswith('up_') else 'val'])
    logs = sorted(glob.glob(f'{d}/recorded/*.csv'))
    res = {}
    for m in ['cubic-t', 'poly', 'mesh']:
        model = f'{OUT}/{name}_{m}.fogm'
        fit = subprocess.run([B, 'fit', '--method', m, '--out', model, '--json', *logs, '--runs', runs], capture_output=True, text=True)
        if fit.returncode: print(case, m, fit.stderr[-300:], file=sys.stderr); continue
        v = subprocess.run([B, 'validate', '--model', model, '--json', *logs, '--runs', runs], capture_output=True, text=True)
        res[m] = json.loads(v.stdout)
    json.dump(res, open(f'{OUT}/{name}.json', 'w'))
    print(case, 'done', file=sys.stderr, flush=True)
