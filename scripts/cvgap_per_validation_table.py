#!/usr/bin/env python3
"""Usage: cvgap_per_validation_table.py OUTDIR (of cvgap_per_validation_run.py): per validation run cubic-t, poly, mesh; RMS inside/outside, without the triangle."""
import json,glob,math,os,sys
for f in sorted(glob.glob(os.path.join(sys.argv[1], '*.json'))):
    d=json.load(open(f)); name=os.path.basename(f)[:-5]
    print('##',name, {m:round(d[m]['compensated_bias_stability_dph'],5) for m in d})
    runs={}
    for m in d:
        for r in d[m]['runs']:
            runs.setdefault(os.path.basename(r['path'])[:-4],{})[m]=(r['compensated_bias_stability_dph'],r['flag_samples']['outside_hull'],r['samples'],r['raw_bias_stability_dph'])
    print(f"{'run':22s} {'raw':>8s} {'cubic-t':>8s} {'poly':>8s} {'mesh':>8s} mesh/poly  out(c,p,m)")
    for k,v in runs.items():
        print(f"{k:22s} {v['poly'][3]:8.5f} {v['cubic-t'][0]:8.5f} {v['poly'][0]:8.5f} {v['mesh'][0]:8.5f} {v['mesh'][0]/v['poly'][0]:6.3f}   {v['cubic-t'][1]},{v['poly'][1]},{v['mesh'][1]} /{v['poly'][2]}")
    # RMS contributions: squared sum share
    for m in d:
        sq={k:v[m][0]**2 for k,v in runs.items()}
        tot=sum(sq.values())
    # RMS over inside runs (poly outside<5%) vs outside runs
    ins=[k for k,v in runs.items() if v['poly'][1]<0.05*v['poly'][2]]; out=[k for k in runs if k not in ins]
    rms=lambda m,ks: math.sqrt(sum(runs[k][m][0]**2 for k in ks)/len(ks)) if ks else float('nan')
    print('  inside runs',len(ins),{m:round(rms(m,ins),5) for m in d},' outside runs',out,{m:round(rms(m,out),5) for m in d})
    tri=[k for k in runs if 'triangle' in k]; pw=[k for k in runs if 'triangle' not in k]
    print('  without triangle',{m:round(rms(m,pw),5) for m in d}, ' mesh/poly', round(rms('mesh',pw)/rms('poly',pw),3), ' all mesh/poly', round(rms('mesh',list(runs))/rms('poly',list(runs)),3), ' inside mesh/poly', round(rms('mesh',ins)/rms('poly',ins),3))
