#!/usr/bin/env python3
"""Usage: cvgap_twin_table.py TWIN.json FIT-CASE1.json FIT-CASE2.json ... (fit --json of auto, same case order as cvgap_twin.py)

Per power-on temperature T0: mesh/poly of auto's leave-one-run-out fold that holds out up_T0 (inside the
region; whole run in brackets), of the same fold's models on down_T0, and of the final models on down_T0."""
import json, sys
twin = json.load(open(sys.argv[1]))
cases = sorted({k.split('|')[0] for k in twin}, key=lambda c: list(twin).index(next(k for k in twin if k.startswith(c))))
print('| case | T0 | CV fold on up_T0: inside (whole run) | same models on down_T0 | final models on down_T0 |')
print('|---|---|---|---|---|')
for case, fit in zip(cases, sys.argv[2:]):
    C = {c['method']: c for c in json.load(open(fit))['axes'][0]['selection']['candidates']}
    for t0 in ['-35C', '-20C', '-05C', '+10C', '+25C', '+40C', '+55C']:
        i = next(j for j, r in enumerate(C['poly']['runs']) if r['run'] == f'up_poweron_{t0}')
        g = lambda m, k: C[m]['runs'][i][k]
        left = g('mesh', 'left_out_bias_stability_dph'), g('poly', 'left_out_bias_stability_dph')
        whole = g('mesh', 'whole_run_bias_stability_dph') / g('poly', 'whole_run_bias_stability_dph')
        cv = f"{left[0] / left[1]:.3f} ({whole:.3f})" if left[1] else f"- ({whole:.3f})"
        cell = []
        for tw in ('False', 'True'):
            (m, out), (p, _) = twin[f'{case}|{t0}|{tw}|mesh'], twin[f'{case}|{t0}|{tw}|poly']
            cell.append(f"{m / p:.3f}" + (f" ({out} of 7200 outside)" if out > 360 else ''))
        print(f'| {case} | {t0} | {cv} | {cell[0]} | {cell[1]} |')
