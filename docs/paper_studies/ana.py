"""Crack state of a direct shear run folder per stage (docs/paper.md, issue 17).

python3 docs/paper_studies/ana.py RUN_DIR configs/paper/direct_shear.msh
Reads RUN_DIR/splits.csv and summary.json; an edge (between two cells) is open at both ends
when splits at both its points listed it (bc counts as pre-separated). Groups: cd (y = 4,
x >= 4), bc, the held box row and the line y = 2, the lower specimen row, the upper block.
"""
import sys,csv,json,os
def load_msh(path):
    L=open(path).read().split('\n'); i=L.index('$Nodes'); n=int(L[i+1])
    pts=[tuple(map(float,L[i+2+k].split()[1:3])) for k in range(n)]
    i=L.index('$Elements'); m=int(L[i+1]); cells=[]
    for k in range(m):
        f=list(map(int,L[i+2+k].split())); t=f[1]; nt=f[2]; nodes=[x-1 for x in f[3+nt:]]
        if t in (2,3): cells.append(nodes)
    return pts,cells
def analyse(run, msh, upto=None):
    pts,cells=load_msh(msh)
    cnt={}
    for c in cells:
        for a,b in zip(c,c[1:]+c[:1]): cnt[(min(a,b),max(a,b))]=cnt.get((min(a,b),max(a,b)),0)+1
    edges={e for e,n in cnt.items() if n==2}
    cut={e:set() for e in edges}
    # bc pre-separated: (2,4)-(4,4)
    for e in edges:
        A,B=pts[e[0]],pts[e[1]]
        if abs(A[1]-4)<1e-9 and abs(B[1]-4)<1e-9 and max(A[0],B[0])<=4+1e-9 and min(A[0],B[0])>=2-1e-9: cut[e]={e[0],e[1]}
    for r in csv.DictReader(open(os.path.join(run,'splits.csv'))):
        if upto is not None and int(r['step'])>upto: continue
        p=int(r['point'])
        for s in r['edges'].split():
            a,b=map(int,s.split('-')); cut[(min(a,b),max(a,b))].add(p)
    def where(e):
        A,B=pts[e[0]],pts[e[1]]
        if abs(A[1]-4)<1e-9 and abs(B[1]-4)<1e-9:
            return 'cd' if min(A[0],B[0])>=4-1e-9 else 'bc'
        y=(A[1]+B[1])/2
        if y<2-1e-9 or (abs(A[1]-2)<1e-9 and abs(B[1]-2)<1e-9): return 'box row/y=2'
        if y<4: return 'lower specimen'
        return 'upper block'
    out={}
    for e,s in cut.items():
        w=where(e)
        o=out.setdefault(w,[0,0,0])
        o[2]+=1
        if len(s)>=1: o[1]+=1
        if len(s)==2: o[0]+=1
    j=json.load(open(os.path.join(run,'summary.json')))
    return out,j
def table(run,msh):
    j=json.load(open(os.path.join(run,'summary.json')))
    tot=0; rows=[]
    for st in j['stages']:
        tot+=st['steps']
        out,_=analyse(run,msh,tot)
        rows.append((st['name'],st['splits'],st['converged'],st['final_ratio'],st['energy_residual'],out))
    return rows,j
if __name__=='__main__':
    rows,j=table(sys.argv[1],sys.argv[2])
    for n,sp,cv,fr,er,out in rows:
        print(f"  {n}: splits {sp}, eq {cv}, ratio {fr:.2e}, resid {er:.1e}; open/cracked/edges:", {k:f'{v[0]}/{v[1]}/{v[2]}' for k,v in sorted(out.items())})
    out,j=analyse(sys.argv[1],sys.argv[2])
    print({k:f'{v[0]}/{v[1]}/{v[2]}' for k,v in sorted(out.items())}, 'splits',j['splits'],'resid %.1e'%j['energy']['relative_residual'], [(s['name'],s['splits'],s['converged'],'%.2e'%s['final_ratio']) for s in j['stages']], 'dt_end %.2e'%j['dt'], 'beyond',j['beyond_criterion'])
