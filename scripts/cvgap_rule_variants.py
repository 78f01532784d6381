#!/usr/bin/env python3
"""Usage: cvgap_rule_variants.py DUMP ROWS.json [ROWS.json ...]
(DUMP: auto_rule_variants.py run with the default scheme; ROWS: testbed_calibration.py --json of the
fixed methods.) auto's choice from the left-out per-run scores under the default rule, with no
one-standard-error rule (lowest CV), and with the rule over the order poly < cubic-t < mesh < hybrid;
seeds 1-5 and 6-10 apart. Asserts that the default rule reproduces the rows' auto_chose."""
import json,glob,os,statistics as st,sys,math
sys.path.insert(0,os.path.dirname(os.path.abspath(__file__)))
import auto_rule_variants as v
rows={}
for f in sys.argv[2:]:
    for r in json.load(open(f)): rows['/'.join(r['case'].split('/')[-2:])]=r
def rule(scores, order, one_se=True, log=False):
    t={m:[math.log(x) if log else x for x in s] for m,s in scores.items()}
    best=min(v.CANDIDATES,key=lambda m: st.mean(t[m]))
    if not one_se: return best
    for m in order:
        d=[a-b for a,b in zip(t[m],t[best])]
        if st.mean(d)<=st.stdev(d)/math.sqrt(len(d)): return m
    return best
VAR=[('default rule',dict(order=v.CANDIDATES)),('lowest CV, no rule',dict(order=v.CANDIDATES,one_se=False)),
     ('rule, order poly < cubic-t < mesh < hybrid',dict(order=['poly','cubic-t','mesh','hybrid']))]
for seeds in (['seed1','seed2','seed3','seed4','seed5'],['seed6','seed7','seed8','seed9','seed10']):
    res={k:[] for k,_ in VAR}
    for p in sorted(glob.glob(os.path.join(sys.argv[1],'seed*_case*.json'))):
        seed,case=os.path.basename(p)[:-5].split('_',1)
        if seed not in seeds: continue
        row=rows[f'{seed}/{case}']; sel=json.load(open(p))['axes'][0]['selection']
        sc=v.fold_scores(sel,'left'); best=min(v.CANDIDATES,key=lambda m: row[m])
        for k,kw in VAR:
            m=rule(sc,**kw) if len(sc['poly'])>=3 else 'poly'
            res[k].append((row[m]/row[best],row[m]/row['noise'],m,f'{seed}/{case}'))
        assert res['default rule'][-1][2]==row['auto_chose'],(seed,case)
    if not any(res.values()): continue
    print(seeds[0],'-',seeds[-1])
    for k,r in res.items():
        print(f"  {k:45s} n={len(r)} within5%={sum(x[0]<=1.05 for x in r)} worst={max(x[0] for x in r):.3f} median/noise={st.median(x[1] for x in r):.3f} misses={[(x[3],x[2],round(x[0],3)) for x in r if x[0]>1.05]}")
