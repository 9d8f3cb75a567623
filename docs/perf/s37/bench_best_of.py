import json, subprocess, sys, statistics as st
# usage: bench.py N rounds cases bin1 bin2 ...
N, R, C = sys.argv[1], int(sys.argv[2]), sys.argv[3]
bins = sys.argv[4:]
res = {b: {} for b in bins}
for r in range(R):
    for b in bins:
        out = subprocess.run([f'./flem_{b}', 'bench', 'laws', '--elements', N, '--min-time', '0.25', '--cases', C], capture_output=True, text=True).stdout
        d = json.loads(out)
        e = [c for c in d['cases'] if c['law'] == 'elastic'][0]['ns_per_elem_update']
        for c in d['cases']:
            res[b].setdefault(c['law'], []).append((c['ns_per_elem_update'], c['ns_per_elem_update'] / e))
import os
if os.environ.get('RAW'):
    json.dump(res, open(os.environ['RAW'], 'w'), indent=1)
for b in bins:
    print(b, ' '.join('%s=%.1f(%.2fx)' % (k.replace('mohr_coulomb', 'mc'), min(x[0] for x in v), min(x[0] for x in v)/min(y[0] for y in res[b]['elastic'])) for k, v in res[b].items()))
