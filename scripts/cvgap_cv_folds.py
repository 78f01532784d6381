#!/usr/bin/env python3
"""Usage: cvgap_cv_folds.py FIT.json ...: per held-out run of auto's cross-validation (fit --json), scored inside the region and over the whole run."""
import json,sys,math
for f in sys.argv[1:]:
    d=json.load(open(f)); s=d['axes'][0]['selection']
    print('##',f, 'chose',s['method'],'best',s['best'])
    C={c['method']:c for c in s['candidates']}
    for m,c in C.items(): print(f"  {m:8s} cv {c['cv_bias_stability_dph']:.5f} diff {c['difference_from_best_dph']:.5f} se_d {c['difference_standard_error_dph']:.5f}")
    print(f"  {'held-out run':18s} {'scored/out':>10s} | inside: cubic-t poly mesh mesh/poly | whole: cubic-t poly mesh mesh/poly")
    for i,r in enumerate(C['poly']['runs']):
        g=lambda m,k: C[m]['runs'][i][k]
        ins=[g(m,'bias_stability_dph') for m in ('cubic-t','poly','mesh')]
        wh=[g(m,'whole_run_bias_stability_dph') for m in ('cubic-t','poly','mesh')]
        fmt=lambda v: ' '.join(f"{x:.5f}" if x else '   -   ' for x in v)
        rat=lambda v: f"{v[2]/v[1]:.3f}" if v[1] else '  -  '
        print(f"  {r['run']:18s} {r['windows_scored']:4d}/{r['windows_outside_region']:<4d} | {fmt(ins)} {rat(ins)} | {fmt(wh)} {rat(wh)}")
